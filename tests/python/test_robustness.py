"""End-to-end robustness of the built binaries (`make test` sets SPHNL_BUILD_DIR):
sphnl_bench validates its experiment file, reports a failure inside a benchmark
on stderr with a non-zero exit, and dies with its parent; `sphnl run` and
`sphnl neighbours` refuse nonsense and never leave partial or mixed output."""
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

REPO = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from harness import machine as M  # noqa: E402

BUILD = pathlib.Path(os.environ.get("SPHNL_BUILD_DIR", REPO / "build"))
BENCH = BUILD / "benchmarks" / "sphnl_bench"
SPHNL = BUILD / "sphnl"
# The snapshot cache key holds the thread count of the development run (all
# the cores the bench may use); the name without it is the older form, still read.
SNAP_1500 = f"dambreak_v1_n1500_bcc_h0.866025_t0.35_thr{os.cpu_count()}.snap"  # the machine's CPUs
SNAP_1500_LEGACY = "dambreak_v1_n1500_bcc_h0.866025_t0.35.snap"


def run(cmd, **kw):
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=300, **kw)


def pid_alive(pid):
    """True while `pid` runs (a zombie or a reused pid of another program is not it)."""
    try:
        stat = pathlib.Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z" and "sphnl_bench" in stat


@unittest.skipUnless(shutil.which("cmake"), "needs cmake")
class ConfigureTest(unittest.TestCase):
    """SPHNL_GATHER: a value other than AUTO, ON, OFF stops the configure with
    the allowed values; OFF and ON decide whether the gather tuning flag is on
    the compile line."""

    def configure(self, *options):
        with tempfile.TemporaryDirectory() as tmp:
            r = run(["cmake", "-S", REPO, "-B", tmp, "-DSPHNL_BUILD_TESTS=OFF", "-DSPHNL_BUILD_BENCHMARKS=OFF",
                     f"-DPython3_EXECUTABLE={sys.executable}", *options])
            flags = pathlib.Path(tmp, "CMakeFiles", "sphnl_core.dir", "flags.make")
            return r, flags.read_text() if flags.exists() else ""

    def test_unknown_value_names_the_allowed_ones(self):
        r, _ = self.configure("-DSPHNL_GATHER=sometimes")
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("SPHNL_GATHER=sometimes: allowed values are AUTO, ON, OFF", r.stderr)

    def test_off_and_on_decide_the_flag(self):
        r, flags = self.configure("-DSPHNL_GATHER=OFF")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("hardware gathers OFF (SPHNL_GATHER=OFF)", r.stdout)
        self.assertNotIn("-mtune-ctrl=", flags)
        r, flags = self.configure("-DSPHNL_GATHER=ON")
        if "needs GCC" in r.stderr:
            self.skipTest("not GCC: SPHNL_GATHER=ON is refused")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("hardware gathers ON (SPHNL_GATHER=ON)", r.stdout)
        self.assertIn("-mtune-ctrl=use_gather_2parts,use_gather_4parts,use_gather", flags)


