"""Tests of tools/compare.py (`make compare`): the comparison logic on
synthetic figures, and the worktree/build/run flow end to end on a throwaway
git repository whose "sphnl_bench" and "valgrind" are small Python scripts.
Nothing here builds sphnl or runs valgrind; the whole file runs in seconds."""
import contextlib
import importlib.util
import io
import json
import os
import pathlib
import shutil
import subprocess
import tempfile
import unittest

REPO = pathlib.Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("sphnl_compare", REPO / "tools" / "compare.py")
C = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(C)

NAME_B = "step/particles:6000/gridder:B/cell_order:sort_x/reorder:1/list:cll/list_steps:7/kgc:0/threads:1"
NAME_D = "step/particles:6000/gridder:D/cell_order:sort_x/reorder:1/list:cll/list_steps:7/kgc:0/threads:1"
# The same benchmark as an older bench names it (before the run-config keys were the names).
OLD_NAME_B = "step/n:6000/gridder:B/order:sort_x/reorder:1/list:cll/ns:7/kgc:0/threads:1"
TIMES = {NAME_B: ([2.0e-3, 2.1e-3, 1.9e-3, 2.05e-3, 1.95e-3],
                  [2.0e-3, 2.2e-3, 1.9e-3, 2.0e-3, 2.1e-3]),
         NAME_D: ([1.5e-3] * 5, [1.5e-3] * 5)}


def irs(factor_b=1.0, factor_d=1.0):
    """Callgrind totals of an 8-step window, the new side scaled by factor."""
    return {NAME_B: ((80_000_000, 8), (int(80_000_000 * factor_b), 8)),
            NAME_D: ((64_000_000, 8), (int(64_000_000 * factor_d), 8))}


def gb_entry(name, s_per_step, steps=8, **extra):
    return {"name": name, "run_name": name, "run_type": "iteration", "repetitions": 1,
            "repetition_index": 0, "threads": 1, "iterations": 1,
            "real_time": s_per_step * steps * 1e3, "cpu_time": s_per_step * steps * 1e3,
            "time_unit": "ms", "window_steps": steps, "s_per_step": s_per_step, **extra}


class ParseTest(unittest.TestCase):
    def test_gb_json_iterations_only(self):
        doc = {"context": {}, "benchmarks": [
            gb_entry(NAME_B, 2e-3),
            {**gb_entry(NAME_B, 9.0), "name": NAME_B + "_mean", "run_type": "aggregate",
             "aggregate_name": "mean"}]}
        figs = C.parse_gb_json(doc)
        self.assertEqual(list(figs), [NAME_B])
        self.assertEqual(figs[NAME_B]["window_steps"], 8)
        self.assertAlmostEqual(figs[NAME_B]["s_per_step"], 2e-3)
        self.assertAlmostEqual(figs[NAME_B]["real_time_s"], 16e-3)

    def test_gb_json_errors_are_reported(self):
        bad = {"benchmarks": [{**gb_entry(NAME_B, 1e-3), "error_occurred": True,
                               "error_message": "cell overflow"}]}
        with self.assertRaisesRegex(C.CompareError, "cell overflow"):
            C.parse_gb_json(bad)
        no_counter = {"benchmarks": [{"name": NAME_B, "real_time": 1, "time_unit": "ns"}]}
        with self.assertRaisesRegex(C.CompareError, "s_per_step"):
            C.parse_gb_json(no_counter)
        with self.assertRaisesRegex(C.CompareError, "not Google Benchmark JSON"):
            C.parse_gb_json({"foo": 1})

    def test_old_names_are_keyed_in_todays_vocabulary(self):
        figs = C.parse_gb_json({"benchmarks": [gb_entry(OLD_NAME_B, 2e-3)]})
        self.assertEqual(list(figs), [NAME_B])
        self.assertEqual(figs[NAME_B]["run_name"], OLD_NAME_B)  # what that bench's filter matches

    def test_old_names_experiment_renames_only_the_sweep_axes(self):
        exp = json.loads((REPO / "experiments" / "compare.json").read_text(encoding="utf-8"))
        old = C.old_names_experiment(exp)
        for size, sweep in old["sweep"].items():
            self.assertEqual(list(sweep)[:3], ["n", "gridder", "order"], size)
            self.assertEqual(sweep["ns"], exp["sweep"][size]["list_steps"])
            self.assertNotIn("particles", sweep)
        self.assertEqual({k: v for k, v in old.items() if k != "sweep"},
                         {k: v for k, v in exp.items() if k != "sweep"})

    def test_callgrind_totals_and_summary(self):
        text = "version: 1\ncreator: callgrind-3.19.0\nevents: Ir\nfn=(1) main\n3 7\nsummary: 123456\ntotals: 123457\n"
        self.assertEqual(C.parse_callgrind_ir(text), 123457)
        self.assertEqual(C.parse_callgrind_ir("events: Ir\nsummary: 99\n"), 99)
        self.assertEqual(C.parse_callgrind_ir("events: Dr Ir Dw\ntotals: 5 42 7\n"), 42)
        with self.assertRaisesRegex(C.CompareError, "no 'totals:'"):
            C.parse_callgrind_ir("events: Ir\nfn=main\n")
        with self.assertRaisesRegex(C.CompareError, "no Ir event"):
            C.parse_callgrind_ir("events: Dr\ntotals: 5\n")

    def test_filter_matches_exactly_one_name(self):
        import re
        flt = C.gb_filter(NAME_B + "/hcoef:1.2")
        self.assertRegex(NAME_B + "/hcoef:1.2", flt)
        self.assertIsNone(re.search(flt, NAME_B + "/hcoef:1x2"))
        self.assertIsNone(re.search(flt, NAME_B + "/hcoef:1.25"))


