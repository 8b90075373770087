#!/usr/bin/python3
"""Run the experiments of experiments/*.json with sphnl_bench (docs/CONTRACTS.md).

    /usr/bin/python3 -m experiments.run --size default [--run-id ID] [--only fig06,fig14]

(from the repository root, or with PYTHONPATH set to it: harness/__init__.py)

Writes results/<run-id>/<id>.json (raw Google Benchmark JSON, renamed into
place only when complete) and results/<run-id>/machine.json. Resumable: an
experiment whose JSON already lists every sweep point is skipped unless --force;
one that lacks some N is completed by running only those N and merging.
--max-n caps every sweep at N <= MAX_N (for a long FULL run done in parts).
"""
import argparse
import collections
import copy
import datetime
import json
import os
import pathlib
import platform
import re
import subprocess
import sys
import threading
import time

from harness import results as R
from harness.fsio import write_atomic

REPO = pathlib.Path(__file__).resolve().parent.parent

AGGREGATE = re.compile(r"_(mean|median|stddev|cv)$")


class RunError(Exception):
    """A failure to report to the user in one message (exit code 1 or 2)."""
    def __init__(self, message, code=1):
        super().__init__(message)
        self.code = code


# ------------------------------------------------------------------ estimates
def step_seconds(p):
    """Cost model of one step (seconds) used for the up-front estimate: the
    brief's ~2 us per particle-step for CLL, plus gridder A's insertion shifts
    (about n/2 4-byte moves per particle at ~10 GB/s when not reordered)."""
    n = p["n"]
    t = 2e-6 * n * (1.3 if p.get("reorder") == 0 else 1.0)
    if p.get("gridder") == "A":
        t += 2e-10 * n * n if p.get("reorder") == 0 else 1e-6 * n
    if p.get("list", "cll") != "cll" and p.get("ns") == 1:
        t *= 1.15
    if p.get("kgc"):
        t *= 1.8
    threads = p.get("threads", 1)
    return t / (0.85 * threads) if threads > 1 else t


def estimate_seconds(exp, size):
    """Model estimate of one experiment's bench time, overhead included."""
    if exp.get("uses"):
        return 0.0
    steps, reps = exp["window_steps"][size], exp["repetitions"][size]
    if exp["benchmark"] == "step":
        per = [step_seconds(p) * steps for p in R.sweep_points(exp, size)]
    else:  # cellindex: ~2e6 cell keys per iteration
        per = [0.05 for _ in R.sweep_points(exp, size)]
    return sum(t * reps + 0.2 for t in per)


def hms(seconds):
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


# -------------------------------------------------------------------- machine
def _cmd(*args):
    try:
        out = subprocess.run(args, capture_output=True, text=True, timeout=30,
                             cwd=REPO, env={**os.environ, "LC_ALL": "C"})
        return out.stdout.strip() if out.returncode == 0 else ""
    except (OSError, subprocess.TimeoutExpired):
        return ""


def machine_info(args):
    """CPU, caches, memory, compiler, git revision, date and size of this run."""
    cpu = dict(line.split(":", 1) for line in _cmd("lscpu").splitlines() if ":" in line)
    cpu = {k.strip(): v.strip() for k, v in cpu.items()}
    as_int = lambda k: int(cpu[k]) if cpu.get(k, "").isdigit() else None  # noqa: E731
    mem_kib = re.search(r"MemTotal:\s+(\d+)", pathlib.Path("/proc/meminfo").read_text(encoding="utf-8")
                        if os.path.exists("/proc/meminfo") else "")
    sockets, per_socket = as_int("Socket(s)"), as_int("Core(s) per socket")
    rev = _cmd("git", "rev-parse", "HEAD")
    return {
        "run_id": args.run_id, "size": args.size,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "cpu_model": cpu.get("Model name", platform.processor() or "unknown"),
        "logical_cpus": as_int("CPU(s)") or os.cpu_count(),
        "cores": sockets * per_socket if sockets and per_socket else None,
        "threads_per_core": as_int("Thread(s) per core"),
        "caches": {k.replace(" cache", ""): cpu[k] for k in
                   ("L1d cache", "L1i cache", "L2 cache", "L3 cache") if k in cpu},
        "memory_bytes": int(mem_kib.group(1)) * 1024 if mem_kib else None,
        "compiler": (_cmd("c++", "--version").splitlines() or ["unknown"])[0],
        "git_revision": rev or "unknown",
        # Results written by earlier parts of this run do not make the code dirty.
        "git_dirty": bool(_cmd("git", "status", "--porcelain", "--", ".", ":!results")) if rev else None,
        "os": platform.platform(),
        "python": platform.python_version(),
        "bench": str(args.bench),
        "max_n": args.max_n,
    }