@unittest.skipUnless(BENCH.exists(), f"{BENCH} not built")
class BenchTest(unittest.TestCase):
    def setUp(self):
        self.tmp = pathlib.Path(tempfile.mkdtemp(prefix="sphnl_robust_"))

    def experiment(self, mutate):
        doc = (REPO / "experiments" / "fig06.json").read_text()
        path = self.tmp / "exp.json"
        path.write_text(mutate(doc))
        return path

    def test_validate_accepts_every_shipped_experiment(self):
        for f in sorted((REPO / "experiments").glob("*.json")):
            r = run([BENCH, f"--experiment={f}", "--validate"])
            self.assertEqual(r.returncode, 0, f"{f}: {r.stderr}")

    def test_revision_names_the_code_it_was_built_from(self):
        r = run([BENCH, "--revision"])
        self.assertEqual(r.returncode, 0, r.stderr)
        rev = r.stdout.strip()
        self.assertRegex(rev, r"^([0-9a-f]{12}(-dirty)?|unknown)$")
        self.assertEqual(M.binary_revision([BENCH, "--revision"]), rev)  # what run.py reads

    def test_misspelled_axis_fails_before_any_benchmark(self):
        exp = self.experiment(lambda d: d.replace('"gridder"', '"gridderr"', 1))
        for extra in (["--validate"], ["--size=tiny", "--benchmark_min_time=0"]):
            r = run([BENCH, f"--experiment={exp}", f"--cache-dir={self.tmp / 'cache'}", *extra])
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertIn(f"{exp}:7:", r.stderr)
            self.assertIn("unknown sweep axis 'gridderr'", r.stderr)
            self.assertIn("allowed: particles, gridder, cell_order,", r.stderr)
            self.assertNotIn("step/", r.stdout)  # nothing ran

    def test_old_axis_name_says_what_it_was_renamed_to(self):
        exp = self.experiment(lambda d: d.replace('"list_steps":', '"ns":', 1))
        r = run([BENCH, f"--experiment={exp}", "--size=tiny", "--validate"])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertRegex(r.stderr, rf"{exp}:7:\d+: sweep.tiny: sweep axis 'ns' was renamed to 'list_steps'")

    def test_run_py_validates_every_experiment_before_running_any(self):
        """experiments/run.py asks the bench's schema first: a misspelt axis stops
        the whole run with the file, line and key, before any benchmark."""
        import types
        from experiments import run as run_py
        (self.tmp / "experiments").mkdir()
        doc = (REPO / "experiments" / "fig06.json").read_text().replace('"gridder"', '"gridderr"')
        (self.tmp / "experiments" / "fig06.json").write_text(doc)
        args = types.SimpleNamespace(bench=BENCH, size="tiny")
        run_py.validate_experiments(args, [{"id": "fig06"}])  # the shipped file passes
        saved, run_py.REPO = run_py.REPO, self.tmp
        try:
            with self.assertRaises(run_py.RunError) as ctx:
                run_py.validate_experiments(args, [{"id": "fig06"}])
        finally:
            run_py.REPO = saved
        self.assertIn("gridderr", str(ctx.exception))
        self.assertIn("fig06.json:", str(ctx.exception))
        self.assertIn("nothing was run", str(ctx.exception))

    def test_freed_memory_waits_untimed_and_only_for_first_calls(self):
        """freed_memory: the idle wait after freeing is not in the timed call
        (idle_1s reads far below 1 s on 27 000 points), every state runs and
        is named; on a warm call the axis is refused with the reason."""
        src = REPO / "experiments" / "ablation_freed_memory.json"
        out = self.tmp / "out.json"
        r = run([BENCH, f"--experiment={src}", "--size=tiny", "--benchmark_min_time=0", "--benchmark_repetitions=1",
                 f"--benchmark_out={out}", "--benchmark_out_format=json"])
        self.assertEqual(r.returncode, 0, r.stderr)
        rows = {b["run_name"].split("freed_memory:")[1].split("/")[0]: b
                for b in json.loads(out.read_text())["benchmarks"] if b.get("run_type") == "iteration"}
        self.assertEqual(sorted(rows), ["as_found", "idle_1s", "just_freed"])
        self.assertLess(rows["idle_1s"]["real_time"], 500.0)  # ms: the 1 s wait was paused
        self.assertTrue(all(b["entries"] == rows["as_found"]["entries"] for b in rows.values()))
        # the host's reported memory across the wait: where the kernel exposes
        # it, a count (not negative: the counter only grows) on every first call
        reported = pathlib.Path("/sys/module/page_reporting/parameters/reported_kib")
        for b in rows.values():
            if reported.exists():
                self.assertGreaterEqual(b["host_reported_kib"], 0)
            else:
                self.assertNotIn("host_reported_kib", b)
        warm = self.tmp / "warm.json"
        warm.write_text(src.read_text().replace('"call": ["first"], "pages": ["huge"], "freed_memory": ["as_found", "just_freed", "idle_1s"]',
                                                '"call": ["warm"], "pages": ["huge"], "freed_memory": ["idle_1s"]', 1))
        r = run([BENCH, f"--experiment={warm}", "--size=tiny", "--benchmark_min_time=0"])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("freed_memory: 'idle_1s' applies to first calls only (call: first)", r.stderr)

    def test_pages_default_is_the_librarys_choice_here(self):
        """pages: default (peers_first_call) gives sphnl's lists the pages the
        public API chooses on this machine: base where the kernel reports free
        memory to its host (read here as machine.json reads it), huge
        elsewhere; the huge_pages counter says which, nanoflann's rows carry none."""
        out = self.tmp / "out.json"
        r = run([BENCH, f"--experiment={REPO / 'experiments' / 'peers_first_call.json'}", "--size=tiny",
                 "--benchmark_filter=freed_memory:just_freed", "--benchmark_min_time=0",
                 "--benchmark_repetitions=1", f"--benchmark_out={out}", "--benchmark_out_format=json"])
        self.assertEqual(r.returncode, 0, r.stderr)
        rows = [b for b in json.loads(out.read_text())["benchmarks"] if b.get("run_type") == "iteration"]
        self.assertEqual(len(rows), 4)  # lattice and random, sphnl and nanoflann
        for b in rows:
            self.assertIn("/pages:default/", b["run_name"])
            if "/impl:nanoflann/" in b["run_name"]:
                self.assertNotIn("huge_pages", b)
            else:
                self.assertEqual(b["huge_pages"], 0 if M.free_memory_reported_to_host() else 1, b["run_name"])
        bad = self.tmp / "bad.json"
        bad.write_text((REPO / "experiments" / "peers_first_call.json").read_text()
                       .replace('"pages": ["default"]', '"pages": ["large"]', 1))
        r = run([BENCH, f"--experiment={bad}", "--validate"])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("large", r.stderr)
        self.assertIn("default", r.stderr)

    def test_duplicate_key_is_refused(self):
        exp = self.experiment(lambda d: d.replace('"metric": "s_per_step"', '"metric": "a", "metric": "s_per_step"'))
        r = run([BENCH, f"--experiment={exp}", "--validate"])
        self.assertEqual(r.returncode, 2)
        self.assertIn("duplicate key 'metric'", r.stderr)

    def test_unwritable_cache_is_named_before_any_work(self):
        blocker = self.tmp / "a_file"
        blocker.write_text("x")  # a directory under a regular file fails for root too
        r = run([BENCH, f"--experiment={REPO / 'experiments' / 'fig06.json'}", "--size=tiny",
                 f"--cache-dir={blocker / 'cache'}", "--benchmark_min_time=0"])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn(f"snapshot cache '{blocker / 'cache'}' is not a writable directory", r.stderr)

    def test_failure_inside_a_benchmark_exits_nonzero_with_its_cause(self):
        # The snapshot's own name is taken by a directory: it can be neither
        # read nor written, which the benchmark only finds out mid-run.
        cache = self.tmp / "cache"
        (cache / SNAP_1500 / "x").mkdir(parents=True)
        (cache / SNAP_1500_LEGACY / "x").mkdir(parents=True)
        for reps in ("1", "3"):  # 3 used to abort in ComputeStats, 1 to exit 0
            r = run([BENCH, f"--experiment={REPO / 'experiments' / 'fig06.json'}", "--size=tiny",
                     f"--cache-dir={cache}", "--benchmark_min_time=0", f"--benchmark_repetitions={reps}",
                     f"--benchmark_out={self.tmp / 'out.json'}", "--benchmark_out_format=json"])
            self.assertEqual(r.returncode, 1, r.stderr)
            self.assertIn("failed: cannot rename", r.stderr)
            self.assertIn(SNAP_1500, r.stderr)
            self.assertNotIn("ComputeStats", r.stderr)

    def test_pinned_bench_finds_the_unpinned_snapshot(self):
        # The counters runner pins concurrent valgrind jobs with taskset -c;
        # the snapshot's key (its development's thread count) must not
        # follow the pinning, or a pinned bench develops a snapshot of its
        # own (under valgrind, for hours at large N) and counts another flow.
        if len(os.sched_getaffinity(0)) < 2 or not shutil.which("taskset"):
            self.skipTest("needs two allowed CPUs and taskset")
        cache = self.tmp / "cache"
        cmd = [str(BENCH), f"--experiment={REPO / 'experiments' / 'fig06.json'}", "--size=tiny",
               f"--cache-dir={cache}", "--benchmark_min_time=0", "--benchmark_filter=gridder:B/"]
        r = run(cmd)
        self.assertEqual(r.returncode, 0, r.stderr)
        made = sorted(p.name for p in cache.iterdir())
        self.assertEqual(made, [SNAP_1500])
        pinned = run(["taskset", "-c", str(min(os.sched_getaffinity(0))), *cmd])
        self.assertEqual(pinned.returncode, 0, pinned.stderr)
        self.assertNotIn("developing", pinned.stderr)
        self.assertEqual(sorted(p.name for p in cache.iterdir()), made)

    def test_debug_library_warning_is_explained(self):
        r = run([BENCH, f"--experiment={REPO / 'experiments' / 'cellindex.json'}", "--size=tiny",
                 f"--cache-dir={self.tmp / 'cache'}", "--benchmark_min_time=0",
                 "--benchmark_filter=cell_order:sort_x/"])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("not about sphnl's timed code, which is a Release build", r.stderr)

    def test_dies_with_its_parent(self):
        # A shell starts the benchmark (long: min_time 600 s) and is killed
        # with SIGKILL, as the OOM killer would kill experiments/run.py.
        script = (f"'{BENCH}' --experiment='{REPO / 'experiments' / 'cellindex.json'}' --size=tiny "
                  f"--cache-dir='{self.tmp / 'cache'}' --benchmark_min_time=600 >/dev/null 2>&1 & "
                  "echo $!; wait")
        parent = subprocess.Popen(["/bin/sh", "-c", script], stdout=subprocess.PIPE, text=True)
        child = int(parent.stdout.readline())
        try:
            deadline = time.monotonic() + 10
            while not pid_alive(child) and time.monotonic() < deadline:
                time.sleep(0.05)
            self.assertTrue(pid_alive(child), "the benchmark did not start")
            time.sleep(0.5)
            parent.kill()
            parent.wait()
            deadline = time.monotonic() + 10
            while pid_alive(child) and time.monotonic() < deadline:
                time.sleep(0.1)
            self.assertFalse(pid_alive(child), "sphnl_bench outlived its parent")
        finally:
            parent.stdout.close()
            if pid_alive(child):
                os.kill(child, signal.SIGKILL)


