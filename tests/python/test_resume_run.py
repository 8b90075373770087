"""experiments/resume_run.py: which revision a run folder is resumed with,
what is refused, and the plan it prints (--dry-run; the build and the
measurement themselves are what `make reproduce` already exercises)."""
import contextlib
import io
import json
import pathlib
import shutil
import subprocess
import tempfile
import unittest

from experiments import resume_run as RR
from harness import machine as M

REPO = pathlib.Path(__file__).resolve().parents[2]
HEAD = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()


def call(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = RR.main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


class TestResumeRun(unittest.TestCase):
    def setUp(self):
        self.tmp = pathlib.Path(tempfile.mkdtemp(prefix="sphnl-resume-"))
        self.addCleanup(shutil.rmtree, self.tmp, ignore_errors=True)
        self.run_dir = self.tmp / "full-x"
        self.run_dir.mkdir()

    def write_parts(self, *parts, size="full"):
        (self.run_dir / "machine.json").write_text(json.dumps({"size": size, "parts": list(parts)}))

    def part(self, **more):
        return {"date": "d", "git_revision": HEAD, "git_dirty": False, "bench_sha256": "1" * 64, **more}

    def test_refusals_name_the_problem(self):
        code, _, err = call(self.tmp / "nope")
        self.assertEqual(code, 2)
        self.assertIn("no such run folder", err)
        code, _, err = call(self.run_dir)
        self.assertIn("machine.json: missing", err)
        self.write_parts(self.part(), self.part(git_revision="b" * 40))
        code, _, err = call(self.run_dir)
        self.assertEqual(code, 2)
        self.assertIn("measured by 2 revisions", err)
        self.assertIn("bbbbbbbbbbbb", err)
        self.write_parts(self.part(git_dirty=True))
        self.assertIn("uncommitted changes", call(self.run_dir)[2])
        self.write_parts(self.part(git_revision=None))
        self.assertIn("records no git revision", call(self.run_dir)[2])
        self.write_parts(self.part(git_revision="f" * 40))
        self.assertIn("is not in this repository", call(self.run_dir, "--dry-run")[2])
        self.write_parts(self.part(), size="huge")
        self.assertIn("size 'huge'", call(self.run_dir)[2])

    @unittest.skipUnless(HEAD, "not a git checkout")
    def test_dry_run_prints_the_plan_and_changes_nothing(self):
        self.write_parts(self.part(), self.part())
        home = REPO / f"build-rev-{HEAD[:12]}"
        existed = home.exists()
        code, out, err = call(self.run_dir, "--dry-run", "--only", "fig14,fig16", "--max-n", "300000",
                              "--python", "/usr/bin/python3", "--jobs", "3")
        self.assertEqual(code, 0, err)
        if not existed:
            self.assertIn(f"git worktree add --detach {home / 'tree'} {HEAD}", out)
            self.assertFalse(home.exists())
        self.assertIn(f"make -C {home / 'tree'} configure BUILD={home / 'build'} PYTHON=/usr/bin/python3", out)
        self.assertIn("--target sphnl_bench sphnl", out)
        self.assertIn("-j 3", out)
        run = next(line for line in out.splitlines() if "experiments.run" in line)
        for want in ("/usr/bin/python3 -m experiments.run --size full --run-id full-x",
                     f"--results-dir {self.tmp.resolve()}", f"--bench {home / 'build' / 'benchmarks' / 'sphnl_bench'}",
                     "--skip-counters", "--only fig14,fig16", "--max-n 300000", f"(in {home / 'tree'})"):
            self.assertIn(want, run)
        code, out, _ = call(self.run_dir, "--dry-run", "--with-counters")
        self.assertIn("counters-build", out)
        self.assertNotIn("--skip-counters", out)

    def test_a_worktree_of_another_revision_is_refused(self):
        with self.assertRaisesRegex(RR.ResumeError, "not 000000000000"):
            RR.check_tree(REPO, "0" * 40)

    def test_a_rebuilt_bench_that_differs_stops_before_measuring(self):
        bench = self.tmp / "sphnl_bench"
        bench.write_bytes(b"a binary")
        with self.assertRaisesRegex(RR.ResumeError, "not the binary the run was measured with"):
            RR.check_bench(bench, [self.part()])
        RR.check_bench(bench, [self.part(bench_sha256=M.sha256(bench))])  # the same: no error
        RR.check_bench(bench, [self.part(bench_sha256=None)])  # nothing recorded: run.py decides


if __name__ == "__main__":
    unittest.main()
