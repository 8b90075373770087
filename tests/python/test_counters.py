"""The counters kind (harness/valgrind.py, experiments/counters.py) and the
explanations of the claims that differ (plots/explanations.py).

The valgrind run is skipped, with the reason, when valgrind is missing or no
bench valgrind can execute is at hand (SPHNL_BUILD_DIR's when this CPU has
no AVX-512, else build-counters/ from `make counters-build`)."""
import json
import os
import pathlib
import shutil
import tempfile
import types
import unittest

from experiments import counters as CNT
from harness import results as R
from harness import valgrind as V
from plots import explanations as X

REPO = pathlib.Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data"
STORED = DATA / "callgrind_window.out"  # callgrind --cache-sim=yes, the measured window (dump 2)


def counters_bench():
    """(bench valgrind can run, or None, and why not)."""
    if shutil.which("valgrind") is None:
        return None, "valgrind is not installed (apt-get install valgrind, or make deps)"
    flags = pathlib.Path("/proc/cpuinfo").read_text(errors="replace") if pathlib.Path("/proc/cpuinfo").exists() else ""
    build = os.environ.get("SPHNL_BUILD_DIR")
    if build and "avx512f" not in flags:  # -march=native emitted no AVX-512: valgrind 3.19 runs it
        bench = pathlib.Path(build) / "benchmarks" / "sphnl_bench"
        if bench.is_file():
            return bench, ""
    bench = REPO / V.COUNTERS_BUILD / "benchmarks" / "sphnl_bench"
    if bench.is_file():
        return bench, ""
    return None, ("no bench valgrind 3.19 can execute: this CPU has AVX-512 (or SPHNL_BUILD_DIR is unset) "
                  "and build-counters/ is missing; run `make counters-build`")


class CallgrindParsing(unittest.TestCase):
    def test_inclusive_cost_is_own_lines_plus_calls(self):
        text = "\n".join([
            "version: 1", "positions: line", "events: Ir D1mr DLmr",
            "fl=(1) a.cpp", "fn=(1) main", "5 10 1", "cfn=(2) child()", "calls=2 7", "6 100 4 2",
            "fn=(2)", "7 60 3 1", "+1 40 1", "cfn=(3) leaf", "calls=1 9", "* 5",
            "fn=(3)", "9 5",
            "totals: 115 5 2"])
        p = V.parse_callgrind(text)
        self.assertEqual(p.events, ["Ir", "D1mr", "DLmr"])
        self.assertEqual(p.totals, [115, 5, 2])
        self.assertEqual(p.inclusive["main"], [110, 5, 2])
        self.assertEqual(p.inclusive["child()"], [105, 4, 1])   # own 100 + the call to leaf
        self.assertEqual(p.inclusive["leaf"], [5, 0, 0])         # missing trailing counts are 0
        self.assertEqual(p.of(["child()", "leaf"], "Ir"), 110)
        self.assertEqual(p.of(["never called"], "D1mr"), 0)

    def test_errors_name_the_problem(self):
        with self.assertRaisesRegex(V.ValgrindError, "cost line before the 'events:' line"):
            V.parse_callgrind("fn=main\n3 4\n")
        with self.assertRaisesRegex(V.ValgrindError, "no 'events:' line"):
            V.parse_callgrind("totals: 4\n")
        with self.assertRaisesRegex(V.ValgrindError, "no 'totals:'"):
            V.parse_callgrind("events: Ir\nfn=main\n3 4\n")
        with self.assertRaisesRegex(V.ValgrindError, "no D1mr event.*--cache-sim=yes"):
            V.parse_callgrind("events: Ir\ntotals: 4\n").total("D1mr")

    def test_stored_window_has_every_phase(self):
        """A real dump of one measured window (tiny dam break, CLL, 2010 caches):
        the three phases hold the window's work and the fields are per particle-step."""
        p = V.parse_callgrind(STORED.read_text(), str(STORED))
        self.assertEqual(p.events, ["Ir", "Dr", "Dw", "I1mr", "D1mr", "D1mw", "ILmr", "DLmr", "DLmw"])
        for functions in V.PHASE_FUNCTIONS.values():
            self.assertTrue(all(f in p.inclusive for f in functions), functions)
            self.assertGreater(p.of(functions, "Ir"), 0)
        fields = CNT.counter_fields(p, particle_steps=1000.0)
        self.assertEqual(fields["ir_total"], p.total("Ir"))
        self.assertEqual(fields["ll_misses_total"], p.total("DLmr") + p.total("DLmw"))
        self.assertAlmostEqual(fields["d1_misses_per_particle_step"], (p.total("D1mr") + p.total("D1mw")) / 1000.0)
        self.assertGreater(fields["ir_phase_coverage"], 0.95)
        self.assertLessEqual(fields["ir_phase_coverage"], 1.0)
        for metric in ("ir", "d1_misses", "ll_misses"):
            phases = sum(fields[f"{metric}_{ph}_per_particle_step"] for ph in V.PHASE_FUNCTIONS)
            self.assertLessEqual(phases, fields[f"{metric}_per_particle_step"] * (1 + 1e-12), metric)
        # per pair the builds stored: the list phase's counts over that work; none without a list
        per_pair = CNT.per_pair_built(fields, 4.0)
        self.assertEqual(sorted(per_pair), ["d1_misses_neighbour_list_per_pair_built",
                                            "ir_neighbour_list_per_pair_built", "ll_misses_neighbour_list_per_pair_built"])
        self.assertAlmostEqual(per_pair["ir_neighbour_list_per_pair_built"],
                               fields["ir_neighbour_list_per_particle_step"] / 4.0)
        self.assertEqual(CNT.per_pair_built(fields, 0.0), {})
        self.assertEqual(CNT.per_pair_built(fields, None), {})
        self.assertGreater(fields["ir_force_per_particle_step"], fields["ir_update_per_particle_step"])


