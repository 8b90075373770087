"""Tests of the Python reproduction harness: experiments/*.json,
experiments/run.py, harness/results.py, plots/figures.py, plots/claims.py and
plots/report.py, driven by tests/python/fake_bench.py instead of sphnl_bench.

    MPLBACKEND=Agg /usr/bin/python3 -m unittest discover -s tests/python -v
"""
import collections
import contextlib
import io
import itertools
import json
import math
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np
import pandas as pd

REPO = pathlib.Path(__file__).resolve().parents[2]
os.environ.setdefault("MPLBACKEND", "Agg")

# Run from the repository root (`make test`), which `python -m` puts on sys.path.
from experiments import run  # noqa: E402
from harness import machine as M  # noqa: E402
from harness import protocol as P  # noqa: E402
from harness import results as R  # noqa: E402
from plots import claims as C  # noqa: E402
from plots import figures as F  # noqa: E402
from plots import report  # noqa: E402

FAKE = REPO / "tests" / "python" / "fake_bench.py"
CONTRACT_NAME = ("step/particles:31239/gridder:B/cell_order:sort_x/reorder:1/list:cll/list_steps:1/"
                 "kgc:0/threads:1")


# run.py sees a clean checkout at this revision unless a test says otherwise
# (the merge refusal depends on the tree; the tests must not).
CLEAN = {M.TEST_REVISION: "a" * 40, M.TEST_DIRTY: "0"}


def run_cli(*args, env=None):
    """experiments/run.py in a subprocess: (exit code, stdout, stderr)."""
    p = subprocess.run([sys.executable, "-m", "experiments.run", *map(str, args)], cwd=REPO,
                       capture_output=True, text=True, env={**os.environ, **CLEAN, **(env or {})})
    return p.returncode, p.stdout, p.stderr


def fake_run(results_dir, size="tiny", *more, env=None):
    # the fake bench stands in for the timed bench only; the counters kind runs
    # under valgrind (tests/python/test_counters.py)
    code, out, err = run_cli("--size", size, "--results-dir", results_dir, "--bench", FAKE,
                             "--run-id", "r", "--skip-counters", *more, env=env)
    if code:
        raise AssertionError(f"run.py failed ({code}):\n{out}\n{err}")
    return pathlib.Path(results_dir) / "r", out


class TempDirCase(unittest.TestCase):
    def setUp(self):
        self.tmp = pathlib.Path(tempfile.mkdtemp(prefix="sphnl-harness-"))
        self.addCleanup(shutil.rmtree, self.tmp, ignore_errors=True)


class TestNames(unittest.TestCase):
    def test_idle_seconds_of_freed_memory(self):
        """One reading of freed_memory's idle_<s>s for the plan, the claims and the figures."""
        for value, seconds in (("idle_3s", 3), ("idle_12s", 12), ("as_found", 0), ("just_freed", 0),
                               ("idle_s", None), ("idle_3", None), ("idle_3s ", None), ("warm", None), (None, None)):
            self.assertEqual(R.idle_seconds(value), seconds, value)

    def test_contract_name_round_trip(self):
        family, p = R.parse_run_name(CONTRACT_NAME)
        self.assertEqual(family, "step")
        self.assertEqual(p, {"particles": 31239, "gridder": "B", "cell_order": "sort_x", "reorder": 1,
                             "list": "cll", "list_steps": 1, "kgc": 0, "threads": 1})
        self.assertIsInstance(p["particles"], int)
        shuffled = dict(reversed(list(p.items())))
        self.assertEqual(R.format_run_name("step", shuffled), CONTRACT_NAME)

    def test_optional_axes_and_gb_segments(self):
        _, p = R.parse_run_name(CONTRACT_NAME + "/lattice:cubic/h_coefficient:0.866025/iterations:1/real_time")
        self.assertEqual(p["lattice"], "cubic")
        self.assertAlmostEqual(p["h_coefficient"], 0.866025)
        self.assertNotIn("iterations", p)
        self.assertEqual(R.format_run_name("step", {**p}), CONTRACT_NAME + "/lattice:cubic/h_coefficient:0.866025")

    def test_other_families(self):
        self.assertEqual(R.format_run_name("cellindex", {"particles": 60000, "cell_order": "sort_xyz"}),
                         "cellindex/cell_order:sort_xyz/particles:60000")
        self.assertEqual(R.parse_run_name("cellindex/cell_order:hilbert/particles:1500"),
                         ("cellindex", {"cell_order": "hilbert", "particles": 1500}))

    def test_old_vocabulary_reads_as_the_new(self):
        """Names written before the run-config keys were used everywhere (the
        stored results, an older `make compare` base) parse to the same point."""
        old = "step/n:31239/gridder:B/order:sort_x/reorder:1/list:cll/ns:1/kgc:0/threads:1/hcoef:1.2"
        self.assertEqual(R.parse_run_name(old), R.parse_run_name(CONTRACT_NAME + "/h_coefficient:1.2"))
        self.assertEqual(R.canonical_run_name(old), CONTRACT_NAME + "/h_coefficient:1.2")
        self.assertEqual(R.canonical_run_name(CONTRACT_NAME), CONTRACT_NAME)
        self.assertEqual(R.canonical_run_name("cellindex/order:hilbert/n:1500"),
                         "cellindex/cell_order:hilbert/particles:1500")
        self.assertEqual(R.canonical_run_name("step/n:1500/real_time"), "step/particles:1500/real_time")
        doc = {"benchmarks": [{"name": old, "run_name": old, "run_type": "iteration",
                               "n": 31246, "s_per_step": 1e-3, "time_unit": "ms", "real_time": 1}]}
        row, = R.entry_rows(doc, "fig06")
        self.assertEqual((row["particles"], row["n_particles"], row["cell_order"], row["list_steps"]),
                         (31239, 31246, "sort_x", 1))
        self.assertEqual(row["run_name"], CONTRACT_NAME + "/h_coefficient:1.2")
        self.assertNotIn("n", row)

    def test_old_sweep_axis_is_an_error_naming_the_new_one(self):
        exp = json.loads((REPO / "experiments" / "fig06.json").read_text(encoding="utf-8"))
        exp["sweep"]["tiny"]["n"] = exp["sweep"]["tiny"].pop("particles")
        with self.assertRaisesRegex(R.ResultsError, r"fig06.json: sweep.tiny: sweep axis 'n' was "
                                                    r"renamed to 'particles'"):
            R.validate_experiment(exp, "experiments/fig06.json")

    def test_point_key_matches_numbers_of_any_spelling(self):
        axes = ["particles", "h_coefficient"]
        self.assertEqual(R.point_key({"particles": 1500, "h_coefficient": 1}, axes),
                         R.point_key({"particles": 1500.0, "h_coefficient": 1.0}, axes))


