"""Tests of the Python reproduction harness: experiments/*.json,
experiments/run.py, harness/results.py, plots/figures.py, plots/claims.py and
plots/report.py, driven by tests/python/fake_bench.py instead of sphnl_bench.

    MPLBACKEND=Agg /usr/bin/python3 -m unittest discover -s tests/python -v
"""
import contextlib
import io
import json
import math
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import unittest

REPO = pathlib.Path(__file__).resolve().parents[2]
os.environ.setdefault("MPLBACKEND", "Agg")

# Run from the repository root (`make test`), which `python -m` puts on sys.path.
from experiments import run  # noqa: E402
from harness import results as R  # noqa: E402
from plots import claims as C  # noqa: E402
from plots import figures as F  # noqa: E402
from plots import report  # noqa: E402

FAKE = REPO / "tests" / "python" / "fake_bench.py"
CONTRACT_NAME = "step/n:31239/gridder:B/order:sort_x/reorder:1/list:cll/ns:1/kgc:0/threads:1"


def run_cli(*args, env=None):
    """experiments/run.py in a subprocess: (exit code, stdout, stderr)."""
    p = subprocess.run([sys.executable, "-m", "experiments.run", *map(str, args)], cwd=REPO,
                       capture_output=True, text=True, env={**os.environ, **(env or {})})
    return p.returncode, p.stdout, p.stderr


def fake_run(results_dir, size="tiny", *more, env=None):
    code, out, err = run_cli("--size", size, "--results-dir", results_dir, "--bench", FAKE,
                             "--run-id", "r", *more, env=env)
    if code:
        raise AssertionError(f"run.py failed ({code}):\n{out}\n{err}")
    return pathlib.Path(results_dir) / "r", out


class TempDirCase(unittest.TestCase):
    def setUp(self):
        self.tmp = pathlib.Path(tempfile.mkdtemp(prefix="sphnl-harness-"))
        self.addCleanup(shutil.rmtree, self.tmp, ignore_errors=True)


class TestNames(unittest.TestCase):
    def test_contract_name_round_trip(self):
        family, p = R.parse_run_name(CONTRACT_NAME)
        self.assertEqual(family, "step")
        self.assertEqual(p, {"n": 31239, "gridder": "B", "order": "sort_x", "reorder": 1,
                             "list": "cll", "ns": 1, "kgc": 0, "threads": 1})
        self.assertIsInstance(p["n"], int)
        shuffled = dict(reversed(list(p.items())))
        self.assertEqual(R.format_run_name("step", shuffled), CONTRACT_NAME)

    def test_optional_axes_and_gb_segments(self):
        _, p = R.parse_run_name(CONTRACT_NAME + "/lattice:cubic/hcoef:0.866025/iterations:1/real_time")
        self.assertEqual(p["lattice"], "cubic")
        self.assertAlmostEqual(p["h_coefficient"], 0.866025)
        self.assertNotIn("iterations", p)
        self.assertEqual(R.format_run_name("step", {**p}), CONTRACT_NAME + "/lattice:cubic/hcoef:0.866025")

    def test_other_families(self):
        self.assertEqual(R.format_run_name("cellindex", {"n": 60000, "order": "sort_xyz"}),
                         "cellindex/order:sort_xyz/n:60000")
        self.assertEqual(R.parse_run_name("cellindex/order:hilbert/n:1500"),
                         ("cellindex", {"order": "hilbert", "n": 1500}))

    def test_point_key_matches_numbers_of_any_spelling(self):
        axes = ["n", "h_coefficient"]
        self.assertEqual(R.point_key({"n": 1500, "h_coefficient": 1}, axes),
                         R.point_key({"n": 1500.0, "h_coefficient": 1.0}, axes))


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

    def test_issue_claims_present(self):
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
        total = {s: sum(run.estimate_seconds(e, s) for e in self.exps.values() if e.get("figure"))
                 for s in R.SIZES}
        self.assertLess(total["tiny"], 60)
        self.assertLess(total["default"], 15 * 60, "default must leave room for snapshots in 20 min")

    def test_fig14_window_holds_several_rebuilds(self):
        exp = self.exps["fig14"]
        for size in ("default", "full"):
            self.assertGreaterEqual(exp["window_steps"][size], 3 * max(exp["sweep"][size]["ns"]))