@unittest.skipUnless(SPHNL.exists(), f"{SPHNL} not built")
class RunTest(unittest.TestCase):
    def setUp(self):
        self.tmp = pathlib.Path(tempfile.mkdtemp(prefix="sphnl_robust_"))

    def sphnl(self, *args, env=None):
        return run([SPHNL, *args], env=dict(os.environ, **(env or {})))

    def test_too_few_fluid_particles_names_the_key(self):
        r = self.sphnl("run", "--set", "particles=100", "--set", "steps=1", "--quiet", "--out", self.tmp / "a")
        self.assertEqual(r.returncode, 2)
        self.assertIn("the case has 2 fluid particles (particles = 100), fewer than the 200", r.stderr)
        r = self.sphnl("run", "--set", "dx=1.0", "--set", "steps=1", "--quiet", "--out", self.tmp / "b")
        self.assertEqual(r.returncode, 2)
        self.assertIn("the case has 0 fluid particles (dx = 1.0", r.stderr)
        self.assertIn("a smaller dx", r.stderr)
        self.assertFalse((self.tmp / "b" / "summary.json").exists())

    def test_more_threads_than_cores_warns(self):
        threads = (os.cpu_count() or 1) + 1
        r = self.sphnl("run", "--set", "particles=3000", "--set", "steps=1", "--set", f"threads={threads}",
                       "--quiet", "--out", self.tmp / "a")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn(f"warning: threads = {threads} is more than the", r.stderr)
        r = self.sphnl("run", "--set", "particles=3000", "--set", "steps=1", "--quiet", "--out", self.tmp / "b")
        self.assertNotIn("warning", r.stderr)

    def test_output_folder_of_another_run_is_not_mixed(self):
        out = self.tmp / "a"
        r = self.sphnl("run", "--set", "particles=3000", "--set", "steps=4", "--set", "output_interval=0",
                       "--quiet", "--out", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertTrue((out / "snapshots" / "step_000004.csv").exists())
        (out / "notes.txt").write_text("mine")
        r = self.sphnl("run", "--set", "particles=3000", "--set", "steps=2", "--set", "output_interval=0",
                       "--quiet", "--out", out)
        self.assertEqual(r.returncode, 2)
        self.assertIn(f"output folder '{out}' already holds a run", r.stderr)
        self.assertIn("--overwrite", r.stderr)
        r = self.sphnl("run", "--set", "particles=3000", "--set", "steps=2", "--set", "output_interval=0",
                       "--quiet", "--out", out, "--overwrite")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(p.name for p in (out / "snapshots").iterdir()), ["step_000002.csv", "step_000002.vtu"])
        self.assertEqual((out / "notes.txt").read_text(), "mine")  # not sphnl's: kept

    def test_memory_estimate_stops_at_once_and_can_be_overridden(self):
        start = time.monotonic()
        r = self.sphnl("run", "--set", "particles=100000000", "--quiet", "--out", self.tmp / "a")
        self.assertEqual(r.returncode, 2)
        self.assertLess(time.monotonic() - start, 5)
        self.assertIn("this run needs about", r.stderr)
        self.assertIn("pass --force-memory to run anyway", r.stderr)
        small = {"SPHNL_MEMORY_AVAILABLE": "1000000"}
        args = ["run", "--set", "particles=3000", "--set", "steps=1", "--quiet"]
        self.assertEqual(self.sphnl(*args, "--out", self.tmp / "b", env=small).returncode, 2)
        r = self.sphnl(*args, "--out", self.tmp / "c", "--force-memory", env=small)
        self.assertEqual(r.returncode, 0, r.stderr)

    def test_peak_rss_is_the_runs_own_not_the_parents(self):
        # ru_maxrss survives execve: a 300 MB parent made every child report >= 300 MB.
        ballast = bytearray(300 * 1024 * 1024)
        ballast[::4096] = b"x" * len(ballast[::4096])  # touch every page
        r = self.sphnl("run", "--set", "particles=3000", "--set", "steps=1", "--quiet", "--out", self.tmp / "a")
        self.assertEqual(r.returncode, 0, r.stderr)
        peak = json.loads((self.tmp / "a" / "summary.json").read_text())["peak_rss_bytes"]
        del ballast
        self.assertLess(peak, 100 * 1024 * 1024)

    def test_memory_estimate_is_within_a_factor_of_the_measured_peak(self):
        # Black box: with MemAvailable faked at 2x the measured peak RSS the
        # run is allowed (estimate <= 2x), at 0.8x it is refused (estimate >= 0.8x).
        for lst in ("cll", "vlx"):
            args = ["run", "--set", "particles=40000", "--set", "steps=3", "--set", f"list={lst}",
                    "--set", "output_interval=0", "--quiet", "--overwrite"]
            r = self.sphnl(*args, "--out", self.tmp / lst)
            self.assertEqual(r.returncode, 0, r.stderr)
            peak = json.loads((self.tmp / lst / "summary.json").read_text())["peak_rss_bytes"]
            r = self.sphnl(*args, "--out", self.tmp / lst, env={"SPHNL_MEMORY_AVAILABLE": str(2 * peak)})
            self.assertEqual(r.returncode, 0, f"{lst}: estimate above 2x the peak RSS {peak}: {r.stderr}")
            r = self.sphnl(*args, "--out", self.tmp / lst, env={"SPHNL_MEMORY_AVAILABLE": str(int(0.8 * peak))})
            self.assertEqual(r.returncode, 2, f"{lst}: estimate below 0.8x the peak RSS {peak}")