class CpuSlots(unittest.TestCase):
    def test_concurrent_jobs_run_on_different_cpus(self):
        """Two valgrind jobs at once each get a CPU of their own (taskset -c),
        taken from the allowed CPUs and given back when the job ends."""
        import threading
        allowed = sorted(os.sched_getaffinity(0))
        if len(allowed) < 2 or not shutil.which("taskset"):
            self.skipTest("needs two allowed CPUs and taskset")
        seen, both_started = [], threading.Barrier(2, timeout=10)

        def fake(name, model, *, prefix, **_):
            seen.append(prefix)
            both_started.wait()  # the two jobs hold their CPUs at the same time
            return name, {}
        saved, CNT._count_one = CNT._count_one, fake
        try:
            cpus = CNT.cpu_slots()
            common = dict(valgrind="v", size="tiny", work=pathlib.Path("."), env={}, prefix=["setarch", "-R"], cpus=cpus)
            threads = [threading.Thread(target=CNT.count_one, args=(n, None), kwargs=common) for n in ("a", "b")]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
        finally:
            CNT._count_one = saved
        self.assertEqual(len(seen), 2)
        self.assertTrue(all(pre[0].endswith("taskset") and pre[1] == "-c" and pre[3:] == ["setarch", "-R"] for pre in seen))
        self.assertEqual(sorted(int(pre[2]) for pre in seen), allowed[:2])
        self.assertEqual(cpus.qsize(), len(allowed))  # every CPU given back