class GateTest(unittest.TestCase):
    def test_identical_builds_pass(self):
        report = C.compare(TIMES, irs(), threshold_pct=2.0)
        self.assertEqual(report["verdict"], "pass")
        self.assertEqual(C.exit_code(report), 0)
        row = {r["name"]: r for r in report["benchmarks"]}[NAME_D]
        self.assertEqual(row["ir"]["change"], 0.0)
        self.assertEqual(row["ir"]["base_per_step"], 8_000_000)
        self.assertEqual(row["time"]["p_value"], 1.0)

    def test_five_percent_ir_regression_is_caught(self):
        report = C.compare(TIMES, irs(factor_b=1.05), threshold_pct=2.0)
        self.assertEqual(report["regressions"], [NAME_B])
        self.assertEqual(C.exit_code(report), 1)
        self.assertAlmostEqual(report["benchmarks"][0]["ir"]["change"], 0.05, places=6)

    def test_improvement_passes(self):
        report = C.compare(TIMES, irs(factor_b=0.90, factor_d=0.95), threshold_pct=2.0)
        self.assertEqual(C.exit_code(report), 0)

    def test_threshold_is_strict_and_settable(self):
        self.assertEqual(C.exit_code(C.compare(TIMES, irs(factor_d=1.02), 2.0)), 0)
        self.assertEqual(C.exit_code(C.compare(TIMES, irs(factor_d=1.021), 2.0)), 1)
        self.assertEqual(C.exit_code(C.compare(TIMES, irs(factor_d=1.05), 10.0)), 0)
        self.assertEqual(C.exit_code(C.compare(TIMES, irs(factor_d=1.001), 0.0)), 1)

    def test_wall_time_is_never_gated(self):
        slower = {NAME_B: ([1e-3] * 5, [3e-3, 3.1e-3, 2.9e-3, 3e-3, 3.2e-3])}
        report = C.compare(slower, {}, threshold_pct=2.0)
        row = report["benchmarks"][0]
        self.assertAlmostEqual(row["time"]["change"], 2.0)
        self.assertLess(row["time"]["p_value"], 0.05)
        self.assertEqual(C.exit_code(report), 0)

    def test_p_value_needs_two_samples(self):
        self.assertIsNone(C.mann_whitney_p([1.0], [2.0]))
        self.assertGreater(C.mann_whitney_p([1, 2, 3, 4, 5], [1.5, 2.5, 3.5, 4.5, 5.5]), 0.3)


