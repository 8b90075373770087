"""End-to-end robustness of the built binaries (`make test` sets SPHNL_BUILD_DIR):
sphnl_bench validates its experiment file, reports a failure inside a benchmark
on stderr with a non-zero exit, and dies with its parent; `sphnl run` and
`sphnl neighbours` refuse nonsense and never leave partial or mixed output."""
import json
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import time
import unittest

REPO = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("SPHNL_BUILD_DIR", REPO / "build"))
BENCH = BUILD / "benchmarks" / "sphnl_bench"
SPHNL = BUILD / "sphnl"
SNAP_1500 = "dambreak_v1_n1500_bcc_h0.866025_t0.35.snap"


def run(cmd, **kw):
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=300, **kw)


def pid_alive(pid):
    """True while `pid` runs (a zombie or a reused pid of another program is not it)."""
    try:
        stat = pathlib.Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z" and "sphnl_bench" in stat


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

    def test_misspelled_axis_fails_before_any_benchmark(self):
        exp = self.experiment(lambda d: d.replace('"gridder"', '"gridderr"', 1))
        for extra in (["--validate"], ["--size=tiny", "--benchmark_min_time=0"]):
            r = run([BENCH, f"--experiment={exp}", f"--cache-dir={self.tmp / 'cache'}", *extra])
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertIn(f"{exp}:7:", r.stderr)
            self.assertIn("unknown sweep axis 'gridderr'", r.stderr)
            self.assertIn("allowed: n, gridder,", r.stderr)
            self.assertNotIn("step/", r.stdout)  # nothing ran

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
        for reps in ("1", "3"):  # 3 used to abort in ComputeStats, 1 to exit 0
            r = run([BENCH, f"--experiment={REPO / 'experiments' / 'fig06.json'}", "--size=tiny",
                     f"--cache-dir={cache}", "--benchmark_min_time=0", f"--benchmark_repetitions={reps}",
                     f"--benchmark_out={self.tmp / 'out.json'}", "--benchmark_out_format=json"])
            self.assertEqual(r.returncode, 1, r.stderr)
            self.assertIn("failed: cannot rename", r.stderr)
            self.assertIn(SNAP_1500, r.stderr)
            self.assertNotIn("ComputeStats", r.stderr)

    def test_debug_library_warning_is_explained(self):
        r = run([BENCH, f"--experiment={REPO / 'experiments' / 'cellindex.json'}", "--size=tiny",
                 f"--cache-dir={self.tmp / 'cache'}", "--benchmark_min_time=0",
                 "--benchmark_filter=order:sort_x/"])
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


if __name__ == "__main__":
    unittest.main()