class KeptCounts(unittest.TestCase):
    def test_a_run_that_stops_keeps_its_counts_for_the_next(self):
        """Three configurations; the first run counts two and fails on the
        third: the next run of the same bench counts only the third and
        records the two it kept; another bench binary counts all three."""
        calls, fail_on = [], {"n": 3000}

        def fake_count(name, model, **_):
            calls.append(name)
            if f"particles:{fail_on['n']}/" in name:
                raise CNT.CountersError("stopped")
            n = int(name.split("particles:")[1].split("/")[0])
            e = {"name": name, "run_name": name, "run_type": "iteration", "repetitions": 1, "repetition_index": 0,
                 "iterations": 1, "real_time": 1.0, "time_unit": "s", "sphnl_round": 0, "n_particles": n,
                 "window_steps": 1, "ir_per_particle_step": float(n)}
            return e, {"host_name": "x"}
        with tempfile.TemporaryDirectory() as tmp:
            tmp = pathlib.Path(tmp)
            exp = tiny_experiment(tmp / "repo")
            for s in R.SIZES:
                exp["sweep"][s]["particles"] = [1500, 2000, 3000]
            bench = tmp / "bench"
            bench.write_text("#!/bin/sh\n")
            bench.chmod(0o755)
            args = types.SimpleNamespace(size="tiny", valgrind=shutil.which("true") and "true", counters_bench=bench,
                                         counters_jobs=1, cache_dir=tmp / "cache", repo=tmp / "repo",
                                         step_seconds=lambda p: 1e-3, part={"git_revision": "0123456789ab"})
            out = tmp / "run" / "counters_test.json"
            out.parent.mkdir()
            saved = CNT.count_one, CNT._run
            CNT.count_one, CNT._run = fake_count, lambda *a, **k: None
            try:
                with self.assertRaisesRegex(CNT.CountersError, "stopped"):
                    CNT.run(args, exp, out, "[t]", {}, progress=lambda m: None)
                self.assertFalse(out.exists())
                work = out.with_name(".counters_test.counters")
                self.assertEqual(len(list(work.glob("*" + CNT.DONE_SUFFIX))), 2)
                calls.clear()
                fail_on["n"] = -1
                CNT.run(args, exp, out, "[t]", {}, progress=lambda m: None)
                self.assertEqual([c.split("particles:")[1].split("/")[0] for c in calls], ["3000"])
                doc = json.loads(out.read_text())
                self.assertEqual([b["n_particles"] for b in doc["benchmarks"]], [1500, 2000, 3000])
                self.assertEqual(len(doc["sphnl_rounds"][0]["kept_from_earlier_run"]), 2)
                self.assertFalse(work.exists())  # a finished run leaves no work folder
                # kept counts of another bench binary are not reused
                fail_on["n"] = 3000
                with self.assertRaises(CNT.CountersError):
                    CNT.run(args, exp, out, "[t]", {}, progress=lambda m: None)
                bench.write_text("#!/bin/sh\n# rebuilt\n")
                calls.clear()
                fail_on["n"] = -1
                CNT.run(args, exp, out, "[t]", {}, progress=lambda m: None)
                self.assertEqual(len(calls), 3)
            finally:
                CNT.count_one, CNT._run = saved


class CacheModels(unittest.TestCase):
    def fake_sysfs(self, root, levels):
        for k, (level, kind, size, ways) in enumerate(levels):
            d = root / f"index{k}"
            d.mkdir(parents=True)
            for name, value in (("level", level), ("type", kind), ("size", size),
                                ("ways_of_associativity", ways), ("coherency_line_size", 64)):
                (d / name).write_text(f"{value}\n")

    def test_this_machine_reads_l1_and_the_last_level(self):
        with tempfile.TemporaryDirectory() as tmp:
            root = pathlib.Path(tmp)
            self.fake_sysfs(root, [(1, "Data", "48K", 12), (1, "Instruction", "32K", 8),
                                   (2, "Unified", "1280K", 10), (3, "Unified", "36864K", 12)])
            m = V.this_machine(root)
        self.assertEqual(m.d1, V.Cache(48 * 1024, 12, 64))     # 64 sets: kept
        self.assertEqual(m.i1, V.Cache(32 * 1024, 8, 64))
        self.assertEqual(m.ll, V.Cache(24 * 1024 * 1024, 12, 64))  # 49 152 sets cut to 32 768
        self.assertIn("simulated as 24576 KiB", m.note)

    def test_the_2010_model_is_the_stated_assumption(self):
        self.assertEqual(V.NEHALEM_2010.options(), ["--I1=32768,8,64", "--D1=32768,8,64", "--LL=8388608,16,64"])
        self.assertIn("the paper names no hardware", V.NEHALEM_2010.note)
        with self.assertRaisesRegex(V.ValgrindError, "unknown cache_model 'epyc'"):
            V.cache_model("epyc")