class TimingIntervalTest(unittest.TestCase):
    def test_noise_is_labelled_not_significant(self):
        # a docs-only commit: -18 % from one noisy window per sample
        noisy = {NAME_B: ([2.0e-3, 2.6e-3, 1.7e-3, 2.4e-3, 1.9e-3], [1.7e-3, 2.5e-3, 1.6e-3, 2.2e-3, 1.5e-3])}
        row = C.compare(noisy, {}, 2.0)["benchmarks"][0]
        self.assertLess(row["time"]["change"], -0.1)
        self.assertFalse(row["time"]["significant"])
        lo, hi = row["time"]["change_interval_95"]
        self.assertLess(lo, 0)
        self.assertGreater(hi, 0)
        cell = C.table_rows({"benchmarks": [row]})[0][3]
        self.assertTrue(cell.startswith("-") and cell.endswith(" n.s."), cell)
        self.assertIn("[", cell)

    def test_a_clear_change_is_significant_with_its_interval(self):
        slower = {NAME_B: ([1e-3, 1.02e-3, 0.98e-3, 1.01e-3, 0.99e-3], [3e-3, 3.1e-3, 2.9e-3, 3e-3, 3.2e-3])}
        row = C.compare(slower, {}, 2.0)["benchmarks"][0]
        self.assertTrue(row["time"]["significant"])
        lo, hi = row["time"]["change_interval_95"]
        self.assertTrue(1.5 < lo <= 2.0 <= hi < 2.5, (lo, hi))
        self.assertNotIn("n.s.", C.table_rows({"benchmarks": [row]})[0][3])

    def test_interval_is_reproducible_and_needs_two_samples(self):
        a, b = [1.0, 1.1, 0.9], [1.2, 1.3, 1.1]
        self.assertEqual(C.bootstrap_change_interval(a, b), C.bootstrap_change_interval(a, b))
        self.assertIsNone(C.bootstrap_change_interval([1.0], b))


class AcceptanceTest(unittest.TestCase):
    COMMITS = [("1" * 40, "Faster lists\n\nnothing to see\n"),
               ("2" * 40, "Exact KGC\n\nperf-regression-accepted: KGC now inverts the full 3x3 matrix (+4 % Ir)\n")]

    def test_acceptance_line_is_read_from_the_commit_messages(self):
        acc = C.acceptances(self.COMMITS)
        self.assertEqual(acc, [{"sha": "2" * 40, "reason": "KGC now inverts the full 3x3 matrix (+4 % Ir)"}])
        self.assertEqual(C.acceptances(self.COMMITS[:1]), [])
        # only at the start of a line
        self.assertEqual(C.acceptances([("3" * 40, "say perf-regression-accepted: no\n")]), [])

    def test_accepted_regression_is_reported_and_passes(self):
        report = C.apply_acceptances(C.compare(TIMES, irs(factor_b=1.05), 2.0), C.acceptances(self.COMMITS))
        self.assertEqual(report["regressions"], [NAME_B])
        self.assertEqual(report["verdict"], "accepted")
        self.assertEqual(C.exit_code(report), 0)
        report.update(reps=5)
        text = C.format_text(report)
        self.assertIn(f"REGRESSION: {NAME_B}: instructions per step +5.00 %", text)
        self.assertIn("ACCEPTED by commit 222222222222: perf-regression-accepted: KGC now inverts", text)
        self.assertIn("accepted", C.format_markdown(report).splitlines()[0])

    def test_unaccepted_regression_still_fails_and_says_how_to_accept(self):
        report = C.apply_acceptances(C.compare(TIMES, irs(factor_b=1.05), 2.0), C.acceptances(self.COMMITS[:1]))
        self.assertEqual(C.exit_code(report), 1)
        report.update(reps=5)
        self.assertIn("perf-regression-accepted: <reason>", C.format_text(report))