@unittest.skipUnless(SPHNL.exists(), f"{SPHNL} not built")
class NeighboursTest(unittest.TestCase):
    def setUp(self):
        self.tmp = pathlib.Path(tempfile.mkdtemp(prefix="sphnl_robust_"))

    def neighbours(self, text, *args):
        inp = self.tmp / "in.csv"
        inp.write_text(text)
        return run([SPHNL, "neighbours", "--input", inp, "--radius", "0.1", "--out", self.tmp / "counts.csv", *args])

    def test_identical_points_are_refused_before_allocating(self):
        start = time.monotonic()
        r = self.neighbours("x,y,z\n" + "0.5,0.5,0.5\n" * 100000)
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertLess(time.monotonic() - start, 10)
        self.assertIn("9999900000 list entries, counted before allocating", r.stderr)
        self.assertIn("--force-memory 1", r.stderr)
        self.assertNotIn("bad_alloc", r.stderr)
        self.assertFalse((self.tmp / "counts.csv").exists())

    def test_semicolon_line_is_one_point(self):
        r = self.neighbours("0;0;0\n")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual((self.tmp / "counts.csv").read_text(), "index,count\n0,0\n")
        r = self.neighbours("x;y;z\n0;0;0\n0.05;0;0\n")
        self.assertEqual((self.tmp / "counts.csv").read_text(), "index,count\n0,1\n1,1\n")

    def test_gridder_c_overflow_suggests_this_tools_option(self):
        r = self.neighbours("0.5,0.5,0.5\n" * 50 + "".join(f"{i * 0.3},0,0\n" for i in range(20)),
                            "--gridder", "C", "--max-parts-in-cell", "4")
        self.assertEqual(r.returncode, 1)
        self.assertIn("--max-parts-in-cell 100", r.stderr)
        self.assertNotIn("--set", r.stderr)

    def test_failed_pairs_write_leaves_no_counts(self):
        blocker = self.tmp / "a_file"
        blocker.write_text("x")
        r = self.neighbours("0,0,0\n0.05,0,0\n", "--pairs", blocker / "pairs.csv")
        self.assertEqual(r.returncode, 1)
        self.assertIn("pairs.csv", r.stderr)
        self.assertEqual(sorted(p.name for p in self.tmp.iterdir()), ["a_file", "in.csv"])

    def test_bytes_used_is_in_use_not_capacity(self):
        r = self.neighbours("".join(f"{i * 0.01},0,0\n" for i in range(2000)))
        self.assertEqual(r.returncode, 0, r.stderr)
        line = next(l for l in r.stdout.splitlines() if l.startswith("bytes used"))
        used, lists, capacity = (int(v) for v in
                                 __import__("re").findall(r"(?:used|lists|capacity)\s+(\d+)", line))
        entries = int(next(l for l in r.stdout.splitlines() if l.startswith("list entries")).split()[2])
        self.assertEqual(lists, entries * 4 + 2001 * 8 + 2000 * 4)
        self.assertLessEqual(lists, capacity)
        self.assertGreater(used, lists)


if __name__ == "__main__":
    unittest.main()