def machine_record(args, path):
    """machine.json for this invocation; earlier invocations that wrote into the
    same run folder (a run done in parts) are listed under `earlier`."""
    info = machine_info(args)
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
        earlier = old.pop("earlier", [])
        info["earlier"] = earlier + [{k: old.get(k) for k in
                                      ("date", "git_revision", "git_dirty", "max_n", "bench")}]
    except (OSError, ValueError, AttributeError):
        pass
    return info


# ------------------------------------------------------------------- running
def restrict_n(exp, size, keep):
    """`exp` with its sweep's N limited to those for which keep(n) is true
    (unchanged when the sweep has no N axis)."""
    sweep = exp["sweep"].get(size, {})
    if "n" not in sweep:
        return exp
    out = copy.deepcopy(exp)
    out["sweep"][size]["n"] = [n for n in sweep["n"] if keep(n)]
    out["_restricted"] = True  # its sweep is not the file's: the bench gets a copy
    return out


def bench_env(args):
    """Environment of the bench: a .py stand-in (tests/python/fake_bench.py)
    imports the harness package, so it gets the repository root on PYTHONPATH."""
    env = dict(os.environ)
    if args.bench.suffix == ".py":
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    return env


def bench_command(args, exp, out_tmp, exp_file):
    base = [sys.executable, str(args.bench)] if args.bench.suffix == ".py" else [str(args.bench)]
    return base + [
        f"--experiment={exp_file}",
        f"--size={args.size}",
        f"--cache-dir={args.cache_dir}",
        f"--benchmark_out={out_tmp}",
        "--benchmark_out_format=json",
        f"--benchmark_repetitions={exp['repetitions'][args.size]}",
        "--benchmark_min_time=0",
    ]


def resume_plan(args, exp, out_path):
    """(experiment to run, benchmark entries to keep): when out_path holds some
    but not all N of the sweep, only the missing N are run and the rest kept."""
    if args.force or not out_path.exists() or "n" not in exp["sweep"][args.size]:
        return exp, []
    try:
        doc = R.read_benchmark_json(out_path)
        missing = R.missing_in(doc, exp, args.size)
    except R.ResultsError:
        return exp, []
    rerun = {R.parse_run_name(name)[1]["n"] for name in missing}

    def n_of(entry):
        family, params = R.parse_run_name(entry.get("run_name", entry.get("name", "")))
        return params.get("n") if family == exp["benchmark"] else None
    keep = [b for b in doc["benchmarks"] if n_of(b) not in (None, *rerun)]
    if not keep:
        return exp, []
    print(f"  {exp['id']}: keeping {len(keep)} entries of {out_path.name}; running only "
          f"N = {', '.join(str(n) for n in sorted(rerun))}", flush=True)
    return restrict_n(exp, args.size, lambda n: n in rerun), keep