class OutputTest(unittest.TestCase):
    def report(self):
        rep = C.compare(TIMES, irs(factor_b=1.05), 2.0,
                        reproduce={NAME_B: ["valgrind --tool=callgrind base ...",
                                            "valgrind --tool=callgrind new ..."]})
        rep.update(base={"ref": "origin/main", "sha": "a" * 40, "dirty": False},
                   new={"ref": "working tree", "sha": "b" * 40, "dirty": True}, reps=5)
        return rep

    def test_markdown_has_a_row_per_benchmark(self):
        md = C.format_markdown(self.report())
        self.assertIn("regression", md.splitlines()[0])
        rows = [line for line in md.splitlines() if line.startswith("| `step/")]
        self.assertEqual(len(rows), 2)
        self.assertIn("+5.00 %", rows[0])
        self.assertIn("**REGRESSION**", rows[0])
        self.assertIn("ok", rows[1])
        self.assertIn("valgrind --tool=callgrind new ...", md)
        self.assertIn("origin/main (aaaaaaaaaaaa)", md)

    def test_text_names_benchmark_change_and_reproduce_command(self):
        text = C.format_text(self.report())
        self.assertIn(f"REGRESSION: {NAME_B}: instructions per step +5.00 %", text)
        self.assertIn("valgrind --tool=callgrind base ...", text)
        self.assertIn("1 gated regression(s): exit 1", text)

    def test_json_and_markdown_written(self):
        with tempfile.TemporaryDirectory() as tmp:
            js, md = C.write_outputs(self.report(), pathlib.Path(tmp) / "out")
            doc = json.loads(js.read_text(encoding="utf-8"))
            self.assertEqual(doc["verdict"], "regression")
            self.assertEqual([r["name"] for r in doc["benchmarks"]], [NAME_B, NAME_D])
            self.assertEqual(doc["benchmarks"][0]["ir"]["new_per_step"], 10_500_000)
            self.assertTrue(md.read_text(encoding="utf-8").startswith("### Performance comparison"))
            self.assertEqual(sorted(p.name for p in js.parent.iterdir()),
                             ["compare.json", "compare.md"])  # no temporaries left


# ------------------------------------------------------------ end to end
FAKE_BENCH = '''#!/usr/bin/python3
# Fake sphnl_bench: the flags of docs/CONTRACTS.md section 2, one benchmark per
# particle count, whose axis and name key is AXIS ("particles"; "n" before the rename).
import json, os, re, sys
IR_PER_STEP, AXIS = {ir}, "{axis}"
args = dict(a[2:].split("=", 1) for a in sys.argv[1:] if "=" in a)
exp = json.load(open(args["experiment"]))
if "--validate" in sys.argv:
    sys.exit(0 if all(AXIS in sweep for sweep in exp["sweep"].values()) else 2)
size, steps = args["size"], exp["window_steps"][args["size"]]
names = ["step/%s:%d/gridder:B" % (AXIS, n) for n in exp["sweep"][size][AXIS]]
names = [n for n in names if re.search(args.get("benchmark_filter", ""), n)]
os.makedirs(args["cache-dir"], exist_ok=True)
entries = [dict(name=n, run_name=n, run_type="iteration", iterations=1, real_time=1.0,
                time_unit="ms", window_steps=steps, s_per_step=1e-3 / steps) for n in names]
json.dump(dict(context={{}}, benchmarks=entries), open(args["benchmark_out"], "w"))
if os.environ.get("FAKE_CG_OUT"):
    total = IR_PER_STEP * steps * len(names)
    open(os.environ["FAKE_CG_OUT"], "w").write("events: Ir\\nsummary: %d\\ntotals: %d\\n" % (total, total))
'''
FAKE_VALGRIND = '''#!/usr/bin/python3
# Fake valgrind: runs the program, which writes the callgrind file itself.
import os, sys
args = sys.argv[1:]
k = next(i for i, a in enumerate(args) if not a.startswith("--"))
opts = dict(a[2:].split("=", 1) for a in args[:k])
assert opts["tool"] == "callgrind" and opts["toggle-collect"] == "sphnl::bench::timed_window*"
os.environ["FAKE_CG_OUT"] = opts["callgrind-out-file"]
os.execv(args[k], args[k:])
'''
FAKE_CMAKELISTS = '''cmake_minimum_required(VERSION 3.20)
project(fake NONE)
file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/benchmarks)
add_custom_target(sphnl_bench ALL
  COMMAND ${CMAKE_COMMAND} -E copy ${CMAKE_SOURCE_DIR}/benchmarks/bench.py
          ${CMAKE_BINARY_DIR}/benchmarks/sphnl_bench)
'''
EXPERIMENT = {"id": "compare", "benchmark": "step",
              "sweep": {"default": {"particles": [100, 200]}}, "window_steps": {"default": 4}}