def tiny_experiment(repo):
    """A one-configuration counters experiment in a scratch repository folder."""
    exp = {"id": "counters_test", "figure": None, "title": "test", "benchmark": "counters",
           "sweep": {s: {"particles": [1500], "gridder": ["B"], "cell_order": ["sort_x"], "reorder": [1], "list": ["cll"],
                         "list_steps": [1], "kgc": [0], "threads": [1], "cache_model": ["nehalem_2010"]}
                     for s in R.SIZES},
           "window_steps": {s: 1 for s in R.SIZES}, "uses": None, "claims": []}
    (repo / "experiments").mkdir(parents=True)
    (repo / "experiments" / "counters_test.json").write_text(json.dumps(exp))
    return exp


@unittest.skipIf(counters_bench()[0] is None, counters_bench()[1])
class CountsRepeat(unittest.TestCase):
    def test_two_runs_give_the_same_counts(self):
        """One tiny window under callgrind, twice, in two run folders of
        different name lengths, from environments of different sizes, and
        the second pinned to a CPU as concurrent jobs are (taskset -c, where
        two CPUs and taskset exist): the instructions the same to the last,
        the simulated misses to 1e-4 (see the comment below)."""
        bench, _ = counters_bench()
        with tempfile.TemporaryDirectory() as tmp:
            tmp = pathlib.Path(tmp)
            exp = tiny_experiment(tmp / "repo")
            args = types.SimpleNamespace(size="tiny", valgrind="valgrind", counters_bench=bench, counters_jobs=1,
                                         cache_dir=tmp / "cache", repo=tmp / "repo",
                                         step_seconds=lambda p: 1e-3, part={"git_revision": "0123456789ab"})
            docs = []
            # a 40-byte variable moved the stack of the bench and its D1
            # misses by 0.25 % before valgrind_env fixed the environment
            # the pinned run (jobs 2: taskset) once found another snapshot,
            # keyed by the CPUs it was allowed, and counted another flow
            for run_dir, padding, jobs in ((tmp / "a", {}, 1),
                                           (tmp / "a-longer-name", {"SPHNL_TEST_PADDING": "x" * 40}, 2)):
                run_dir.mkdir()
                args.counters_jobs = jobs
                CNT.run(args, exp, run_dir / "counters_test.json", "[test]", {**os.environ, **padding},
                        progress=lambda msg: None)
                docs.append(json.loads((run_dir / "counters_test.json").read_text()))
                self.assertFalse(list(run_dir.glob(".*")), "the work folder was left behind")
        a, b = (d["benchmarks"] for d in docs)
        self.assertEqual(len(a), 1)
        name = "counters/particles:1500/gridder:B/cell_order:sort_x/reorder:1/list:cll/list_steps:1/kgc:0/threads:1/cache_model:nehalem_2010"
        self.assertEqual(a[0]["name"], name)
        counts = [k for k in a[0] if k.endswith(("_per_particle_step", "_total"))]
        self.assertGreater(len(counts), 10)
        for k in counts:
            if k.startswith("ir"):
                self.assertEqual(a[0][k], b[0][k], k)
            else:
                # equal to the last in every run seen since valgrind_env; 1e-4
                # leaves room for a placement effect not yet found, far below
                # the 2.5e-3 the environment's size used to make
                self.assertAlmostEqual(a[0][k], b[0][k], delta=1e-4 * max(abs(a[0][k]), 1.0), msg=k)
        # D1 misses there must be; LL misses may be 0 (a tiny case fits the
        # simulated 8 MiB after the warm-up window)
        self.assertGreater(a[0]["d1_misses_total"], 0)
        self.assertGreaterEqual(a[0]["ll_misses_total"], 0)
        self.assertGreater(a[0]["ir_phase_coverage"], 0.95)
        self.assertEqual(a[0]["ll_bytes"], 8 * 1024 * 1024)
        self.assertEqual(docs[0]["sphnl_protocol"]["rounds"], 1)
        self.assertEqual(docs[0]["sphnl_rounds"][0]["git_revision"], "0123456789ab")  # the part's, not HEAD's
        rows = R.entry_rows(docs[0], "counters_test")  # the results loader reads it
        self.assertEqual(rows[0]["cache_model"], "nehalem_2010")