def run_experiment(args, exp, out_path, label):
    """Run one experiment; the JSON appears at out_path only if complete."""
    size, family = args.size, exp["benchmark"]
    full_exp = exp
    exp, keep = resume_plan(args, exp, out_path)
    configs = len(R.sweep_points(exp, size))
    reps = exp["repetitions"][size]
    print(f"{label} {exp['id']}: {configs} configurations x {reps} repetitions, "
          f"{exp['window_steps'][size]} steps each (model estimate {hms(estimate_seconds(exp, size))})",
          flush=True)
    tmp = out_path.with_name(f".{out_path.name}.partial")
    exp_file = REPO / "experiments" / (exp["id"] + ".json")
    if exp.get("_restricted"):  # the bench reads its sweep from a file: give it the restricted one
        exp_file = out_path.with_name(f".{exp['id']}.experiment.json")
        write_atomic(exp_file, json.dumps({k: v for k, v in exp.items() if k != "_restricted"},
                                            indent=1) + "\n")
    cmd = bench_command(args, exp, tmp, exp_file)
    if args.verbose:
        print("  $ " + " ".join(cmd), flush=True)
    start, lines = time.monotonic(), 0
    tail = collections.deque(maxlen=30)
    try:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, bufsize=1, cwd=REPO, env=bench_env(args))
    except OSError as e:
        raise RunError(f"cannot start {args.bench}: {e}", 2) from None

    def pump_stderr():  # keep a tail; show the bench's own messages (snapshots)
        for line in proc.stderr:
            tail.append(line.rstrip("\n"))
            if args.verbose or line.startswith("sphnl_bench"):
                print("  | " + line.rstrip("\n"), file=sys.stderr, flush=True)
    reader = threading.Thread(target=pump_stderr, daemon=True)
    reader.start()
    try:
        for line in proc.stdout:
            if args.verbose:
                print("  > " + line.rstrip("\n"), flush=True)
            token = (line.split() or [""])[0]
            if token.startswith(family + "/") and not AGGREGATE.search(token):
                lines += 1
                if lines % reps == 0:
                    elapsed = time.monotonic() - start
                    eta = elapsed / lines * (configs * reps - lines)
                    print(f"  {exp['id']}: configs done {lines // reps}/{configs}, "
                          f"elapsed {hms(elapsed)}, ETA {hms(eta)}", flush=True)
        rc = proc.wait()
        reader.join(timeout=5)
        if rc != 0:
            raise RunError(f"{exp['id']}: {args.bench} exited with status {rc}; nothing saved.\n"
                           "Last lines of its stderr:\n  " + "\n  ".join(tail or ["(empty)"]))
        try:
            doc = R.read_benchmark_json(tmp)
            if keep:  # merge with the entries kept from the earlier run
                doc["benchmarks"] = keep + doc["benchmarks"]
                doc["context"]["sphnl_merged"] = (f"{len(keep)} entries kept from an earlier run "
                                                  "of this experiment (other N)")
                write_atomic(tmp, json.dumps(doc, indent=2) + "\n")
            missing = R.missing_in(doc, full_exp, size)
        except R.ResultsError as e:
            raise RunError(f"{exp['id']}: the bench exited 0 but its output is unusable: {e}") from None
        if missing:
            raise RunError(f"{exp['id']}: the bench output lacks {len(missing)} of {configs} sweep "
                           "points (names must follow docs/CONTRACTS.md), e.g.\n  "
                           + "\n  ".join(missing[:5]))
        os.replace(tmp, out_path)
    finally:  # on any failure or Ctrl-C: no bench left running, no partial JSON left
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        tmp.unlink(missing_ok=True)
        if exp.get("_restricted"):
            exp_file.unlink(missing_ok=True)
    print(f"  {exp['id']}: done in {hms(time.monotonic() - start)} -> {out_path}", flush=True)


def status(out_path, exp, size):
    """'complete', or why the experiment must (re)run."""
    if not out_path.exists():
        return "not run"
    try:
        missing = R.missing_points(out_path, exp, size)
    except R.ResultsError as e:
        return f"unreadable ({e})"
    return "complete" if not missing else f"incomplete ({len(missing)} sweep points missing)"