class TestExperiments(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.exps = R.load_experiments(REPO / "experiments")

    def test_every_figure_and_claim_has_code(self):
        for exp_id, exp in self.exps.items():
            if exp.get("figure"):
                self.assertTrue(exp_id == "table1" or exp_id in F.FIGURES, exp_id)
            for c in exp["claims"]:
                self.assertIn(c["id"], C.CLAIMS, f"{exp_id}: claim {c['id']} has no function")
                for key in ("text", "paper_value", "unit", "tolerance", "source"):
                    self.assertIn(key, c, f"{exp_id}/{c['id']}")
                rep, partly = c["tolerance"]["reproduced"], c["tolerance"]["partly"]
                for end, lo_side in ((0, True), (1, False)):  # partly contains reproduced
                    if partly[end] is not None:
                        self.assertIsNotNone(rep[end], c["id"])
                        self.assertTrue(partly[end] <= rep[end] if lo_side else partly[end] >= rep[end],
                                        c["id"])

    def test_the_papers_claims_present(self):
        ids = {c["id"] for e in self.exps.values() for c in e["claims"]}
        for needed in ("table1_cll_list", "table1_vl_force", "A_slower_3x", "A_superlinear",
                       "D_vs_B_unsorted", "C_memory_20x", "A_least_memory", "reorder_gain_BCD",
                       "reorder_gain_A", "sortx_beats_zorder", "zorder_index_100x",
                       "BCD_equal_after_reorder", "A_2x_after_reorder",
                       "B_less_memory_than_D_reordered", "vl_ns1_slower_13pct", "vl_memory_18x",
                       "vl_beats_cll_3_to_15", "best_ns_near_7", "vlx_faster_than_vlc",
                       "vlx_lighter_than_vlc", "vlx_gain_ns7_150k", "kgc_gain_8pct",
                       "neighbour_search_NlnN", "cll_memory_31239", "vl_memory_30x_ns7",
                       "D_memory_150k", "C_memory_150k"):
            self.assertIn(needed, ids)

    def test_time_budgets(self):
        """A default `make reproduce` from a fresh clone stays under 30 min on
        2 cores for the timed experiments, even when every experiment adds
        rounds up to its budget; the counters experiments (valgrind, two
        processes at a time) add at most 20 min more."""
        chosen = [e for e in self.exps.values() if e.get("figure") and not e.get("uses")
                  and e["benchmark"] != "counters"]
        counted = [e for e in self.exps.values() if e["benchmark"] == "counters"]
        self.assertTrue(counted)
        self.assertLess(sum(run.estimate_seconds(e, "default") for e in counted) / 2, 20 * 60)
        nothing = pathlib.Path(tempfile.gettempdir()) / "sphnl-no-cache"
        for size, limit in (("tiny", 60), ("default", 30 * 60)):
            snaps = run.snapshot_seconds(chosen, size, nothing)
            least = sum(run.estimate_seconds(e, size) for e in chosen) + snaps
            most = sum(run.most_seconds(e, size) for e in chosen) + snaps
            self.assertLess(least, limit, size)
            self.assertLess(most, limit, size)
            self.assertLessEqual(least, most)
        self.assertGreater(run.snapshot_seconds(chosen, "default", nothing), 60)
        # `make ablations` (not part of make reproduce) without the six studies
        # at N = 118 853 (README gives their minutes apart): at most 35 min
        ablations = [e for i, e in self.exps.items()
                     if i.startswith("ablation_") or i in ("beyond_loops", "beyond_thread_updates", "peers_first_call")]
        self.assertEqual(len(ablations), 11)
        self.assertTrue(all(e["figure"] is None for e in ablations), "ablations must stay out of make reproduce")
        for size, limit in (("tiny", 90), ("default", 35 * 60)):
            most = sum(run.most_seconds(e, size) for e in ablations) + run.snapshot_seconds(ablations, size, nothing)
            self.assertLess(most, limit, size)

    def test_every_window_holds_whole_list_lifetimes(self):
        for exp in self.exps.values():
            for size in R.SIZES:
                ok, message = P.window_ok(exp, size)
                self.assertTrue(ok, message)
        self.assertGreaterEqual(self.exps["fig14"]["window_steps"]["full"],
                                3 * max(self.exps["fig14"]["sweep"]["full"]["list_steps"]))

    def test_improvement_experiments_sweep_three_flow_states(self):
        for exp_id in ("fig12", "fig14", "fig16", "fig17"):
            for size in ("default", "full"):
                self.assertEqual(self.exps[exp_id]["sweep"][size]["flow_time"], [0.2, 0.35, 0.5],
                                 f"{exp_id} {size}")

    def test_full_keeps_the_papers_n(self):
        full = {i: set(e["sweep"]["full"].get("particles", [])) for i, e in self.exps.items() if not e.get("uses")}
        self.assertTrue({8000, 300000} <= full["fig16"] and 150000 in full["fig16"])
        self.assertIn(31239, full["fig14"])
        self.assertIn(1000000, full["fig12"])
        self.assertIn(150000, full["fig06"])


class TestRunAndLoad(TempDirCase):
    def test_tiny_run_load_and_resume(self):
        out_dir, log = fake_run(self.tmp, "tiny", "--only", "fig06,fig14")
        self.assertIn("[1/2] fig06: 4 configurations", log)
        self.assertIn("round 2, configurations reported 4/4", log)
        self.assertIn("ETA", log)
        self.assertIn("model round time", log)      # round 1: nothing measured yet
        self.assertIn("measured round time", log)   # round 2: the time of round 1
        self.assertEqual(sorted(p.name for p in out_dir.iterdir()),
                         ["fig06.json", "fig14.json", "machine.json"])
        machine = json.loads((out_dir / "machine.json").read_text(encoding="utf-8"))
        for key in ("cpu_model", "cores", "caches", "memory_bytes", "compiler", "git_revision",
                    "date", "size"):
            self.assertIn(key, machine)
        df = R.load_run(out_dir)
        self.assertEqual(len(df), 2 * (4 + 6))  # tiny: 2 rounds of 1 repetition per configuration
        self.assertEqual(sorted(df["round"].unique()), [0, 1])
        self.assertEqual(set(df["gridder"]), {"A", "B", "C", "D"})
        self.assertTrue(str(df["particles"].dtype).startswith("int"), df["particles"].dtype)
        for col in ("s_per_step", "nl_bytes", "n_particles", "s_force", "real_time_s"):
            self.assertIn(col, df)
        mtime = (out_dir / "fig06.json").stat().st_mtime_ns
        _, log2 = fake_run(self.tmp, "tiny", "--only", "fig06")
        self.assertIn("fig06: complete, skipped", log2)
        self.assertEqual((out_dir / "fig06.json").stat().st_mtime_ns, mtime)
        _, log3 = fake_run(self.tmp, "tiny", "--only", "fig06", "--force")
        self.assertIn("[1/1] fig06", log3)

    def test_incomplete_result_is_rerun(self):
        out_dir, _ = fake_run(self.tmp, "tiny", "--only", "fig06")
        doc = json.loads((out_dir / "fig06.json").read_text(encoding="utf-8"))
        last = doc["benchmarks"][-1]["run_name"]
        doc["benchmarks"] = [b for b in doc["benchmarks"] if b["run_name"] != last]
        (out_dir / "fig06.json").write_text(json.dumps(doc), encoding="utf-8")
        _, log = fake_run(self.tmp, "tiny", "--only", "fig06")
        self.assertIn("incomplete (1 sweep points missing)", log)
        self.assertEqual(R.missing_points(out_dir / "fig06.json", R.load_experiments(
            REPO / "experiments")["fig06"], "tiny"), [])

    def test_max_n_then_resume_runs_only_missing_n(self):
        out_dir, log = fake_run(self.tmp, "default", "--only", "fig06", "--max-n", "16000")
        self.assertIn("fig06: 8 configurations", log)  # 4 gridders x N in {8000, 16000}
        path = out_dir / "fig06.json"
        first = json.loads(path.read_text(encoding="utf-8"))["benchmarks"]
        self.assertEqual({R.parse_run_name(b["run_name"])[1]["particles"] for b in first}, {8000, 16000})
        self.assertEqual(json.loads((out_dir / "machine.json").read_text())["max_n"], 16000)
        _, log2 = fake_run(self.tmp, "default", "--only", "fig06", "--max-n", "16000")
        self.assertIn("fig06: complete, skipped", log2)
        # Without the cap the experiment is incomplete; only the missing N run
        # (another seed, so a rerun of a kept N would show) and are merged in.
        _, log3 = fake_run(self.tmp, "default", "--only", "fig06", env={"FAKE_BENCH_SEED": "9"})
        self.assertIn("incomplete (4 sweep points missing)", log3)
        self.assertIn("running only N = 31239", log3)
        merged_doc = json.loads(path.read_text(encoding="utf-8"))
        merged = merged_doc["benchmarks"]
        kept = [b for b in merged if R.parse_run_name(b["run_name"])[1]["particles"] <= 16000]
        self.assertEqual(kept, first)
        # The new rounds are numbered after the kept ones: a round tag names one process.
        first_rounds = {b["sphnl_round"] for b in first}
        new_rounds = {b["sphnl_round"] for b in merged if b not in first}
        self.assertFalse(first_rounds & new_rounds)
        self.assertEqual(len(merged_doc["sphnl_rounds"]), len(first_rounds) + len(new_rounds))
        self.assertEqual(len(merged_doc["sphnl_protocol_earlier"]), 1)
        self.assertEqual(R.missing_points(path, R.load_experiments(REPO / "experiments")["fig06"],
                                          "default"), [])
        self.assertEqual(sorted(p.name for p in out_dir.iterdir()), ["fig06.json", "machine.json"])
        machine = json.loads((out_dir / "machine.json").read_text(encoding="utf-8"))
        self.assertIsNone(machine["max_n"])
        self.assertEqual([e["max_n"] for e in machine["earlier"]], [16000])  # a skip writes nothing

    def test_hidden_files_of_a_run_in_progress_are_ignored(self):
        out_dir, _ = fake_run(self.tmp, "tiny", "--only", "fig06")
        (out_dir / ".fig12.experiment.json").write_text('{"id": "fig12"}', encoding="utf-8")
        (out_dir / ".fig12.json.partial").write_text("{", encoding="utf-8")
        self.assertEqual(set(R.load_run(out_dir)["experiment"]), {"fig06"})

    def test_max_n_rejects_nonsense(self):
        code, _, err = run_cli("--size", "tiny", "--bench", FAKE, "--max-n", "0")
        self.assertEqual(code, 2)
        self.assertIn("--max-n must be a positive", err)

    def test_uses_only_id_runs_its_source(self):
        _, log = fake_run(self.tmp, "tiny", "--only", "fig07")
        self.assertIn("fig07 is drawn from fig06", log)
        self.assertIn("[1/1] fig06", log)

    def test_repetitions_aggregates_and_errors(self):
        out_dir, _ = fake_run(self.tmp, "default", "--only", "fig12",
                              env={"FAKE_BENCH_ERROR": "list:vlc", "FAKE_BENCH_NOISE": "0"})
        df = R.load_run(out_dir)
        configs = 4 * 2 * 3  # N x lists x flow states
        self.assertEqual(len(df), configs * 9)  # 3 rounds x 3; aggregates (_mean, ...) are not rows
        self.assertEqual(sorted(df["repetition_index"].unique()), [0, 1, 2])
        self.assertEqual(sorted(df["round"].unique()), [0, 1, 2])
        self.assertEqual(sorted(df["flow_time"].unique()), [0.2, 0.35, 0.5])
        med = R.medians(df)
        self.assertEqual(list(med["list"].unique()), ["cll"])  # error rows dropped
        self.assertTrue((med["reps"] == 9).all())
        self.assertNotIn("run_sequence", med)  # bookkeeping, not a measurement
        self.assertEqual(len(R.errors(df)), configs // 2)

    def test_missing_binary(self):
        code, _, err = run_cli("--size", "tiny", "--results-dir", self.tmp, "--bench",
                               self.tmp / "nope" / "sphnl_bench", "--only", "fig06")
        self.assertEqual(code, 2)
        self.assertIn("make build", err)
        self.assertFalse((self.tmp / "tiny").exists())

    def test_unknown_experiment(self):
        code, _, err = run_cli("--size", "tiny", "--bench", FAKE, "--only", "fig99")
        self.assertEqual(code, 2)
        self.assertIn("fig99", err)
        self.assertIn("fig06", err)  # the valid ids are listed

    def test_bench_failure_leaves_no_json(self):
        code, _, err = run_cli("--size", "tiny", "--results-dir", self.tmp, "--bench", FAKE,
                               "--run-id", "r", "--only", "fig06", env={"FAKE_BENCH_FAIL": "1"})
        self.assertEqual(code, 1)
        self.assertIn("exited with status 1", err)
        self.assertIn("snapshot checksum mismatch", err)  # the bench's stderr tail
        self.assertEqual([p.name for p in (self.tmp / "r").iterdir()], ["machine.json"])

    def test_corrupt_json_names_the_file(self):
        (self.tmp / "fig06.json").write_text('{"benchmarks": [', encoding="utf-8")
        with self.assertRaisesRegex(R.ResultsError, "fig06.json"):
            R.load_run(self.tmp)


def fake_exp(**over):
    """A minimal `step` experiment definition (a copy of fig16's shape)."""
    sweep = {"particles": [8000], "gridder": ["B"], "cell_order": ["sort_x"], "reorder": [1],
             "list": ["cll", "vlc", "vlx"], "list_steps": [1, 3, 7, 14], "kgc": [0], "threads": [1]}
    proto = {"min_rounds": 3, "max_rounds": 5, "reps_per_round": 3,
             "target_halfwidth_pct": 1.0, "budget_s": 100}
    exp = {"id": "x", "benchmark": "step", "sweep": {s: dict(sweep) for s in R.SIZES},
           "window_steps": {s: 42 for s in R.SIZES}, "protocol": proto, "claims": []}
    for key, value in over.items():
        exp[key] = value
    return exp


class TestProtocolRules(unittest.TestCase):
    def test_window_must_be_a_multiple_of_every_ns(self):
        self.assertEqual(P.window_ok(fake_exp(), "default"), (True, ""))
        ok, message = P.window_ok(fake_exp(window_steps={"default": 40}), "default")
        self.assertFalse(ok)
        for part in ("experiments/x.json", "window_steps.default = 40", "lcm 42", "use 42"):
            self.assertIn(part, message)
        ok, _ = P.window_ok(fake_exp(window_steps={"default": 28}), "default")  # 28 % 3 != 0
        self.assertFalse(ok)

    def test_window_must_cover_three_lifetimes(self):
        exp = fake_exp(window_steps={"default": 14})
        exp["sweep"]["default"]["list_steps"] = [7, 14]  # a multiple of both, but one lifetime of 14
        ok, message = P.window_ok(exp, "default")
        self.assertFalse(ok)
        self.assertIn("3 x 14 = 42", message)
        exp["window_steps"]["default"] = 42
        self.assertTrue(P.window_ok(exp, "default")[0])

    def test_cll_only_sweeps_have_no_window_rule(self):
        exp = fake_exp(window_steps={"default": 5})
        exp["sweep"]["default"]["list"] = ["cll"]
        self.assertTrue(P.window_ok(exp, "default")[0])

    def test_a_broken_window_stops_the_run_naming_file_and_field(self):
        with tempfile.TemporaryDirectory() as tmp:
            exp = json.loads((REPO / "experiments" / "fig16.json").read_text(encoding="utf-8"))
            exp["window_steps"]["default"] = 20
            (pathlib.Path(tmp) / "fig16.json").write_text(json.dumps(exp), encoding="utf-8")
            with self.assertRaisesRegex(R.ResultsError, r"fig16\.json: window_steps\.default = 20"):
                R.load_experiments(tmp)

    def test_protocol_block(self):
        self.assertEqual(P.protocol_of(fake_exp(), "default")["reps_per_round"], 3)
        per_size = fake_exp(protocol={s: {**fake_exp()["protocol"], "budget_s": i + 1}
                                      for i, s in enumerate(R.SIZES)})
        self.assertEqual(P.protocol_of(per_size, "full")["budget_s"], 3)
        for bad, needle in (({"min_rounds": 2}, "at least 3 separate processes"),
                            ({"reps_per_round": 2}, "at least 9 repetitions"),
                            ({"max_rounds": 2}, "below min_rounds"),
                            ({"budget_s": 0}, "protocol.budget_s is 0"),
                            ({"reps_per_round": 2.5}, "whole number")):
            with self.assertRaisesRegex(P.ProtocolError, needle):
                P.protocol_of(fake_exp(protocol={**fake_exp()["protocol"], **bad}), "default")
        with self.assertRaisesRegex(P.ProtocolError, "experiments/x.json: no 'protocol' block"):
            P.protocol_of(fake_exp(protocol=None), "default")
        with self.assertRaisesRegex(P.ProtocolError, "no size 'full'"):
            P.protocol_of(fake_exp(protocol={"tiny": fake_exp()["protocol"]}), "full")

    def test_bootstrap_halfwidth(self):
        self.assertEqual(P.median_halfwidth_pct([[2.0] * 3] * 3), 0.0)
        self.assertEqual(P.median_halfwidth_pct([[1.0]]), math.inf)
        rng = np.random.default_rng(3)
        narrow = P.median_halfwidth_pct([1 + 0.001 * rng.standard_normal(9)])
        wide = P.median_halfwidth_pct([1 + 0.05 * rng.standard_normal(9)])
        self.assertLess(narrow, 0.2)
        self.assertGreater(wide, 1.0)
        # Quiet rounds that disagree: the drift between processes, which
        # pooling the repetitions would hide, keeps the interval wide.
        drift = [list(1 + 0.001 * rng.standard_normal(15) + shift) for shift in (0, 0.03, -0.03)]
        self.assertGreater(P.median_halfwidth_pct(drift), 1.0)
        self.assertLess(P.median_halfwidth_pct([sum(drift, [])]), 0.5)
        uneven = [drift[0][:5], drift[1], drift[2][:9]]  # the general path
        self.assertGreater(P.median_halfwidth_pct(uneven), 1.0)

    def test_stop_reason(self):
        proto = P.protocol_of(fake_exp(), "default")  # 3-5 rounds, +-1 %, 100 s
        quiet = {"a": [[1.0] * 3] * 3, "b": [[2.0] * 3] * 3}
        noisy = {"a": [[1.0, 1.1, 0.9]] * 3, "b": [[2.0] * 3] * 3}
        self.assertIsNone(P.stop_reason(quiet, proto, 2, 10, 5))  # below the minimum rounds
        self.assertEqual(P.stop_reason(quiet, proto, 3, 10, 5), P.STOP_TARGET)
        self.assertIsNone(P.stop_reason(noisy, proto, 3, 10, 5))  # another round fits
        self.assertEqual(P.stop_reason(noisy, proto, 3, 90, 30), P.STOP_BUDGET)
        self.assertEqual(P.stop_reason(noisy, proto, 5, 10, 2), P.STOP_MAX)
        self.assertEqual(P.stop_reason(quiet, proto, 5, 500, 100), P.STOP_TARGET)  # target first

    def test_executed_order_and_warmups(self):
        entries = [{"run_name": "b", "run_sequence": 3}, {"run_name": "a", "run_sequence": 1},
                   {"run_name": "b", "run_sequence": 4}, {"run_name": "a", "run_sequence": 5}]
        self.assertEqual(P.executed_order(entries), (["a", "b", "b", "a"], 2))  # 0 and 2 discarded
        self.assertEqual(P.executed_order([{"run_name": "a"}]), (["a"], None))


def read_doc(path):
    return json.loads(pathlib.Path(path).read_text(encoding="utf-8"))


class TestRounds(TempDirCase):
    """The round scheduler end to end with the fake bench (default size)."""

    @classmethod
    def setUpClass(cls):
        cls.base = pathlib.Path(tempfile.mkdtemp(prefix="sphnl-rounds-"))
        cls.run_dir, cls.log = fake_run(cls.base, "default", "--only", "fig16",
                                        env={"FAKE_BENCH_NOISE": "0"})
        cls.doc = read_doc(cls.run_dir / "fig16.json")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.base, ignore_errors=True)

    def test_every_configuration_in_every_round(self):
        exp = R.load_experiments(REPO / "experiments")["fig16"]
        names = {R.format_run_name("step", p) for p in R.sweep_points(exp, "default")}
        self.assertEqual(len(names), 3 * 3 * 3)  # N x lists x flow states
        rounds = self.doc["sphnl_rounds"]
        self.assertEqual([r["round"] for r in rounds], [0, 1, 2])
        for r in rounds:
            mine = [b for b in self.doc["benchmarks"] if b["sphnl_round"] == r["round"]]
            self.assertEqual(collections.Counter(b["run_name"] for b in mine),
                             collections.Counter({n: 3 for n in names}))
            self.assertEqual(collections.Counter(r["order"]), collections.Counter({n: 3 for n in names}))
            self.assertEqual(r["warmups_discarded"], len(names))  # one per configuration
        self.assertFalse([b for b in self.doc["benchmarks"] if b.get("run_type") != "iteration"])

    def test_order_is_interleaved_random_and_recorded(self):
        orders = [r["order"] for r in self.doc["sphnl_rounds"]]
        self.assertEqual(len({tuple(o) for o in orders}), 3, "every round has its own order")
        for order in orders:
            blocks = sum(1 for a, b in zip(order, order[1:]) if a != b) + 1
            self.assertGreater(blocks, 27, "repetitions alternate between configurations")
            self.assertNotEqual(order, sorted(order))

    def test_protocol_and_noise_record(self):
        proto = self.doc["sphnl_protocol"]
        self.assertEqual((proto["rounds"], proto["reps_per_round"], proto["stop_reason"]),
                         (3, 3, P.STOP_TARGET))
        self.assertIn("3 rounds (target met)", self.log)
        for r in self.doc["sphnl_rounds"]:
            for key in ("started", "ended", "loadavg_before", "loadavg_after", "steal_pct",
                        "cpu_affinity", "cpu_mhz", "under_load", "git_revision", "bench_sha256"):
                self.assertIn(key, r)
            self.assertEqual((r["omp_proc_bind"], r["omp_places"]), ("close", "cores"))
            self.assertEqual(r["git_revision"], "a" * 40)
            self.assertEqual(r["bench_sha256"], M.sha256(FAKE))
            self.assertIsInstance(r["under_load"], bool)

    def test_flow_time_segment(self):
        names = {b["run_name"] for b in self.doc["benchmarks"]}
        self.assertTrue(any(n.endswith("/threads:1/flow_time:0.2") for n in names), names)
        df = R.load_run(self.run_dir)
        self.assertEqual(sorted(df["flow_time"].unique()), [0.2, 0.35, 0.5])

    def test_noise_adds_rounds_until_max(self):
        out, log = fake_run(self.tmp, "default", "--only", "table1", env={"FAKE_BENCH_NOISE": "0.05"})
        proto = read_doc(out / "table1.json")["sphnl_protocol"]
        self.assertEqual((proto["rounds"], proto["stop_reason"]), (5, P.STOP_MAX))
        self.assertEqual(len(R.load_run(out)), 2 * 5 * 3)
        self.assertIn("5 rounds (max rounds)", log)

    def test_a_window_without_the_axis_is_t_035(self):
        out, _ = fake_run(self.tmp, "tiny", "--only", "fig06")
        self.assertFalse([b for b in read_doc(out / "fig06.json")["benchmarks"]
                          if "flow_time" in b["run_name"]])
        self.assertEqual(set(R.load_run(out)["flow_time"]), {0.35})


def strings(value):
    if isinstance(value, dict):
        return [s for v in value.values() for s in strings(v)]
    if isinstance(value, list):
        return [s for v in value for s in strings(v)]
    return [value] if isinstance(value, str) else []


class TestProvenance(TempDirCase):
    def test_machine_json_has_no_absolute_path_and_the_cpu(self):
        out, _ = fake_run(self.tmp, "tiny", "--only", "fig06")
        machine = read_doc(out / "machine.json")
        self.assertFalse([s for s in strings(machine) if s.startswith("/") or str(self.tmp) in s
                          or str(REPO) in s], machine)
        self.assertEqual(machine["bench"], "tests/python/fake_bench.py")
        self.assertEqual(machine["bench_sha256"], M.sha256(FAKE))
        for key in ("cpu_model", "cpu_family", "cpu_model_number", "cpu_stepping", "cpu_mhz",
                    "cpu_max_mhz", "caches", "caches_sysfs", "loadavg_start", "loadavg_end", "parts",
                    "free_memory_reported_to_host", "transparent_huge_pages"):
            self.assertIn(key, machine)
        if M.sysfs_caches():  # where sysfs has them, the caches are never empty
            self.assertTrue(machine["caches"])
            self.assertTrue(set(machine["caches_sysfs"]) & {"L1d", "L2"})
        self.assertEqual(len(machine["loadavg_end"]), 3)
        self.assertFalse(machine["forced_merge"])

    def test_sysfs_cache_reader(self):
        with tempfile.TemporaryDirectory() as tmp:
            for i, (level, kind, size) in enumerate(((1, "Data", "48K"), (1, "Instruction", "32K"),
                                                     (2, "Unified", "1024K"))):
                d = pathlib.Path(tmp) / "cpu0" / "cache" / f"index{i}"
                d.mkdir(parents=True)
                for name, value in (("level", level), ("type", kind), ("size", size)):
                    (d / name).write_text(f"{value}\n")
            old, M.CPU_SYS = M.CPU_SYS, pathlib.Path(tmp)
            try:
                self.assertEqual(M.sysfs_caches(), {"L1d": "48K", "L1i": "32K", "L2": "1024K"})
            finally:
                M.CPU_SYS = old

    def test_free_page_reporting_reader(self):
        """The balloon's free page reporting bit (virtio device 0x0005,
        feature bit 5), read as the library reads it: other devices and a
        balloon without the bit say no, a missing tree says no."""
        with tempfile.TemporaryDirectory() as tmp:
            root = pathlib.Path(tmp)
            self.assertFalse(M.free_memory_reported_to_host(root))  # no bus/virtio at all
            for name, device, features in (("virtio0", "0x0001", "111111"), ("virtio1", "0x0005", "111110")):
                d = root / "bus" / "virtio" / "devices" / name
                d.mkdir(parents=True)
                (d / "device").write_text(device + "\n")
                (d / "features").write_text(features + "000\n")
            self.assertFalse(M.free_memory_reported_to_host(root))
            (root / "bus" / "virtio" / "devices" / "virtio1" / "features").write_text("111111000\n")
            self.assertTrue(M.free_memory_reported_to_host(root))
        self.assertIn(M.transparent_huge_pages(), ("always", "madvise", "never", None))

    def test_the_report_says_what_decides_a_first_calls_pages(self):
        """The Memory row names the THP mode and whether free memory is
        reported to the host; a machine.json older than those fields says nothing."""
        self.assertEqual(report.memory_pages({}), "")
        said = report.memory_pages({"transparent_huge_pages": "madvise", "free_memory_reported_to_host": True})
        self.assertIn("transparent huge pages madvise", said)
        self.assertIn("search defaults to base pages", said)
        self.assertIn("not reported", report.memory_pages({"free_memory_reported_to_host": False}))
        out, _ = fake_run(self.tmp, "tiny", "--only", "fig06")
        lines, _ = report.machine_section(out)
        memory = [line for line in lines if line.startswith("| Memory |")]
        self.assertEqual(len(memory), 1, lines)
        self.assertIn("free memory", memory[0])

    def test_merge_refusal_rules(self):
        part = {"date": "d1", "git_revision": "a" * 40, "git_dirty": False, "bench_sha256": "1" * 64}
        self.assertIsNone(M.merge_refusal([part], dict(part)))
        self.assertIn("uncommitted changes", M.merge_refusal([part], {**part, "git_dirty": True}))
        self.assertIn("git revision differs", M.merge_refusal([part], {**part, "git_revision": "b" * 40}))
        self.assertIn("bench binary differs", M.merge_refusal([part], {**part, "bench_sha256": "2" * 64}))
        self.assertIn("earlier part", M.merge_refusal([{**part, "git_dirty": True}], part))
        amd = {"cpu_vendor": "AuthenticAMD", "cpu_model": "AMD EPYC", "cpu_family": 26, "cpu_model_number": 2,
               "logical_cpus": 2}
        intel = {"cpu_vendor": "GenuineIntel", "cpu_model": "Intel Xeon", "cpu_family": 6,
                 "cpu_model_number": 207, "logical_cpus": 2}
        self.assertIsNone(M.merge_refusal([{**part, "machine": amd}], {**part, "machine": dict(amd)}))
        why = M.merge_refusal([{**part, "machine": amd}], {**part, "machine": intel})
        self.assertIn("machine differs", why)
        self.assertIn("AMD EPYC (family 26, model 2), 2 logical CPUs", why)
        self.assertIn("here Intel Xeon (family 6, model 207)", why)
        self.assertIn("machine differs", M.merge_refusal([{**part, "machine": amd}],
                                                         {**part, "machine": {**amd, "logical_cpus": 4}}))
        # a part recorded before parts carried their machine is not refused for it
        self.assertIsNone(M.merge_refusal([part], {**part, "machine": intel}))

    def test_snapshot_development_is_recorded_and_not_charged_to_the_budget(self):
        out, _ = fake_run(self.tmp, "tiny", "--only", "table1", env={"FAKE_BENCH_SNAPSHOT": "123.4"})
        rounds = read_doc(out / "table1.json")["sphnl_rounds"]
        self.assertEqual([r["snapshot_s"] for r in rounds], [123.4] * len(rounds))
        self.assertEqual(run.measuring_seconds(300.0, [{"snapshot_s": 240.0}, {"snapshot_s": 0.0}]), 60.0)
        self.assertEqual(run.measuring_seconds(10.0, [{"snapshot_s": 12.0}]), 0.0)  # clock granularity
        self.assertEqual(run.measuring_seconds(10.0, [{"round": 0}]), 10.0)  # a record without the field

    def test_under_load_is_decided_by_what_others_used_during_the_round(self):
        quiet = {"loadavg_before": [0.7, 1.2, 1.6], "loadavg_after": [1.6, 1.5, 1.6],
                 "other_busy_cores": 0.0, "steal_pct": 0.01, "under_load": True}
        # the load average holds the run's own snapshot development: not load
        self.assertFalse(M.under_load(quiet, bench_threads=1))
        self.assertFalse(M.under_load(quiet))
        self.assertTrue(M.under_load({**quiet, "other_busy_cores": 0.63}))
        self.assertTrue(M.under_load({**quiet, "steal_pct": 2.5}))
        self.assertFalse(M.under_load({**quiet, "other_busy_cores": 0.5, "steal_pct": 1.0}))  # limits included
        # without /proc/stat: the load average against the bench's threads, else the stored flag
        blind = {"loadavg_before": [2.6, 2.0, 1.0], "loadavg_after": [1.0, 1.0, 1.0],
                 "other_busy_cores": None, "steal_pct": None}
        self.assertTrue(M.under_load(blind, bench_threads=2))
        self.assertFalse(M.under_load(blind, bench_threads=3))
        self.assertTrue(M.under_load({**blind, "under_load": True}))
        self.assertFalse(M.under_load({**blind, "under_load": False}))

    def test_the_report_flags_rounds_by_todays_rule(self):
        d = self.tmp / "run"
        d.mkdir()
        rounds = [{"round": 0, "loadavg_before": [0.7, 1, 1], "loadavg_after": [1.9, 1, 1],
                   "other_busy_cores": 0.0, "steal_pct": 0.0, "under_load": True},
                  {"round": 1, "loadavg_before": [0.5, 1, 1], "loadavg_after": [0.6, 1, 1],
                   "other_busy_cores": 0.9, "steal_pct": 0.0, "under_load": False}]
        (d / "fig06.json").write_text(json.dumps({"benchmarks": [], "sphnl_rounds": rounds,
                                                  "sphnl_protocol": {"reps_per_round": 3}}))
        lines, flagged = report.rounds_section(d)
        self.assertEqual(flagged, 1)
        self.assertIn("**under load**: 1 of 2 rounds (1;", lines[0])

    def test_an_old_machine_json_gives_its_last_part_the_top_level_machine(self):
        old = {"cpu_vendor": "AuthenticAMD", "cpu_model": "AMD EPYC", "cpu_family": 26, "cpu_model_number": 2,
               "logical_cpus": 2, "memory_bytes": 1,
               "parts": [{"date": "d1", "git_revision": "a" * 40}, {"date": "d2", "git_revision": "a" * 40}]}
        parts = run.earlier_parts(old)
        self.assertNotIn("machine", parts[0])  # unknown: the top level is the last part's machine
        self.assertEqual(parts[1]["machine"], M.machine_identity(old))
        self.assertNotIn("machine", old["parts"][1])  # the record read is left as it was

    def test_merge_of_a_part_is_refused_unless_forced(self):
        out, _ = fake_run(self.tmp, "default", "--only", "fig06", "--max-n", "16000")
        before = (out / "fig06.json").read_bytes()
        elsewhere = json.dumps({"cpu_vendor": "v", "cpu_model": "Another CPU", "cpu_family": 1,
                                "cpu_model_number": 1, "logical_cpus": 64})
        for env, needle in (({M.TEST_REVISION: "b" * 40}, "git revision differs"),
                            ({M.TEST_DIRTY: "1"}, "uncommitted changes"),
                            ({M.TEST_IDENTITY: elsewhere}, "machine differs")):
            code, _, err = run_cli("--size", "default", "--results-dir", self.tmp, "--bench", FAKE,
                                   "--run-id", "r", "--only", "fig06", env=env)
            self.assertEqual(code, 2, err)
            self.assertIn(needle, err)
            self.assertIn("--force-merge", err)
            self.assertEqual((out / "fig06.json").read_bytes(), before)  # nothing touched
        code, _, err = run_cli("--size", "default", "--results-dir", self.tmp, "--bench", FAKE,
                               "--run-id", "r", "--only", "fig06", "--force-merge", "comment-only change",
                               env={M.TEST_REVISION: "b" * 40})
        self.assertEqual(code, 0, err)
        machine = read_doc(out / "machine.json")
        self.assertTrue(machine["forced_merge"])
        self.assertIn("comment-only change", machine["forced_merge_reason"])
        self.assertEqual([p["git_revision"][0] for p in machine["parts"]], ["a", "b"])
        self.assertTrue(machine["parts"][1]["forced_merge"])
        rounds = read_doc(out / "fig06.json")["sphnl_rounds"]
        self.assertEqual([r["round"] for r in rounds], list(range(len(rounds))))
        self.assertEqual({r["git_revision"][0] for r in rounds}, {"a", "b"})

    def test_a_bench_built_from_other_code_is_refused_unless_allowed(self):
        # A revision this repository does not hold: refused whatever the tree's state.
        other = {"FAKE_BENCH_REVISION": "0000000abcde"}
        code, _, err = run_cli("--size", "tiny", "--results-dir", self.tmp, "--bench", FAKE,
                               "--run-id", "r", "--only", "fig06", env=other)
        self.assertEqual(code, 2, err)
        self.assertIn("does not measure this checkout's code", err)
        self.assertIn("0000000abcde", err)
        self.assertIn("--allow-other-build", err)
        self.assertFalse((self.tmp / "r" / "fig06.json").exists())  # refused before measuring
        code, _, err = run_cli("--size", "tiny", "--results-dir", self.tmp, "--bench", FAKE, "--run-id", "r",
                               "--only", "fig06", "--allow-other-build", "bench of a deleted branch", env=other)
        self.assertEqual(code, 0, err)
        part = read_doc(self.tmp / "r" / "machine.json")["parts"][-1]
        self.assertEqual(part["builds"]["bench"], "0000000abcde")
        self.assertIn("bench of a deleted branch", part["builds"]["other_build_reason"])
        lines, _ = report.machine_section(self.tmp / "r")
        self.assertTrue(any("Other build" in line and "deleted branch" in line for line in lines), lines)

    def test_the_build_revision_is_compared_with_the_code_of_the_checkout(self):
        repo = self.tmp / "repo"
        (repo / "core").mkdir(parents=True)
        (repo / "docs").mkdir()

        def git(*a):
            return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *a], cwd=repo,
                                  check=True, capture_output=True, text=True).stdout.strip()

        def commit(path, text):
            (repo / path).write_text(text)
            git("add", "-A")
            git("commit", "-q", "-m", path)
            return git("rev-parse", "--short=12", "HEAD")
        git("init", "-q")
        first = commit("core/a.hpp", "int a;\n")
        docs = commit("docs/x.md", "words\n")
        self.assertIsNone(M.build_mismatch(first, repo))  # only docs changed since the build
        self.assertIsNone(M.build_mismatch(docs, repo))
        self.assertIsNone(M.build_mismatch("unknown", repo))
        self.assertIn("does not hold", M.build_mismatch("0000000abcde", repo))
        self.assertIn("uncommitted changes on", M.build_mismatch(docs + "-dirty", repo))
        code = commit("core/a.hpp", "int b;\n")
        why = M.build_mismatch(first, repo)
        self.assertIn("the code changed", why)
        self.assertIn("core/a.hpp", why)
        self.assertIsNone(M.build_mismatch(code, repo))
        (repo / "core" / "a.hpp").write_text("int c;\n")
        self.assertIn("uncommitted changes to the code", M.build_mismatch(code, repo))
        self.assertIsNone(M.build_mismatch(code + "-dirty", repo))  # as far as can be told

    def test_the_report_names_the_machine_of_each_earlier_part(self):
        out, _ = fake_run(self.tmp, "default", "--only", "fig06", "--max-n", "16000")
        fake_run(self.tmp, "default", "--only", "fig06")  # the rest of fig06: a second part
        lines, _ = report.machine_section(out)
        earlier = [line for line in lines if line.startswith("| Earlier part |")]
        self.assertEqual(len(earlier), 1, lines)
        self.assertIn(f"on {M.describe_identity(M.machine_identity())}", earlier[0])

    def test_force_merge_needs_a_reason(self):
        code, _, err = run_cli("--size", "tiny", "--bench", FAKE, "--force-merge", " ")
        self.assertEqual(code, 2)
        self.assertIn("--force-merge needs a reason", err)