def counters_doc(values):
    """Results JSON of a counters experiment: {(list, n, cache_model): ll misses}."""
    entries = []
    for (lst, n, model), ll in values.items():
        name = R.format_run_name("counters", {"particles": n, "gridder": "B", "cell_order": "sort_x", "reorder": 1, "list": lst,
                                              "list_steps": 1, "kgc": 0, "threads": 1, "cache_model": model})
        entries.append({"name": name, "run_name": name, "run_type": "iteration", "repetitions": 1,
                        "repetition_index": 0, "iterations": 1, "real_time": 1.0, "time_unit": "s",
                        "sphnl_round": 0, "n_particles": n, "window_steps": 3, "ll_misses_per_particle_step": ll})
    return {"context": {}, "benchmarks": entries}


SPEC = {"metric": "ll_misses_per_particle_step", "where": {"particles": "max"}, "op": "ratio", "of": [
    {"op": "ratio", "of": [{"select": {"list": "vlc"}}, {"select": {"list": "cll"}}], "where": {"cache_model": "nehalem_2010"}},
    {"op": "ratio", "of": [{"select": {"list": "vlc"}}, {"select": {"list": "cll"}}], "where": {"cache_model": "this_machine"}}]}


def loaded_entry(measure=SPEC, band=(1.5, 1e6), experiment="counters_x"):
    """An entry as plots/explanations.load gives it (with its experiment)."""
    return {"id": "h", "explains": ["vl_ns1_slower_13pct"], "hypothesis": "h", "measure": measure, "unit": "x",
            "supported_if": list(band), "band_reason": "r", "experiment": experiment, "pending_axes": []}


def rows_of(doc, experiment="counters_x"):
    import pandas as pd
    return pd.DataFrame(R.entry_rows(doc, experiment))


class ExplanationSpecs(unittest.TestCase):
    def test_counts_give_a_zero_width_interval_and_the_verdict(self):
        values = {("cll", 4000, "nehalem_2010"): 1.0, ("vlc", 4000, "nehalem_2010"): 9.0,
                  ("cll", 16000, "nehalem_2010"): 2.0, ("vlc", 16000, "nehalem_2010"): 8.0,
                  ("cll", 16000, "this_machine"): 1.0, ("vlc", 16000, "this_machine"): 2.0}
        rows = rows_of(counters_doc(values))
        r = X.measure(loaded_entry(), rows, resamples=50)
        self.assertAlmostEqual(r["value"], (8.0 / 2.0) / (2.0 / 1.0))  # at the largest N only
        self.assertEqual((r["ci_low"], r["ci_high"]), (r["value"], r["value"]))
        self.assertEqual(r["verdict"], "supported")
        self.assertEqual(X.measure(loaded_entry(band=(3, 10)), rows, resamples=50)["verdict"], "refuted")
        self.assertEqual(X.measure(loaded_entry(), rows.iloc[:0], resamples=50)["verdict"], "not measured")
        pending = dict(loaded_entry(), pending_axes=["initial_order"])
        self.assertEqual(X.measure(pending, rows, resamples=50)["verdict"], "pending")

    def test_an_interval_across_the_band_edge_is_unresolved(self):
        """Timed rows of three rounds: the improvement's interval straddles 5 %."""
        entries = []
        for rnd, (t_ref, t) in enumerate([(1.00, 0.90), (1.00, 1.00), (1.00, 0.97)]):
            for lst, value in (("cll", t_ref), ("vlx", t)):
                name = R.format_run_name("step", {"particles": 8000, "gridder": "B", "cell_order": "sort_x", "reorder": 1,
                                                  "list": lst, "list_steps": 7, "kgc": 0, "threads": 1})
                entries.append({"name": name, "run_name": name, "run_type": "iteration", "repetition_index": 0,
                                "iterations": 1, "real_time": value, "time_unit": "s", "sphnl_round": rnd,
                                "s_per_step": value, "window_steps": 1})
        spec = {"metric": "s_per_step", "op": "improvement",
                "of": [{"select": {"list": "cll"}}, {"select": {"list": "vlx"}}]}
        r = X.measure(loaded_entry(spec, band=(5, 100), experiment="s"), rows_of({"benchmarks": entries}, "s"),
                      resamples=200)
        self.assertLess(r["ci_low"], 5)
        self.assertGreater(r["ci_high"], 5)
        self.assertEqual(r["verdict"], "unresolved")

    def test_a_leaf_must_match_one_configuration(self):
        rows = rows_of(counters_doc({("cll", 4000, "this_machine"): 1.0, ("cll", 4000, "nehalem_2010"): 2.0}))
        spec = {"metric": "ll_misses_per_particle_step", "select": {"list": "cll"}}
        r = X.measure(loaded_entry(spec), rows, resamples=50)
        self.assertEqual(r["verdict"], "not measured")
        self.assertIn("2 configurations match", r["note"])

    def test_bad_entries_are_refused_with_the_fix(self):
        def entry(**kw):  # as written in a file: no experiment / pending_axes keys
            e = {k: v for k, v in loaded_entry().items() if k not in ("experiment", "pending_axes")}
            return {**e, **kw}
        with self.assertRaisesRegex(X.SpecError, "unknown key.*experiment"):
            X.validate(loaded_entry(), "f.json")
        with self.assertRaisesRegex(X.SpecError, "supported_if is .*two finite numbers"):
            X.validate(entry(supported_if=[1, None]), "f.json")
        with self.assertRaisesRegex(X.SpecError, "no metric for this leaf"):
            X.validate(entry(measure={"select": {"list": "cll"}}), "f.json")
        with self.assertRaisesRegex(X.SpecError, "unknown op 'quotient'"):
            X.validate(entry(measure={"op": "quotient", "of": [{}, {}]}), "f.json")


