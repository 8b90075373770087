#!/usr/bin/python3
"""Resume a run folder with the code that measured it, after this checkout
has moved on.

    /usr/bin/python3 -m experiments.resume_run results/<run-id> [--only fig14,fig16] [--max-n N]

A FULL run takes longer than one sitting, so it is made in parts
(experiments/run.py --max-n, --only), and run.py refuses to add a part made
by other code. Once this checkout holds newer commits, `make reproduce` can
no longer finish such a run. This script reads the revision every part of
the folder was measured with (machine.json), checks that revision out in a
git worktree of its own (build-rev-<revision>/tree, beside the other
build-* folders), configures it with that revision's own `make configure`,
builds its bench and `sphnl`, and runs that revision's experiments/run.py into the same
folder. The bench embeds its revision and no path, so a rebuild of the same
revision by the same compiler for the same CPU is the same binary; where it
is not, this stops before measuring (run.py would refuse the part). The
report is drawn by this checkout's plots/ afterwards (`make resume` does).
"""
import argparse
import json
import os
import pathlib
import shlex
import subprocess
import sys

from experiments import run as RUN
from harness import machine as M

REPO = pathlib.Path(__file__).resolve().parent.parent
SIZES = ("tiny", "default", "full")


class ResumeError(Exception):
    """A failure to report in one message (exit code 2)."""


def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run_dir", type=pathlib.Path, help="the run folder to resume (results/<run-id>)")
    ap.add_argument("--only", help="comma-separated experiment ids (default: run.py's default set)")
    ap.add_argument("--max-n", type=int, metavar="N", help="leave out sweep points above N particles")
    ap.add_argument("--with-counters", action="store_true",
                    help="also run the counters experiments (builds that revision's counters build; "
                         "hours of valgrind at the full size); left out by default")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 2, help="build jobs (default: every CPU)")
    ap.add_argument("--python", default=sys.executable, help="interpreter for that revision's run.py")
    ap.add_argument("--dry-run", action="store_true",
                    help="print what would be checked out, built and run; change nothing")
    return ap.parse_args(argv)


def run_revision(run_dir):
    """(revision, size, parts) of the run folder: the one clean revision all
    its parts were measured with."""
    if not run_dir.is_dir():
        raise ResumeError(f"{run_dir}: no such run folder (give results/<run-id>)")
    path = run_dir / "machine.json"
    try:
        machine = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ResumeError(f"{path}: missing; only a folder written by experiments/run.py can be resumed") from None
    except (OSError, ValueError) as e:
        raise ResumeError(f"{path}: not readable JSON ({e})") from None
    parts = RUN.earlier_parts(machine)
    revisions = sorted({p.get("git_revision") for p in parts})
    if None in revisions or "unknown" in revisions:
        raise ResumeError(f"{path}: a part records no git revision; the code that measured it is unknown, "
                          "so the run cannot be resumed with it (measure into a new run folder)")
    if len(revisions) != 1:
        raise ResumeError(f"{path}: its parts were measured by {len(revisions)} revisions "
                          f"({', '.join(r[:12] for r in revisions)}); a run of mixed code has no one revision "
                          "to resume with (measure into a new run folder)")
    if any(p.get("git_dirty") for p in parts):
        raise ResumeError(f"{path}: a part was measured from a tree with uncommitted changes, which no "
                          "revision reproduces (measure into a new run folder)")
    size = machine.get("size")
    if size not in SIZES:
        raise ResumeError(f"{path}: size {size!r} is not one of {', '.join(SIZES)}")
    return revisions[0], size, parts


def git(*args, cwd=REPO, check=True):
    out = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True)
    if check and out.returncode:
        raise ResumeError(f"git {' '.join(args)} failed: {out.stderr.strip()}")
    return out