class TestFiguresAndReport(TempDirCase):
    @classmethod
    def setUpClass(cls):
        cls.base = pathlib.Path(tempfile.mkdtemp(prefix="sphnl-tiny-"))
        # the figures of make reproduce, and peers_first_call (make ablations), whose figure is drawn too
        drawn = [p.stem for p in (REPO / "experiments").glob("*.json")
                 if (json.loads(p.read_text()).get("figure") and json.loads(p.read_text())["benchmark"] != "counters")
                 or p.stem == "peers_first_call"]
        cls.run_dir, _ = fake_run(cls.base, "tiny", "--only", ",".join(sorted(drawn)))
        cls.df = R.load_run(cls.run_dir)
        cls.exps = R.load_experiments(REPO / "experiments")
        # few replicates: these tests check what is drawn, not the intervals
        cls.saved_resamples, F.RESAMPLES = F.RESAMPLES, 20

    @classmethod
    def tearDownClass(cls):
        F.RESAMPLES = cls.saved_resamples
        shutil.rmtree(cls.base, ignore_errors=True)

    def timed_figures(self):
        """Every figure the fake bench can feed: the counters figures are drawn
        from valgrind counts (tests/python/test_counters.py), beyond_mpi from
        `sphnl run` under mpirun (tests/python/test_beyond_mpi.py)."""
        return {fig_id: fn for fig_id, fn in F.FIGURES.items()
                if self.exps[self.exps[fig_id].get("uses") or fig_id]["benchmark"] not in ("counters", "mpi")}

    def draw_all(self, out):
        for fig_id, fn in self.timed_figures().items():
            src = self.exps[fig_id].get("uses") or fig_id
            sentence = fn(self.df[self.df["experiment"] == src], out)
            self.assertTrue(sentence.endswith("."), fig_id)

    def test_every_figure_png_svg_deterministic(self):
        a, b = self.tmp / "a", self.tmp / "b"
        self.draw_all(a)
        self.draw_all(b)
        for fig_id in self.timed_figures():
            for ext in ("png", "svg"):
                self.assertGreater((a / f"{fig_id}.{ext}").stat().st_size, 1000, fig_id)
                self.assertEqual((a / f"{fig_id}.{ext}").read_bytes(), (b / f"{fig_id}.{ext}").read_bytes(),
                                 f"{fig_id}.{ext} differs between two runs")
        self.assertEqual(sorted(p.name for p in a.iterdir() if p.name.startswith(".")), [])

    def test_table1(self):
        md, sentence = F.table1(self.df[self.df["experiment"] == "table1"], self.exps["table1"])
        self.assertIn("| Neighbour List | 1.7 %", md)
        self.assertIn("VL step", sentence)

    def test_peer_table_reads_every_configuration_with_its_interval(self):
        # Synthetic peers rows with known answers: sphnl lists 25x as fast as
        # nanoflann on one thread and gains 1.5x from a second; nanoflann none.
        rng = np.random.default_rng(1)
        rows = []
        for rnd, rep, impl, th, cloud, order, call in itertools.product(
                range(3), range(3), ("sphnl", "nanoflann"), (1, 2), ("lattice", "random"),
                ("generated", "shuffled"), ("warm", "first")):
            eps = (100.0 if impl == "sphnl" else 4.0) * (1.5 if impl == "sphnl" and th == 2 else 1.0)
            eps *= 1 + 0.01 * rng.standard_normal()
            rows.append(dict(experiment="peers", family="search", particles=1000, threads=th, impl=impl,
                             cloud=cloud, memory_order=order, call=call, entries_per_s=eps,
                             run_name=f"search/particles:1000/threads:{th}/impl:{impl}/cloud:{cloud}"
                                      f"/memory_order:{order}/call:{call}",
                             repetition_index=rep, round=rnd, error_occurred=False))
        table = F._peer_table(F._med(pd.DataFrame(rows), family="search")).splitlines()
        body = [line for line in table if line.startswith(("| lattice", "| random"))]
        self.assertEqual(len(body), 8)
        for line in body:
            cells = re.findall(r"([\d.]+) \[([\d.]+), ([\d.]+)\]", line)
            self.assertEqual(len(cells), 4, line)
            for (value, lo, hi), want in zip(cells, (25.0, 37.5, 1.5, 1.0)):
                value, lo, hi = float(value), float(lo), float(hi)
                self.assertLess(abs(value / want - 1), 0.03, line)
                self.assertLessEqual(lo, value)
                self.assertLessEqual(value, hi)
                self.assertLess(hi / lo, 1.1, line)

    def test_peers_first_call_figure_names_the_smallest_ratio_per_memory_state(self):
        # Synthetic first calls: sphnl 8x nanoflann just freed, 3x (lattice) or
        # 6x (random) idle; idle memory costs sphnl 2x or 1.3x, nanoflann 1.1x.
        rng = np.random.default_rng(2)
        rows = []
        for rnd, rep, impl, th, cloud, state in itertools.product(
                range(3), range(3), ("sphnl", "nanoflann"), (1, 2), ("lattice", "random"), ("just_freed", "idle_3s")):
            seconds = 1.0 if impl == "nanoflann" else 0.125
            if state == "idle_3s":
                seconds *= 1.1 if impl == "nanoflann" else (1.1 * 8 / 3 if cloud == "lattice" else 1.1 * 8 / 6)
            seconds *= 1 + 0.01 * rng.standard_normal()
            rows.append(dict(experiment="peers_first_call", family="search", particles=150000, threads=th,
                             impl=impl, cloud=cloud, memory_order="generated", call="first", freed_memory=state,
                             entries_per_s=1e7 / seconds, s_call=seconds, repetition_index=rep, round=rnd,
                             run_name=f"search/{impl}/{cloud}/{th}/{state}", error_occurred=False))
        sentence = F.peers_first_call(pd.DataFrame(rows), self.tmp)
        self.assertTrue((self.tmp / "peers_first_call.png").exists())
        self.assertTrue((self.tmp / "peers_first_call.svg").exists())
        found = re.findall(r"(just freed|idle 3 s) ([\d.]+)x \[([\d.]+), ([\d.]+)\] \((\w+),", sentence)
        self.assertEqual([f[0] for f in found], ["just freed", "idle 3 s"], sentence)
        self.assertLess(abs(float(found[0][1]) / 8 - 1), 0.03, sentence)
        self.assertLess(abs(float(found[1][1]) / 3 - 1), 0.03, sentence)
        self.assertEqual(found[1][4], "lattice", sentence)
        for _, value, lo, hi, _ in found:
            self.assertLessEqual(float(lo), float(value))
            self.assertLessEqual(float(value), float(hi))
        with self.assertRaises(F.NoData):  # the peers experiment's first calls have no freed_memory axis
            F.peers_first_call(pd.DataFrame(rows).drop(columns="freed_memory"), self.tmp)

    def test_missing_data_is_reported_not_raised(self):
        with self.assertRaises(F.NoData):
            F.fig08(self.df[self.df["experiment"] == "fig06"], self.tmp)  # no reordered runs

    def test_report_tiny_and_its_published_copy(self):
        # One report (the costly part: every figure drawn) serves both checks.
        run_dir = self.tmp / "results" / "run"
        shutil.copytree(self.run_dir, run_dir)
        (run_dir / "fig09.json").unlink()
        published = self.tmp / "results" / "REPRODUCTION.md"
        with contextlib.redirect_stdout(io.StringIO()):
            self.assertEqual(report.main([str(run_dir), "--publish", str(published)]), 0)
        text = (run_dir / "REPRODUCTION.md").read_text(encoding="utf-8")
        self.assertIn("| Figure | Claim | Paper | Measured [95 % interval] | Verdict | Note |", text)
        self.assertIn("tiny run", text)
        self.assertIn("fig09 (Figure 9): `fig09.json` is missing", text)
        for exp in self.exps.values():
            for c in exp["claims"]:
                self.assertIn(f"(`{c['id']}`)", text)
        self.assertIn("not measured", text)
        self.assertNotIn("| reproduced |", text)  # nothing is measured on a tiny run
        self.assertTrue((run_dir / "table1.md").exists())
        self.assertTrue((run_dir / "figures" / "fig06.svg").exists())
        self.assertFalse((run_dir / "figures" / "fig09.png").exists())
        # --publish: the same text, its links rewritten to point into the run folder
        copy = published.read_text(encoding="utf-8")
        self.assertIn("](figures/fig06.png)", text)
        self.assertIn("](run/figures/fig06.png)", copy)
        self.assertNotIn("](figures/", copy)
        self.assertEqual(copy.replace("](run/", "]("), text)

    def test_report_corrupt_json(self):
        run_dir = self.tmp / "run"
        shutil.copytree(self.run_dir, run_dir)
        (run_dir / "fig12.json").write_text("not json", encoding="utf-8")
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            self.assertEqual(report.main([str(run_dir)]), 2)
        self.assertIn("fig12.json", err.getvalue())