@unittest.skipUnless(shutil.which("git") and shutil.which("cmake"), "needs git and cmake")
class EndToEndTest(unittest.TestCase):
    """A throwaway repository: commit 1 is the base; the working tree is edited."""

    def setUp(self):
        self._tmp = tempfile.TemporaryDirectory()
        self.root = pathlib.Path(self._tmp.name)
        self.repo = self.root / "repo"
        (self.repo / "benchmarks").mkdir(parents=True)
        (self.repo / "CMakeLists.txt").write_text(FAKE_CMAKELISTS, encoding="utf-8")
        (self.repo / "benchmarks" / "bench_main.cpp").write_text("// the real bench lives here\n", encoding="utf-8")
        self.write_bench(1000)
        (self.repo / "experiments").mkdir()
        (self.repo / "experiments" / "compare.json").write_text(json.dumps(EXPERIMENT), encoding="utf-8")
        self.valgrind = self.root / "valgrind"
        self.valgrind.write_text(FAKE_VALGRIND, encoding="utf-8")
        self.valgrind.chmod(0o755)
        self.git("init", "-q", "-b", "main")
        self.git("add", ".")
        self.commit("base")

    def tearDown(self):
        # Worktrees live under repo/.compare and go with the temporary folder.
        self._tmp.cleanup()

    def git(self, *args):
        env = dict(os.environ, GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@t",
                   GIT_COMMITTER_NAME="t", GIT_COMMITTER_EMAIL="t@t")
        return subprocess.run(["git", "-C", str(self.repo), *args], check=True, env=env,
                              capture_output=True, text=True).stdout.strip()

    def commit(self, message):
        self.git("commit", "-q", "-a", "-m", message)
        return self.git("rev-parse", "HEAD")

    def write_bench(self, ir_per_step, axis="particles"):
        path = self.repo / "benchmarks" / "bench.py"
        path.write_text(FAKE_BENCH.format(ir=ir_per_step, axis=axis), encoding="utf-8")
        path.chmod(0o755)

    def compare(self, *extra):
        out, err = io.StringIO(), io.StringIO()
        argv = ["--repo", str(self.repo), "--valgrind", str(self.valgrind), "--reps", "2",
                "--out", str(self.root / "out"), *extra]
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = C.main(argv)
        return code, out.getvalue(), err.getvalue()

    def test_identical_then_regressed_working_tree(self):
        code, out, err = self.compare("--base", "HEAD")
        self.assertEqual(code, 0, err)
        self.assertIn("pass", out)
        report = json.loads((self.root / "out" / "compare.json").read_text(encoding="utf-8"))
        self.assertEqual(len(report["benchmarks"]), 2)
        self.assertEqual(report["benchmarks"][0]["ir"]["base_per_step"], 1000)
        self.assertFalse(report["new"]["dirty"])

        self.write_bench(1050)  # uncommitted edit: the new side sees it
        code, out, err = self.compare()  # default base: merge base with main
        self.assertEqual(code, 1, err)
        self.assertIn("REGRESSION: step/particles:100/gridder:B: instructions per step +5.00 %", out)
        self.assertIn("--toggle-collect=sphnl::bench::timed_window*", out)
        report = json.loads((self.root / "out" / "compare.json").read_text(encoding="utf-8"))
        self.assertTrue(report["new"]["dirty"])
        self.assertEqual(report["base"]["sha"], self.git("rev-parse", "HEAD"))
        # the user's tree is untouched and the base worktree is registered once
        self.assertIn("1050", (self.repo / "benchmarks" / "bench.py").read_text(encoding="utf-8"))
        self.assertEqual(self.git("worktree", "list").count("worktree-"), 1)

    def test_base_in_the_old_vocabulary(self):
        """A base built before the rename rejects today's sweep axes: it gets
        the file in the old names, and its 'step/n:100/...' matches 'step/particles:100/...'."""
        self.write_bench(1000, axis="n")
        old = self.commit("the bench of the old vocabulary")
        self.write_bench(1050)  # today's names, 5 % more instructions
        code, out, err = self.compare("--base", old)
        self.assertEqual(code, 1, err + out)
        self.assertIn("predates today's sweep-axis names", err)
        self.assertIn("REGRESSION: step/particles:100/gridder:B: instructions per step +5.00 %", out)
        report = json.loads((self.root / "out" / "compare.json").read_text(encoding="utf-8"))
        self.assertEqual([r["name"] for r in report["benchmarks"]],
                         ["step/particles:100/gridder:B", "step/particles:200/gridder:B"])
        self.assertNotIn("ran only on", err)
        base_cmd, new_cmd = report["benchmarks"][0]["reproduce"]
        self.assertIn("old-names.json", base_cmd)
        self.assertIn(r"--benchmark_filter=^step/n:100/gridder:B$", base_cmd)
        self.assertIn(r"--benchmark_filter=^step/particles:100/gridder:B$", new_cmd)

    def test_committed_regression_with_acceptance_line_passes(self):
        base = self.git("rev-parse", "HEAD")
        self.write_bench(1100)
        self.commit("Slower on purpose\n\nperf-regression-accepted: exact arithmetic for the test\n")
        code, out, err = self.compare("--base", base)
        self.assertEqual(code, 0, err + out)
        self.assertIn("ACCEPTED by commit", out)
        self.assertIn("exact arithmetic for the test", out)
        report = json.loads((self.root / "out" / "compare.json").read_text(encoding="utf-8"))
        self.assertEqual(report["verdict"], "accepted")
        self.assertEqual(len(report["regressions"]), 2)

    def test_parent_of_a_single_commit_clone(self):
        code, _, err = self.compare("--base", "HEAD~1")
        self.assertEqual(code, 2)
        self.assertIn("single-commit or shallow clone", err)

    def test_unknown_ref(self):
        code, _, err = self.compare("--base", "no-such-branch")
        self.assertEqual(code, 2)
        self.assertIn("unknown git ref 'no-such-branch'", err)

    def test_base_that_does_not_build(self):
        base = self.git("rev-parse", "HEAD")
        (self.repo / "CMakeLists.txt").write_text("this is ( not cmake\n", encoding="utf-8")
        broken = self.commit("broken")
        (self.repo / "CMakeLists.txt").write_text(FAKE_CMAKELISTS, encoding="utf-8")
        code, _, err = self.compare("--base", "HEAD")
        self.assertEqual(code, 2)
        self.assertIn(f"base HEAD ({broken[:12]}) does not build", err)
        self.assertIn("Parse error", err)  # the tail of the build log
        self.assertNotEqual(base, broken)

    def test_base_predating_the_benchmark_interface(self):
        self.git("rm", "-q", "benchmarks/bench_main.cpp")
        self.commit("no benchmarks")
        (self.repo / "benchmarks" / "bench_main.cpp").write_text("//\n", encoding="utf-8")
        code, _, err = self.compare("--base", "HEAD")
        self.assertEqual(code, 2)
        self.assertIn("predates the benchmark interface", err)

    def test_no_main_branch_for_the_default_base(self):
        self.git("branch", "-m", "main", "topic")
        code, _, err = self.compare()
        self.assertEqual(code, 2)
        self.assertIn("no 'main' or 'origin/main' branch", err)


if __name__ == "__main__":
    unittest.main()