class CountersReport(unittest.TestCase):
    def test_figure_section_and_claims_json_from_a_counters_run(self):
        """A run folder holding only counters_lists (synthetic counts): its
        figure is drawn, the section evaluates its entries and lists the
        others as not measured, and claims.json names the explanations."""
        from plots import report
        exp = R.load_experiments(REPO / "experiments")["counters_lists"]
        entries = []
        for k, p in enumerate(R.sweep_points(exp, "default")):
            name = R.format_run_name("counters", p)
            e = {"name": name, "run_name": name, "run_type": "iteration", "repetitions": 1, "repetition_index": 0,
                 "iterations": 1, "real_time": 60.0, "time_unit": "s", "sphnl_round": 0, "n_particles": p["particles"],
                 "window_steps": 21}
            scale = (3.0 if p["list"] != "cll" else 1.0) * (2.0 if p["cache_model"] == "nehalem_2010" else 1.0)
            for metric in ("ir", "d1_misses", "ll_misses"):
                for ph, share in (("neighbour_list", 0.2), ("force", 0.7), ("update", 0.1)):
                    e[f"{metric}_{ph}_per_particle_step"] = share * scale * p["particles"] / 1000
                e[f"{metric}_per_particle_step"] = scale * p["particles"] / 1000
            entries.append(e)
        with tempfile.TemporaryDirectory() as tmp:
            run_dir = pathlib.Path(tmp)
            (run_dir / "counters_lists.json").write_text(json.dumps({"context": {}, "benchmarks": entries}))
            text, records, *_ = report.build(run_dir, REPO / "experiments", resamples=50)
            self.assertTrue((run_dir / "figures" / "counters_lists.png").stat().st_size > 1000)
        self.assertIn("## Why the results differ", text)
        why = text.split("## Why the results differ", 1)[1]
        row = next(line for line in why.splitlines() if "`vlx_vlc_same_work`" in line)
        self.assertIn("| 1x [1, 1] |", row)     # VL_X and VL_C equal in these counts: supported
        self.assertIn("| supported |", row)
        self.assertIn("| not measured |", next(line for line in why.splitlines() if "`A_ties_D_memory`" in line))
        self.assertIn("| not measured |", next(line for line in why.splitlines() if "`cll_boundary_pairs`" in line))
        rec = {r["id"]: r for r in records}
        self.assertIn("vl_outgrows_2010_ll", rec["vl_ns1_slower_13pct"]["explanation"])
        self.assertIsNone(rec["table1_cll_list"]["explanation"])