def select(experiments, only):
    """Experiments to run, in report order; a uses-only id selects its source.
    Without --only: every experiment that draws a paper figure or study
    (those with "figure": null, like the CI set `compare`, only on request)."""
    if not only:
        ids = [i for i, e in experiments.items() if e.get("figure")]
    else:
        ids = [s.strip() for s in only.split(",") if s.strip()]
        unknown = [i for i in ids if i not in experiments]
        if unknown:
            raise RunError(f"unknown experiment id(s) {', '.join(unknown)}; valid ids: "
                           + ", ".join(experiments), 2)
    chosen = []
    for i in ids:
        src = experiments[i].get("uses") or i
        if src != i and only:
            print(f"{i} is drawn from {src}: running {src}")
        if src not in chosen:
            chosen.append(src)
    return [experiments[i] for i in experiments if i in chosen]


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", choices=R.SIZES, default="default",
                   help="sweep size of every experiment (default: default)")
    p.add_argument("--run-id", help="results sub-folder (default: the size)")
    p.add_argument("--results-dir", type=pathlib.Path, default=REPO / "results",
                   help="where <run-id>/ is written (default: results)")
    p.add_argument("--bench", type=pathlib.Path, default=REPO / "build/benchmarks/sphnl_bench",
                   help="benchmark binary (default: build/benchmarks/sphnl_bench; "
                        "a .py file is run with this Python)")
    p.add_argument("--only", help="comma-separated experiment ids (default: every experiment "
                                  "that draws a figure; a uses-only id runs its source)")
    p.add_argument("--force", action="store_true", help="rerun experiments already complete")
    p.add_argument("--cache-dir", type=pathlib.Path,
                   help="snapshot cache passed to the bench (default: RESULTS_DIR/cache)")
    p.add_argument("--max-n", type=int, metavar="N",
                   help="leave out sweep points with more than N particles (a long FULL run in "
                        "parts: rerun later without it and only the missing N run)")
    p.add_argument("--dry-run", action="store_true",
                   help="print the plan and the model time estimate, run nothing")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="echo the bench command, its stdout and stderr")
    args = p.parse_args(argv)
    if args.max_n is not None and args.max_n < 1:
        p.error(f"--max-n must be a positive particle count, not {args.max_n}")
    args.run_id = args.run_id or args.size
    args.cache_dir = (args.cache_dir or args.results_dir / "cache").resolve()
    args.bench = args.bench.resolve() if args.bench.exists() else args.bench
    return args


def main(argv=None):
    args = parse_args(argv)
    try:
        experiments = R.load_experiments(REPO / "experiments")
        chosen = select(experiments, args.only)
        if args.max_n is not None:
            capped = [restrict_n(e, args.size, lambda n: n <= args.max_n) for e in chosen]
            for e in capped:
                if "n" in e["sweep"][args.size] and not e["sweep"][args.size]["n"]:
                    print(f"{e['id']}: no sweep point with N <= {args.max_n}, left out")
            chosen = [e for e in capped if e["sweep"][args.size].get("n", True)]
        out_dir = args.results_dir / args.run_id
        plan = []
        for exp in chosen:
            out = out_dir / f"{exp['id']}.json"
            state = status(out, exp, args.size)
            plan.append((exp, out, state if args.force or state != "complete" else None))
        todo = [(exp, out) for exp, out, why in plan if why]
        total = sum(estimate_seconds(e, args.size) for e, _ in todo)
        for exp, out, why in plan:
            print(f"{exp['id']}: {'run (' + why + ')' if why else 'complete, skipped (--force reruns)'}")
        print(f"{len(todo)} of {len(plan)} experiments to run, model estimate {hms(total)} "
              f"(plus snapshot creation for new N)", flush=True)
        if args.dry_run or not todo:
            return 0
        if not (args.bench.is_file() and os.access(args.bench, os.X_OK)):
            raise RunError(f"benchmark binary {args.bench} not found or not executable; "
                           "build it first with `make build`", 2)
        out_dir.mkdir(parents=True, exist_ok=True)
        write_atomic(out_dir / "machine.json",
                       json.dumps(machine_record(args, out_dir / "machine.json"), indent=2) + "\n")
        start, modelled = time.monotonic(), 0.0
        for k, (exp, out) in enumerate(todo, 1):
            if modelled:  # scale the model by how fast this machine has been so far
                left = sum(estimate_seconds(e, args.size) for e, _ in todo[k - 1:])
                print(f"overall: {k - 1}/{len(todo)} experiments done in "
                      f"{hms(time.monotonic() - start)}, about "
                      f"{hms(left * (time.monotonic() - start) / modelled)} left", flush=True)
            run_experiment(args, exp, out, f"[{k}/{len(todo)}]")
            modelled += estimate_seconds(exp, args.size)
        print(f"all done; draw the figures with: /usr/bin/python3 -m plots.report {out_dir}")
        return 0
    except (RunError, R.ResultsError) as e:
        print(f"error: {e}", file=sys.stderr)
        return getattr(e, "code", 2)
    except KeyboardInterrupt:
        print("\ninterrupted: the experiment in progress was not saved; rerun to resume",
              file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