class TestRunAndLoad(TempDirCase):
    def test_tiny_run_load_and_resume(self):
        out_dir, log = fake_run(self.tmp, "tiny", "--only", "fig06,fig14")
        self.assertIn("[1/2] fig06: 4 configurations", log)
        self.assertIn("configs done 4/4", log)
        self.assertIn("ETA", log)
        self.assertEqual(sorted(p.name for p in out_dir.iterdir()),
                         ["fig06.json", "fig14.json", "machine.json"])
        machine = json.loads((out_dir / "machine.json").read_text(encoding="utf-8"))
        for key in ("cpu_model", "cores", "caches", "memory_bytes", "compiler", "git_revision",
                    "date", "size"):
            self.assertIn(key, machine)
        df = R.load_run(out_dir)
        self.assertEqual(len(df), 4 + 6)  # tiny: 1 repetition per configuration
        self.assertEqual(set(df["gridder"]), {"A", "B", "C", "D"})
        self.assertTrue(str(df["n"].dtype).startswith("int"), df["n"].dtype)
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
        doc["benchmarks"].pop()
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
        self.assertEqual({R.parse_run_name(b["run_name"])[1]["n"] for b in first}, {8000, 16000})
        self.assertEqual(json.loads((out_dir / "machine.json").read_text())["max_n"], 16000)
        _, log2 = fake_run(self.tmp, "default", "--only", "fig06", "--max-n", "16000")
        self.assertIn("fig06: complete, skipped", log2)
        # Without the cap the experiment is incomplete; only the missing N run
        # (another seed, so a rerun of a kept N would show) and are merged in.
        _, log3 = fake_run(self.tmp, "default", "--only", "fig06", env={"FAKE_BENCH_SEED": "9"})
        self.assertIn("incomplete (8 sweep points missing)", log3)
        self.assertIn("running only N = 31239, 60000", log3)
        merged = json.loads(path.read_text(encoding="utf-8"))["benchmarks"]
        kept = [b for b in merged if R.parse_run_name(b["run_name"])[1]["n"] <= 16000]
        self.assertEqual(kept, first)
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
                              env={"FAKE_BENCH_ERROR": "list:vlc"})
        df = R.load_run(out_dir)
        self.assertEqual(len(df), 8 * 3)  # aggregates (_mean, ...) are not rows
        self.assertEqual(sorted(df["repetition_index"].unique()), [0, 1, 2])
        med = R.medians(df)
        self.assertEqual(list(med["list"].unique()), ["cll"])  # error rows dropped
        self.assertTrue((med["reps"] == 3).all())
        self.assertEqual(len(R.errors(df)), 4)

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


class TestFiguresAndReport(TempDirCase):
    @classmethod
    def setUpClass(cls):
        cls.base = pathlib.Path(tempfile.mkdtemp(prefix="sphnl-tiny-"))
        cls.run_dir, _ = fake_run(cls.base, "tiny")
        cls.df = R.load_run(cls.run_dir)
        cls.exps = R.load_experiments(REPO / "experiments")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.base, ignore_errors=True)

    def draw_all(self, out):
        for fig_id, fn in F.FIGURES.items():
            src = self.exps[fig_id].get("uses") or fig_id
            sentence = fn(self.df[self.df["experiment"] == src], out)
            self.assertTrue(sentence.endswith("."), fig_id)

    def test_every_figure_png_svg_deterministic(self):
        a, b = self.tmp / "a", self.tmp / "b"
        self.draw_all(a)
        self.draw_all(b)
        for fig_id in F.FIGURES:
            for ext in ("png", "svg"):
                self.assertGreater((a / f"{fig_id}.{ext}").stat().st_size, 1000, fig_id)
                self.assertEqual((a / f"{fig_id}.{ext}").read_bytes(), (b / f"{fig_id}.{ext}").read_bytes(),
                                 f"{fig_id}.{ext} differs between two runs")
        self.assertEqual(sorted(p.name for p in a.iterdir() if p.name.startswith(".")), [])

    def test_table1(self):
        md, sentence = F.table1(self.df[self.df["experiment"] == "table1"], self.exps["table1"])
        self.assertIn("| Neighbour List | 1.7 %", md)
        self.assertIn("VL step", sentence)

    def test_missing_data_is_reported_not_raised(self):
        with self.assertRaises(F.NoData):
            F.fig08(self.df[self.df["experiment"] == "fig06"], self.tmp)  # no reordered runs

    def test_report_tiny(self):
        run_dir = self.tmp / "run"
        shutil.copytree(self.run_dir, run_dir)
        (run_dir / "fig09.json").unlink()
        with contextlib.redirect_stdout(io.StringIO()):
            self.assertEqual(report.main([str(run_dir)]), 0)
        text = (run_dir / "REPRODUCTION.md").read_text(encoding="utf-8")
        self.assertIn("| Figure | Claim | Paper | Measured | Verdict | Note |", text)
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

    def test_report_publish_rewrites_links(self):
        run_dir = self.tmp / "results" / "run"
        shutil.copytree(self.run_dir, run_dir)
        published = self.tmp / "results" / "REPRODUCTION.md"
        with contextlib.redirect_stdout(io.StringIO()):
            self.assertEqual(report.main([str(run_dir), "--publish", str(published)]), 0)
        own = (run_dir / "REPRODUCTION.md").read_text(encoding="utf-8")
        copy = published.read_text(encoding="utf-8")
        self.assertIn("](figures/fig06.png)", own)
        self.assertIn("](run/figures/fig06.png)", copy)
        self.assertNotIn("](figures/", copy)
        self.assertEqual(copy.replace("](run/", "]("), own)

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
    import pandas as pd
    out = []
    for params, ctr in rows:
        full = {"experiment": "x", "family": "step", "order": "sort_x", "list": "cll", "ns": 1,
                "kgc": 0, "threads": 1, "repetition_index": 0, "error_occurred": False,
                "error_message": "", **params}
        out.append({**full, "run_name": R.format_run_name("step", {k: v for k, v in full.items()
                                                                  if k in R.FAMILY_KEYS["step"]}),
                    "n_particles": params["n"], **ctr})
    return pd.DataFrame(out)