class ShippedExplanations(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.entries = X.load(REPO / "experiments")

    def test_every_entry_names_an_experiment_and_claims_that_exist(self):
        self.assertEqual(X.check_references(self.entries, REPO / "experiments"), [])
        self.assertTrue(all(e["hypothesis"].strip() and e["band_reason"].strip() for e in self.entries))

    def test_every_claim_that_differs_in_the_full_run_has_an_entry(self):
        claims = json.loads((REPO / "results" / "full" / "claims.json").read_text(encoding="utf-8"))
        differ = {c["id"] for c in claims if c["verdict"] in ("not reproduced", "partly")}
        self.assertTrue(differ)
        covered = set(X.by_claim(self.entries))
        self.assertEqual(sorted(differ - covered), [])
        for c in claims:  # the report wrote which entries explain each
            if c["id"] in differ:
                self.assertTrue(c.get("explanation"), c["id"])

    def test_counters_entries_read_the_counters_experiments(self):
        counted = {e["id"] for e in self.entries if e["experiment"].startswith("counters_")}
        self.assertTrue({"vl_outgrows_2010_ll", "reorder_ll_resident", "gather_l1_resident"} <= counted)

    def test_vl_force_entries_split_work_from_misses(self):
        """counters_vl_force's three entries on synthetic force-phase counts
        whose answers are known: VL_X saves 16 % of CLL's instructions at the
        smallest N and 9.5 % at the largest (a fall of 6.5 pp: supported), its
        D1 misses relative to CLL's do not grow (refuted), and CLL takes no
        LL miss at all at the smallest N (the difference needs no division)."""
        force = {  # (list, N): (instructions, D1 misses, LL misses) per particle-step
            ("cll", 31239): (1000.0, 40.0, 0.0), ("vlx", 31239): (840.0, 30.0, 0.1),
            ("cll", 300000): (1200.0, 50.0, 0.2), ("vlx", 300000): (1086.0, 37.5, 1.3)}
        entries = []
        for (lst, n), (ir, d1, ll) in force.items():
            name = R.format_run_name("counters", {"particles": n, "gridder": "B", "cell_order": "sort_x", "reorder": 1,
                                                  "list": lst, "list_steps": 7, "kgc": 0, "threads": 1,
                                                  "cache_model": "this_machine"})
            entries.append({"name": name, "run_name": name, "run_type": "iteration", "repetitions": 1,
                            "repetition_index": 0, "iterations": 1, "real_time": 1.0, "time_unit": "s",
                            "sphnl_round": 0, "n_particles": n, "window_steps": 7, "ir_force_per_particle_step": ir,
                            "d1_misses_force_per_particle_step": d1, "ll_misses_force_per_particle_step": ll})
        rows = rows_of({"context": {}, "benchmarks": entries}, "counters_vl_force")
        got = {e["id"]: X.measure(e, rows, resamples=20) for e in self.entries if e["experiment"] == "counters_vl_force"}
        self.assertEqual(sorted(got), ["vl_force_d1_misses_grow", "vl_force_ll_misses_grow", "vl_force_work_saving_shrinks"])
        self.assertAlmostEqual(got["vl_force_work_saving_shrinks"]["value"], 9.5 - 16.0)
        self.assertEqual(got["vl_force_work_saving_shrinks"]["verdict"], "supported")
        self.assertAlmostEqual(got["vl_force_d1_misses_grow"]["value"], (37.5 / 50.0) / (30.0 / 40.0))
        self.assertEqual(got["vl_force_d1_misses_grow"]["verdict"], "refuted")
        self.assertAlmostEqual(got["vl_force_ll_misses_grow"]["value"], (1.3 - 0.2) - (0.1 - 0.0))
        self.assertEqual(got["vl_force_ll_misses_grow"]["verdict"], "supported")


if __name__ == "__main__":
    unittest.main()