def plan(args):
    """The commands that resume the run: the build steps and then the
    measurement, each a (description, argv, cwd) triple, and the folders
    they use."""
    revision, size, parts = run_revision(args.run_dir)
    if git("cat-file", "-e", f"{revision}^{{commit}}", check=False).returncode:
        raise ResumeError(f"revision {revision[:12]} (every part of {args.run_dir}) is not in this repository; "
                          "fetch it, then run this again")
    home = REPO / f"build-rev-{revision[:12]}"
    tree, build = home / "tree", home / "build"
    run_dir = args.run_dir.resolve()
    steps = []
    if not tree.exists():
        steps.append((f"check out {revision[:12]}", ["git", "worktree", "add", "--detach", str(tree), revision], REPO))
    # That revision's own configure rule, so its build flags are the ones it
    # was measured with, whatever today's Makefile passes.
    steps.append(("configure with that revision's `make configure`",
                  ["make", "-C", str(tree), "configure", f"BUILD={build}", f"PYTHON={args.python}"], REPO))
    steps.append(("build the bench and sphnl",
                  ["cmake", "--build", str(build), "-j", str(args.jobs), "--target", "sphnl_bench", "sphnl"], REPO))
    run = [args.python, "-m", "experiments.run", "--size", size, "--run-id", run_dir.name,
           "--results-dir", str(run_dir.parent), "--bench", str(build / "benchmarks" / "sphnl_bench"),
           "--sphnl", str(build / "sphnl")]
    if args.with_counters:
        counters = home / "build-counters"
        steps.append(("the counters build (valgrind)",
                      ["make", "-C", str(tree), "counters-build", f"COUNTERS_BUILD={counters}",
                       f"PYTHON={args.python}"], REPO))
        run += ["--counters-bench", str(counters / "benchmarks" / "sphnl_bench")]
    else:
        run.append("--skip-counters")
    if args.only:
        run += ["--only", args.only]
    if args.max_n is not None:
        run += ["--max-n", str(args.max_n)]
    measure = (f"measure with {revision[:12]}'s experiments/run.py", run, tree)
    return revision, parts, tree, build, steps, measure


def check_tree(tree, revision):
    """A worktree left by an earlier resume must still be that revision, clean."""
    head = git("rev-parse", "HEAD", cwd=tree).stdout.strip()
    if head != revision:
        raise ResumeError(f"{tree} holds {head[:12]}, not {revision[:12]}; remove it "
                          f"(git worktree remove --force {tree}) and run this again")
    if git("status", "--porcelain", "--untracked-files=no", cwd=tree).stdout.strip():
        raise ResumeError(f"{tree} has uncommitted changes; remove it (git worktree remove --force {tree}) "
                          "and run this again")


def check_bench(bench, parts):
    """The rebuilt bench must be the binary the parts were measured with."""
    want = {p.get("bench_sha256") for p in parts} - {None}
    got = M.sha256(bench)
    if want and got not in want:
        raise ResumeError(f"the rebuilt {bench} (sha256 {got[:12]}) is not the binary the run was measured with "
                          f"({', '.join(w[:12] for w in sorted(want))}): another compiler, or -march=native on "
                          "another CPU; measure into a new run folder on the machine that made it")


def run_step(step, dry_run):
    what, argv, cwd = step
    print(f"resume: {what}: {shlex.join(argv)}" + (f"  (in {cwd})" if cwd != REPO else ""), flush=True)
    if not dry_run:
        code = subprocess.run(argv, cwd=cwd).returncode
        if code:
            raise ResumeError(f"{what} failed (exit code {code})")


def main(argv=None):
    args = parse_args(argv)
    try:
        revision, parts, tree, build, steps, measure = plan(args)
        if tree.exists():
            check_tree(tree, revision)
        for step in steps:
            run_step(step, args.dry_run)
        if not args.dry_run:
            check_bench(build / "benchmarks" / "sphnl_bench", parts)
        run_step(measure, args.dry_run)
    except ResumeError as e:
        print(f"resume_run: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