def synthetic(rows):
    """A results DataFrame as load_run makes it, from (params, counters) pairs."""
    out = []
    for params, ctr in rows:
        full = {"experiment": "x", "family": "step", "cell_order": "sort_x", "list": "cll", "list_steps": 1,
                "kgc": 0, "threads": 1, "repetition_index": 0, "error_occurred": False,
                "error_message": "", **params}
        out.append({**full, "run_name": R.format_run_name("step", {k: v for k, v in full.items()
                                                                  if k in R.FAMILY_KEYS["step"]}),
                    "n_particles": params["particles"], **ctr})
    return pd.DataFrame(out)


class TestClaims(unittest.TestCase):
    def gridder_data(self, slow_a):
        rows = []
        for n in (8000, 31239, 60000):
            for g, f in (("A", slow_a * n / 8000), ("B", 1.2), ("C", 1.25), ("D", 1.0)):
                rows.append(({"particles": n, "gridder": g, "reorder": 0},
                             {"s_per_step": 1e-6 * n * f, "nl_bytes": 10 * n}))
        return synthetic(rows)

    def claim(self, claim_id):
        return next(c for e in R.load_experiments(REPO / "experiments").values()
                    for c in e["claims"] if c["id"] == claim_id)

    def test_verdict_intervals(self):
        band = {"reproduced": [3, 6], "partly": [2, 10]}
        self.assertEqual(C.verdict(3.5, 3.5, 3.5, band)[0], "reproduced")
        self.assertEqual(C.verdict(2.5, 2.5, 2.5, band)[0], "partly")
        self.assertEqual(C.verdict(1.5, 1.5, 1.5, band)[0], "not reproduced")
        self.assertEqual(C.verdict(float("nan"), 0, 1, band)[0], "not measured")

    def test_claim_that_holds_is_reproduced(self):
        r = C.evaluate(self.claim("A_slower_3x"), self.gridder_data(slow_a=1.0))
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["value"], 7.5 / 1.25)
        self.assertIn("paper: N = 150 000", r["note"])
        # claims.json's at_n is the N the value was read at, not the wanted one
        self.assertEqual((r["at_n"], r["at_n_wanted"]), (60000, 150000))
        at_wanted = C.evaluate({**self.claim("A_slower_3x"), "at_n": 31239}, self.gridder_data(slow_a=1.0))
        self.assertEqual(at_wanted["at_n"], 31239)
        self.assertNotIn("at_n_wanted", at_wanted)
        r = C.evaluate(self.claim("A_superlinear"), self.gridder_data(1.0))
        self.assertAlmostEqual(r["value"], 1.0)  # t_A / t_B grows as N^1 in gridder_data

    def test_claim_that_fails_is_not_reproduced(self):
        r = C.evaluate(self.claim("A_slower_3x"), self.gridder_data(slow_a=0.15))
        self.assertEqual(r["verdict"], "not reproduced", r)
        r = C.evaluate(self.claim("D_vs_A_unsorted"), self.gridder_data(slow_a=0.15))
        self.assertEqual(r["verdict"], "not reproduced", r)

    def test_not_measured(self):
        small = synthetic([({"particles": 1500, "gridder": g, "reorder": 0}, {"s_per_step": 1.0, "nl_bytes": 1})
                           for g in "ABCD"])
        r = C.evaluate(self.claim("A_slower_3x"), small)
        self.assertEqual(r["verdict"], "not measured")
        self.assertIn("1 500", r["note"])
        r = C.evaluate({**self.claim("A_slower_3x"), "id": "no_such_claim"}, self.gridder_data(1))
        self.assertEqual(r["verdict"], "not measured")
        one_n = self.gridder_data(1.0)
        self.assertEqual(C.evaluate(self.claim("A_superlinear"), one_n[one_n["particles"] == 60000])["verdict"],
                         "not measured")

    def test_nlnn_fit(self):
        """The claim is the exponent of the candidate pairs per step (N ln N: ~1.1),
        with the interactions and the runtime per interaction beside it."""
        rows = [({"particles": n, "gridder": "B", "reorder": 1},
                 {"s_per_step": 1e-7 * n ** 1.3, "candidates_per_particle": 10 * math.log(n),
                  "interactions_per_particle": 5 * math.log(n)}) for n in (8000, 16000, 31239, 60000)]
        r = C.evaluate(self.claim("neighbour_search_NlnN"), synthetic(rows))
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["value"], 1.105, places=2)
        self.assertAlmostEqual(r["related"]["k_runtime"]["value"], 1.3, places=6)
        self.assertLess(r["related"]["k_runtime_per_interaction"]["value"], 0.3)
        quadratic = [(p, {**c, "candidates_per_particle": c["candidates_per_particle"] * p["particles"]})
                     for p, c in rows]
        self.assertEqual(C.evaluate(self.claim("neighbour_search_NlnN"), synthetic(quadratic))["verdict"],
                         "not reproduced")

    def test_gain_grows_with_loops(self):
        """vlx_gain_grows_with_loops: the fitted change of VL_X's improvement
        from k = 0 to 3 extra loops; growing gains are reproduced, shrinking
        ones are not, and a run without the axis is not measured."""
        def loops_data(cll_per_loop):
            rows = []
            for k in range(4):
                t_cll, t_vlx = 1.0 + cll_per_loop * k, 0.95 + 0.2 * k  # VL_X: 5 % faster at k = 0
                for lst, t in (("cll", t_cll), ("vlx", t_vlx)):
                    rows.append(({"particles": 31239, "gridder": "B", "reorder": 1, "list": lst, "list_steps": 7,
                                  "extra_loops": k}, {"s_per_step": t}))
            return synthetic(rows)
        c = self.claim("vlx_gain_grows_with_loops")
        r = C.evaluate(c, loops_data(cll_per_loop=0.3))  # CLL's extra loop costs more: the gain grows
        self.assertEqual(r["verdict"], "reproduced", r)
        gains = [100 * (1 + 0.3 * k - (0.95 + 0.2 * k)) / (1 + 0.3 * k) for k in range(4)]
        self.assertAlmostEqual(r["related"]["gain_k3"]["value"], gains[3], places=6)
        self.assertGreater(r["value"], 5)
        r = C.evaluate(c, loops_data(cll_per_loop=0.15))  # CLL's extra loop costs less: the gain shrinks
        self.assertEqual(r["verdict"], "not reproduced", r)
        no_axis = synthetic([({"particles": 31239, "gridder": "B", "reorder": 1, "list": lst, "list_steps": 7},
                              {"s_per_step": 1.0}) for lst in ("cll", "vlx")])
        self.assertEqual(C.evaluate(c, no_axis)["verdict"], "not measured")

    def test_peer_ratio_pairs_configurations_and_takes_their_geometric_mean(self):
        """sphnl_over_nanoflann: sphnl's entries per second over nanoflann's,
        configuration by configuration, at the largest N; 8x and 2x give 4x."""
        rows = []
        for rep in range(3):
            for impl, base in (("sphnl", 8e8), ("nanoflann", 1e8)):
                for call, factor in (("warm", 1.0), ("first", 4.0)):  # sphnl 8x warm, 2x first
                    eps = base / (factor if impl == "sphnl" and call == "first" else 1.0)
                    for n in (31000, 150000):
                        rows.append({"experiment": "peers", "family": "search", "particles": n, "gridder": "B",
                                     "cell_order": "sort_x", "reorder": 1, "threads": 1, "impl": impl,
                                     "cloud": "lattice", "memory_order": "generated", "call": call,
                                     "repetition_index": rep, "round": rep, "error_occurred": False,
                                     "error_message": "", "run_name": f"search/{impl}/{call}/{n}",
                                     "n_particles": n, "entries_per_s": eps * (1 + 0.01 * rep)})
        r = C.evaluate(self.claim("sphnl_over_nanoflann"), pd.DataFrame(rows))
        self.assertAlmostEqual(r["value"], 4.0, places=6)
        self.assertAlmostEqual(r["related"]["smallest_ratio"]["value"], 2.0, places=6)
        self.assertAlmostEqual(r["related"]["warm_call"]["value"], 8.0, places=6)
        self.assertEqual(r["verdict"], "partly", r)
        self.assertIn("150 000", r["note"])
        self.assertNotIn("pages", r["note"])
        data = pd.DataFrame(rows)
        data["huge_pages"] = np.where(data["impl"] == "sphnl", 1.0, np.nan)  # pages: default, resolved huge
        self.assertIn("sphnl on huge pages", C.evaluate(self.claim("sphnl_over_nanoflann"), data)["note"])

    @staticmethod
    def first_call_rows(ratio, idle_state="idle_3s", noise=0.01):
        """Three rounds of synthetic peers_first_call rows at N = 150 000:
        nanoflann at 1e7 entries/s (2 s a call), sphnl at ratio[(state,
        cloud, threads)] times that."""
        rng = np.random.default_rng(3)
        rows = []
        for rnd, rep in itertools.product(range(3), range(3)):
            for (state, cloud, threads), r in ratio.items():
                state = idle_state if state == "idle" else state
                for impl, eps in (("sphnl", 1e7 * r), ("nanoflann", 1e7)):
                    eps *= 1 + noise * rng.standard_normal()
                    rows.append({"experiment": "peers_first_call", "family": "search", "particles": 150000,
                                 "gridder": "B", "cell_order": "sort_x", "reorder": 1, "threads": threads,
                                 "impl": impl, "cloud": cloud, "memory_order": "generated", "call": "first",
                                 "freed_memory": state, "repetition_index": rep, "round": rnd,
                                 "error_occurred": False, "error_message": "", "n_particles": 150000,
                                 "run_name": f"search/{impl}/{cloud}/{threads}/{state}",
                                 "entries_per_s": eps, "s_call": 2e7 / eps})
        return pd.DataFrame(rows)

    def test_first_call_peer_claims_read_the_smallest_ratio_per_memory_state(self):
        """first_call_over_nanoflann_*: the smallest sphnl / nanoflann ratio
        over the configurations of one memory state, its interval from the
        simultaneous band, the geometric mean beside it; the idle claim reads
        the longest idle_<s>s of the run."""
        ratio = {("just_freed", "lattice", 1): 6.0, ("just_freed", "lattice", 2): 9.0,
                 ("just_freed", "random", 1): 20.0, ("just_freed", "random", 2): 30.0,
                 ("idle", "lattice", 1): 2.0, ("idle", "lattice", 2): 3.5,
                 ("idle", "random", 1): 8.0, ("idle", "random", 2): 10.0}
        data = self.first_call_rows(ratio)
        r = C.evaluate(self.claim("first_call_over_nanoflann_just_freed"), data)
        self.assertAlmostEqual(r["value"], 6.0, delta=0.15)
        self.assertLessEqual(r["ci_low"], r["value"])
        self.assertLess(r["ci_high"], 9.0)  # the next smallest is far: it cannot be the minimum
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertIn("smallest of 4 configurations", r["note"])
        self.assertIn("lattice/generated/1 thr.", r["note"])
        self.assertAlmostEqual(r["related"]["geometric_mean"]["value"], (6 * 9 * 20 * 30) ** 0.25, delta=0.3)
        r = C.evaluate(self.claim("first_call_over_nanoflann_idle"), data)
        self.assertAlmostEqual(r["value"], 2.0, delta=0.05)
        self.assertEqual(r["verdict"], "not reproduced", r)
        self.assertIn("idle 3s", r["note"])
        # Two idle lengths: the longer one is read.
        longer = self.first_call_rows({("idle", "lattice", 1): 4.0, ("idle", "random", 1): 7.0},
                                      idle_state="idle_12s")
        r = C.evaluate(self.claim("first_call_over_nanoflann_idle"), pd.concat([data, longer]))
        self.assertAlmostEqual(r["value"], 4.0, delta=0.1)
        self.assertIn("idle 12s", r["note"])
        self.assertNotIn("pages", r["note"])  # rows before the huge_pages counter: nothing said
        # The pages sphnl's lists used (pages: default resolved) are named.
        data["huge_pages"] = np.where(data["impl"] == "sphnl", 0.0, np.nan)
        r = C.evaluate(self.claim("first_call_over_nanoflann_just_freed"), data)
        self.assertIn("sphnl on base pages", r["note"])
        data.loc[(data["impl"] == "sphnl") & (data["cloud"] == "random"), "huge_pages"] = 1.0
        r = C.evaluate(self.claim("first_call_over_nanoflann_just_freed"), data)
        self.assertIn("sphnl on base and huge pages", r["note"])
        # The peers experiment's first calls (no freed_memory axis) do not count.
        r = C.evaluate(self.claim("first_call_over_nanoflann_just_freed"), data.drop(columns="freed_memory"))
        self.assertEqual(r["verdict"], "not measured", r)

    def test_first_call_peer_claim_min_ties_widen_the_interval(self):
        """Two configurations equally near the smallest: both are named as
        possible smallest and the interval spans what either allows (here
        across the 5x edge: partly, not reproduced)."""
        data = self.first_call_rows({("just_freed", "lattice", 1): 5.0, ("just_freed", "random", 1): 5.05},
                                    noise=0.05)
        r = C.evaluate(self.claim("first_call_over_nanoflann_just_freed"), data)
        self.assertIn("lattice/generated/1 thr.", r["note"])
        self.assertIn("random/generated/1 thr.", r["note"])
        self.assertLess(r["ci_low"], 5.0)
        self.assertGreater(r["ci_high"], 5.0)
        self.assertEqual(r["verdict"], "partly", r)  # across the 5x edge, inside the 3x-200x band

    @staticmethod
    def search_rows(experiment, seconds):
        """Three rounds of synthetic `search` rows on the 10^6 lattice:
        seconds maps (threads, ((axis, value), ...)) to s_call; axes not
        given are impl sphnl, call warm."""
        rows = []
        for rep in range(3):
            for (threads, axes), t in seconds.items():
                row = {"experiment": experiment, "family": "search", "particles": 1000000, "gridder": "B",
                       "cell_order": "sort_x", "reorder": 1, "threads": threads, "impl": "sphnl",
                       "cloud": "lattice", "memory_order": "generated", "call": "warm",
                       "repetition_index": rep, "round": rep, "error_occurred": False, "error_message": "",
                       "n_particles": 1000000, "s_call": t * (1 + 0.001 * rep)}
                row.update(dict(axes))
                row["run_name"] = "search/" + "/".join(str(v) for _, v in axes) + f"/{threads}"
                rows.append(row)
        return pd.DataFrame(rows)

    def test_api_and_search_thread_claims(self):
        """search_api's claims: the API's seconds per call over the engine's
        (one thread), and the engine's speed-up from one thread to two, read
        from s_call at N = 1 000 000."""
        seconds = {("sphnl", 1): 0.20, ("sphnl", 2): 0.11, ("api_visit", 1): 0.204, ("api_visit", 2): 0.114,
                   ("api", 1): 0.60, ("api", 2): 0.34}
        data = self.search_rows("search_api", {(threads, (("impl", impl),)): t
                                               for (impl, threads), t in seconds.items()})
        r = C.evaluate(self.claim("api_visit_over_engine"), data)
        self.assertAlmostEqual(r["value"], 1.02, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        r = C.evaluate(self.claim("api_rows_over_engine"), data)
        self.assertAlmostEqual(r["value"], 3.0, places=6)
        self.assertEqual(r["verdict"], "not reproduced", r)
        self.assertAlmostEqual(r["related"]["two_threads"]["value"], 0.34 / 0.11, places=6)
        r = C.evaluate(self.claim("search_two_threads_over_one"), data)
        self.assertAlmostEqual(r["value"], 0.20 / 0.11, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["related"]["api"]["value"], 0.60 / 0.34, places=6)
        r = C.evaluate(self.claim("search_two_threads_over_one"), data[data["threads"] == 1])
        self.assertEqual(r["verdict"], "not measured", r)

    def test_first_call_claims(self):
        """first_call's claims: a first call's seconds with base pages over
        huge pages, and a first call over a warm one with huge pages, one
        thread (two threads related), read from s_call at N = 1 000 000."""
        seconds = {("first", "base", 1): 1.30, ("first", "huge", 1): 0.26, ("warm", "huge", 1): 0.20,
                   ("warm", "base", 1): 0.20, ("first", "base", 2): 0.80, ("first", "huge", 2): 0.16,
                   ("warm", "huge", 2): 0.11, ("warm", "base", 2): 0.11}
        data = self.search_rows("first_call", {(threads, (("call", call), ("pages", pages))): t
                                               for (call, pages, threads), t in seconds.items()})
        r = C.evaluate(self.claim("first_call_huge_over_base"), data)
        self.assertAlmostEqual(r["value"], 5.0, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["related"]["two_threads"]["value"], 5.0, places=6)
        self.assertAlmostEqual(r["related"]["warm_one_thread"]["value"], 1.0, places=6)
        r = C.evaluate(self.claim("first_over_warm_huge"), data)
        self.assertAlmostEqual(r["value"], 1.3, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["related"]["two_threads"]["value"], 0.16 / 0.11, places=6)
        # Results without the pages axis (every search run before it): not measured.
        r = C.evaluate(self.claim("first_over_warm_huge"), data.drop(columns="pages"))
        self.assertEqual(r["verdict"], "not measured", r)

    def test_step_thread_claims(self):
        """beyond_scaling's claims: one thread over two with the split by
        interactions and phased updates; fluid over interactions on two."""
        two = {("fluid", "private"): 0.070, ("fluid", "phased"): 0.068,
               ("interactions", "private"): 0.060, ("interactions", "phased"): 0.055}
        rows = []
        for (split, updates), t2 in two.items():
            base = {"particles": 118853, "gridder": "B", "reorder": 1, "lattice": "cubic", "h_coefficient": 1.0,
                    "thread_split": split, "thread_updates": updates}
            rows.append(({**base, "threads": 1}, {"s_per_step": 0.1, "s_force": 0.08}))
            rows.append(({**base, "threads": 2}, {"s_per_step": t2, "s_force": 0.04}))
        data = synthetic(rows)
        r = C.evaluate(self.claim("step_two_threads_over_one"), data)
        self.assertAlmostEqual(r["value"], 0.1 / 0.055, places=6)
        self.assertEqual(r["verdict"], "partly", r)
        self.assertAlmostEqual(r["related"]["fluid_private"]["value"], 0.1 / 0.070, places=6)
        self.assertAlmostEqual(r["related"]["force_phase"]["value"], 2.0, places=6)
        r = C.evaluate(self.claim("interactions_split_over_fluid"), data)
        self.assertAlmostEqual(r["value"], 0.068 / 0.055, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        no_axis = synthetic([({"particles": 118853, "gridder": "B", "reorder": 1, "threads": t},
                              {"s_per_step": 0.1}) for t in (1, 2)])
        self.assertEqual(C.evaluate(self.claim("step_two_threads_over_one"), no_axis)["verdict"], "not measured")

    def test_dynamic_split_claims(self):
        """beyond_dynamic's claims: one thread over two handed out dynamically;
        the split by interactions over dynamic on two threads."""
        rows = []
        for split, t2, f2 in (("interactions", 0.060, 0.050), ("dynamic", 0.054, 0.045)):
            base = {"particles": 118853, "gridder": "B", "reorder": 1, "lattice": "cubic", "h_coefficient": 1.0,
                    "thread_split": split, "thread_updates": "private"}
            rows.append(({**base, "threads": 1}, {"s_per_step": 0.1, "s_force": 0.09}))
            rows.append(({**base, "threads": 2}, {"s_per_step": t2, "s_force": f2}))
        data = synthetic(rows)
        r = C.evaluate(self.claim("step_two_threads_dynamic"), data)
        self.assertAlmostEqual(r["value"], 0.1 / 0.054, places=6)
        self.assertEqual(r["verdict"], "partly", r)
        self.assertAlmostEqual(r["related"]["force_phase"]["value"], 2.0, places=6)
        self.assertAlmostEqual(r["related"]["interactions_private"]["value"], 0.1 / 0.060, places=6)
        r = C.evaluate(self.claim("dynamic_split_over_interactions"), data)
        self.assertAlmostEqual(r["value"], 0.060 / 0.054, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["related"]["force_phase"]["value"], 0.050 / 0.045, places=6)

    def test_verlet_masked_loop_claims(self):
        """beyond_vl_loop's claims: VL_X's gather over masked loop (VL_C and
        mixed related), and VL_X masked in µs per particle-step, read from the
        Verlet-list rows only (a CLL row of the same axes must not be taken)."""
        rows = []
        for lst, gather, masked in (("vlx", 0.110, 0.090), ("vlc", 0.120, 0.125), ("cll", 0.5, 0.5)):
            for precision in ("double", "mixed"):
                base = {"particles": 118853, "gridder": "B", "reorder": 1, "lattice": "cubic", "h_coefficient": 1.0,
                        "list": lst, "list_steps": 7, "precision": precision}
                rows.append(({**base, "pair_loop": "gather"}, {"s_per_step": gather, "s_force": gather / 2}))
                rows.append(({**base, "pair_loop": "masked"},
                             {"s_per_step": masked, "s_force": masked / 4, "kernel_lanes_per_pair": 1.1}))
        data = synthetic(rows)
        r = C.evaluate(self.claim("vl_masked_over_gather"), data)
        self.assertAlmostEqual(r["value"], 0.110 / 0.090, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["related"]["VL_C"]["value"], 0.120 / 0.125, places=6)
        self.assertAlmostEqual(r["related"]["force_phase"]["value"], 2 * 0.110 / 0.090, places=6)
        self.assertAlmostEqual(r["related"]["kernel_lanes_per_pair"]["value"], 1.1, places=6)
        r = C.evaluate(self.claim("step_us_vlx_masked"), data)
        self.assertAlmostEqual(r["value"], 1e6 * 0.090 / 118853, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertIn("VL_X", r["note"])
        no_axis = synthetic([({"particles": 118853, "list": "vlx", "list_steps": 7, "gridder": "B", "reorder": 1},
                              {"s_per_step": 0.1})])
        self.assertEqual(C.evaluate(self.claim("vl_masked_over_gather"), no_axis)["verdict"], "not measured")

    def test_inner_order_claims(self):
        """beyond_inner_order's claims: index over morton with the masked loop
        in double (mixed, gather and both orders' lanes per pair related),
        and the masked loop in morton order in µs per particle-step, read from
        the morton rows only (the index rows of the same axes must not be taken)."""
        rows = []
        for order, masked, gather, lanes in (("index", 0.100, 0.140, 2.24), ("morton", 0.080, 0.138, 1.6)):
            for precision, scale in (("double", 1.0), ("mixed", 0.7)):
                base = {"particles": 118853, "gridder": "B", "reorder": 1, "lattice": "cubic", "h_coefficient": 1.0,
                        "list": "cll", "precision": precision, "inner_order": order}
                rows.append(({**base, "pair_loop": "gather"}, {"s_per_step": gather * scale, "s_force": gather / 2}))
                rows.append(({**base, "pair_loop": "masked"},
                             {"s_per_step": masked * scale, "s_force": masked / 2, "kernel_lanes_per_pair": lanes}))
        data = synthetic(rows)
        r = C.evaluate(self.claim("index_over_morton_masked"), data)
        self.assertAlmostEqual(r["value"], 0.100 / 0.080, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["related"]["mixed"]["value"], 0.100 / 0.080, places=6)
        self.assertAlmostEqual(r["related"]["gather"]["value"], 0.140 / 0.138, places=6)
        self.assertAlmostEqual(r["related"]["kernel_lanes_per_pair_index"]["value"], 2.24, places=6)
        self.assertAlmostEqual(r["related"]["kernel_lanes_per_pair_morton"]["value"], 1.6, places=6)
        r = C.evaluate(self.claim("step_us_mixed_masked_morton"), data)
        self.assertAlmostEqual(r["value"], 1e6 * 0.080 * 0.7 / 118853, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        r = C.evaluate(self.claim("step_us_double_masked_morton"), data)
        self.assertAlmostEqual(r["value"], 1e6 * 0.080 / 118853, places=6)
        self.assertEqual(r["verdict"], "reproduced", r)
        no_axis = synthetic([({"particles": 118853, "list": "cll", "gridder": "B", "reorder": 1, "pair_loop": "masked"},
                              {"s_per_step": 0.1})])
        self.assertEqual(C.evaluate(self.claim("index_over_morton_masked"), no_axis)["verdict"], "not measured")

    def test_regression_flips_a_claim_end_to_end(self):
        """fake_bench --fake-regress: slowing VL_X turns its gain into a loss."""
        with tempfile.TemporaryDirectory() as tmp:
            good, _ = fake_run(tmp, "default", "--only", "fig16")
            bad, _ = fake_run(pathlib.Path(tmp) / "bad", "default", "--only", "fig16",
                              env={"FAKE_BENCH_REGRESS": "list:vlx=1.2"})
            c = self.claim("vlx_gain_ns7_150k")
            self.assertNotEqual(C.evaluate(c, R.load_run(good))["verdict"], "not reproduced")
            r = C.evaluate(c, R.load_run(bad))
            self.assertEqual(r["verdict"], "not reproduced")
            self.assertLess(r["ci_high"], 0)


if __name__ == "__main__":
    unittest.main()