class TestClaims(unittest.TestCase):
    def gridder_data(self, slow_a):
        rows = []
        for n in (8000, 31239, 60000):
            for g, f in (("A", slow_a * n / 8000), ("B", 1.2), ("C", 1.25), ("D", 1.0)):
                rows.append(({"n": n, "gridder": g, "reorder": 0},
                             {"s_per_step": 1e-6 * n * f, "nl_bytes": 10 * n}))
        return synthetic(rows)

    def claim(self, claim_id):
        return next(c for e in R.load_experiments(REPO / "experiments").values()
                    for c in e["claims"] if c["id"] == claim_id)

    def test_verdict_intervals(self):
        tol = {"reproduced": [3, None], "partly": [2, None]}
        self.assertEqual(C.verdict(3.5, tol), "reproduced")
        self.assertEqual(C.verdict(2.5, tol), "partly")
        self.assertEqual(C.verdict(1.5, tol), "not reproduced")
        self.assertEqual(C.verdict(float("nan"), tol), "not measured")
        self.assertEqual(C.verdict(-13, {"reproduced": [-23, -3], "partly": [None, 0]}), "reproduced")

    def test_claim_that_holds_is_reproduced(self):
        r = C.evaluate(self.claim("A_slower_3x"), self.gridder_data(slow_a=1.0))
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertAlmostEqual(r["measured"], 7.5 / 1.25)
        self.assertIn("paper: N = 150 000", r["note"])
        self.assertEqual(C.evaluate(self.claim("A_superlinear"), self.gridder_data(1.0))["verdict"],
                         "reproduced")

    def test_claim_that_fails_is_not_reproduced(self):
        r = C.evaluate(self.claim("A_slower_3x"), self.gridder_data(slow_a=0.15))
        self.assertEqual(r["verdict"], "not reproduced", r)
        r = C.evaluate(self.claim("D_vs_A_unsorted"), self.gridder_data(slow_a=0.15))
        self.assertEqual(r["verdict"], "not reproduced", r)

    def test_not_measured(self):
        small = synthetic([({"n": 1500, "gridder": g, "reorder": 0}, {"s_per_step": 1.0, "nl_bytes": 1})
                           for g in "ABCD"])
        r = C.evaluate(self.claim("A_slower_3x"), small)
        self.assertEqual(r["verdict"], "not measured")
        self.assertIn("1 500", r["note"])
        r = C.evaluate({**self.claim("A_slower_3x"), "id": "no_such_claim"}, self.gridder_data(1))
        self.assertEqual(r["verdict"], "not measured")
        one_n = self.gridder_data(1.0)
        self.assertEqual(C.evaluate(self.claim("A_superlinear"), one_n[one_n["n"] == 60000])["verdict"],
                         "not measured")

    def test_nlnn_fit(self):
        rows = [({"n": n, "gridder": "B", "reorder": 1}, {"s_per_step": 1e-7 * n * math.log(n)})
                for n in (8000, 16000, 31239, 60000)]
        r = C.evaluate(self.claim("neighbour_search_NlnN"), synthetic(rows))
        self.assertEqual(r["verdict"], "reproduced", r)
        self.assertIn("a·N·ln N fits better", r["note"])

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
            self.assertLess(r["measured"], 0)


if __name__ == "__main__":
    unittest.main()
