#!/usr/bin/python3
"""Run the experiments of experiments/*.json with sphnl_bench under the
measurement protocol of docs/MEASUREMENT.md (format: docs/CONTRACTS.md).

    /usr/bin/python3 -m experiments.run --size default [--run-id ID] [--only fig06,fig14]

(from the repository root, or with PYTHONPATH set to it: harness/__init__.py)

Every experiment is measured in rounds, one bench process each, with its
configurations' repetitions randomly interleaved and a discarded warm-up
iteration per configuration; rounds are added after the protocol's minimum
until every configuration's median is known to the experiment's target or its
time budget ends. Writes results/<run-id>/<id>.json (Google Benchmark JSON
with every repetition of every round, renamed into place only when complete)
and results/<run-id>/machine.json. Resumable: an experiment whose JSON already
lists every sweep point is skipped unless --force; one that lacks some N is
completed by running only those N and merging, which is refused when the code
differs from the earlier parts' unless --force-merge REASON.
--max-n caps every sweep at N <= MAX_N (for a long FULL run done in parts).
"""
import argparse
import collections
import copy
import json
import math
import os
import pathlib
import re
import subprocess
import sys
import threading
import time

from experiments import counters as CNT
from experiments import mpi_runs as MPI
from harness import machine as M
from harness import protocol as P
from harness import results as R
from harness.fsio import write_atomic

REPO = pathlib.Path(__file__).resolve().parent.parent

AGGREGATE = re.compile(r"_(mean|median|stddev|cv)$")
# The bench's line after it developed a flow snapshot (benchmarks/bench_common.cpp):
# that time is preparation, not measurement, and is not charged to the budget.
SNAPSHOT_DEVELOPED = re.compile(r"^sphnl_bench: developed in \d+ steps, ([0-9.]+) s wall")
# Pinning of the bench's OpenMP threads (recorded per round; a value already
# in the environment is kept, so a user can choose another binding).
PINNING = {"OMP_PROC_BIND": "close", "OMP_PLACES": "cores"}
# GB 1.7.1 runs iterations for this long before the measured ones of each
# configuration and discards them: one window, the first of the round.
WARMUP_FLAG = "--benchmark_min_warmup_time=0.000001"


class RunError(Exception):
    """A failure to report to the user in one message (exit code 1 or 2)."""
    def __init__(self, message, code=1):
        super().__init__(message)
        self.code = code


# ------------------------------------------------------------------ estimates
def particle_step_seconds(n):
    """CLL seconds per particle-step of one core: the medians of results/full
    (0.75 us at N = 8 000, 1.4 us at 60 000, 2.2 us at 10^6: caches), times
    1.12, the ratio of the bench time measured in results/full and
    results/reference to this model's (both 0.89)."""
    return 1.12 * max(0.3e-6, 0.75e-6 + 0.29e-6 * math.log(n / 8000))


def step_seconds(p):
    """Cost model of one step (seconds) of sweep point `p`, for the plan only:
    once running, ETAs come from the rounds measured."""
    n = p["particles"]
    base = particle_step_seconds(n) * n
    t = base * (1.05 if p.get("reorder") == 0 else 1.0)
    if p.get("cell_order", "sort_x") != "sort_x":
        t *= 1.03
    if p.get("gridder") == "A":  # insertion shifts when unsorted; 2x when reordered
        t += 1.1e-10 * n * n if p.get("reorder") == 0 else base
    if p.get("list", "cll") != "cll":
        t *= 0.86 + 0.001 * (p.get("list_steps", 1) - 4) ** 2
    if p.get("kgc"):
        t *= 1.85
    threads = p.get("threads", 1)
    return t / (0.85 * threads) if threads > 1 else t


def search_seconds(p):
    """Cost model of one repetition of a `search` point: the timed list build,
    plus (call: warm) the untimed build that warms the buffers up; a first
    call's timed lists are checked themselves. A build costs 0.5 us a point for sphnl on one core and 25x that for
    nanoflann (the ratio the default run's `peers` measured); with these the
    model gives the measured rounds of `peers`: 118 s against 2.0-2.7 min at
    the default size, 1 530 s against 24 min 29 s for a FULL round (one
    round, 3 December 2026, when a first call also made an untimed build),
    the time around the calls included."""
    one = 5e-7 * p["particles"] * (25 if p.get("impl", "sphnl") == "nanoflann" else 1)
    threads = p.get("threads", 1)
    freed = p.get("freed_memory", "as_found")
    # a freed_memory other than as_found makes an untimed call first, and
    # idle_<s>s then waits s seconds (benchmarks/search_benchmark.cpp)
    calls = 1 if p.get("call", "warm") == "first" and freed == "as_found" else 2
    idle = R.idle_seconds(freed) or 0
    return calls * (one / (0.9 * threads) if threads > 1 else one) + idle


ROUND_OVERHEAD_S = 0.3  # bench start, snapshot load, JSON


def round_seconds(exp, size):
    """Model of one round: every configuration's warm-up + repetitions."""
    reps = P.protocol_of(exp, size)["reps_per_round"]
    if exp["benchmark"] == "mpi":
        return MPI.estimate_seconds(exp, size, step_seconds) / P.protocol_of(exp, size)["min_rounds"]
    if exp["benchmark"] == "step":
        window = exp["window_steps"][size]
        per = [step_seconds(p) * window for p in R.sweep_points(exp, size)]
    elif exp["benchmark"] == "search":
        per = [search_seconds(p) for p in R.sweep_points(exp, size)]
    else:  # cellindex: >= 2e6 cell keys per iteration
        per = [0.02 for p in R.sweep_points(exp, size)]
    return sum(t * (reps + 1) for t in per) + ROUND_OVERHEAD_S


def estimate_seconds(exp, size):
    """Model estimate of one experiment at its minimum number of rounds (a
    counters experiment: its one round, one valgrind process at a time)."""
    if exp.get("uses"):
        return 0.0
    if exp["benchmark"] == "counters":
        return CNT.estimate_seconds(exp, size, step_seconds)
    if exp["benchmark"] == "mpi":
        return MPI.estimate_seconds(exp, size, step_seconds)
    return round_seconds(exp, size) * P.protocol_of(exp, size)["min_rounds"]


def most_seconds(exp, size):
    """Model of the longest an experiment may take: rounds are added while one
    more fits in the budget, up to max_rounds; the minimum rounds always run."""
    if exp.get("uses") or exp["benchmark"] == "counters":
        return estimate_seconds(exp, size)
    proto, per = P.protocol_of(exp, size), round_seconds(exp, size)
    fit = max(proto["min_rounds"], min(proto["max_rounds"], int(proto["budget_s"] // per)))
    return per * fit


def develop_steps(n, flow_time):
    """Steps of the development run to flow_time (3 346 to 0.35 s at N = 10^6;
    dt scales with the spacing, N^(-1/3))."""
    return 3346 * (n / 1e6) ** (1 / 3) * flow_time / 0.35


def snapshot_seconds(experiments, size, cache_dir):
    """Model of the development runs still to do: per case, one run from t = 0
    to the latest missing flow time (on every core), as bench_common.cpp does."""
    threads = os.cpu_count() or 1
    need = collections.defaultdict(set)
    for exp in experiments:
        if exp.get("uses") or exp["benchmark"] not in ("step", "counters", "cellindex"):
            continue
        for p in R.sweep_points(exp, size):
            need[p["particles"]].add(p.get("flow_time", R.DEFAULT_FLOW_TIME))
    def cached(n, t):  # the names of bench_common.cpp (lattice bcc, h coefficient 0.866025)
        stem = cache_dir / f"dambreak_v1_n{n}_bcc_h0.866025_t{R.format_value(float(t))}"
        legacy = t == R.DEFAULT_FLOW_TIME and pathlib.Path(f"{stem}.snap").exists()
        return legacy or pathlib.Path(f"{stem}_thr{threads}.snap").exists()
    total = 0.0
    for n, times in need.items():
        missing = [t for t in times if not cached(n, t)]
        if missing:
            total += develop_steps(n, max(missing)) * particle_step_seconds(n) * n / (0.85 * threads)
    return total


def hms(seconds):
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


# -------------------------------------------------------------------- machine
def part_record(args):
    """Provenance of this invocation (one part of a run made in parts)."""
    return {"date": M.now(), "git_revision": M.git_revision() or "unknown",
            "git_dirty": M.git_dirty(), "bench": M.relative_to_repo(args.bench),
            "bench_sha256": M.sha256(args.bench), "max_n": args.max_n, "only": args.only,
            "machine": M.machine_identity(), "loadavg_start": M.loadavg(), "loadavg_end": None}


def read_machine(path):
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
        return old if isinstance(old, dict) else None
    except (OSError, ValueError):
        return None


def earlier_parts(old):
    """The parts recorded in an existing machine.json (older files: `earlier`
    plus the top level)."""
    if not old:
        return []
    if "parts" in old:
        parts = [dict(p) for p in old["parts"]]
    else:
        keys = ("date", "git_revision", "git_dirty", "max_n", "bench", "bench_sha256")
        parts = list(old.get("earlier", [])) + [{k: old.get(k) for k in keys}]
    # Files written before parts recorded their machine: the top level
    # describes the machine of the last part (machine_record), and only that.
    if parts and not parts[-1].get("machine") and old.get("cpu_model"):
        parts[-1]["machine"] = M.machine_identity(old)
    return parts


def machine_record(args, part, parts_before, forced):
    """machine.json: this machine, this part at the top level, every part in
    `parts` (the report lists the earlier ones from `earlier`)."""
    info = {"run_id": args.run_id, "size": args.size, **M.machine_info(),
            **{k: part[k] for k in ("date", "git_revision", "git_dirty", "bench", "bench_sha256",
                                    "max_n", "loadavg_start", "loadavg_end")},
            "forced_merge": bool(forced) or any(p.get("forced_merge") for p in parts_before),
            "forced_merge_reason": forced or next((p.get("forced_merge_reason") for p in parts_before
                                                   if p.get("forced_merge")), None),
            "pinning": {k: os.environ.get(k, v) for k, v in PINNING.items()},
            "parts": parts_before + [part]}
    if parts_before:
        info["earlier"] = parts_before
    return info


# ------------------------------------------------------------------- running
def restrict_particles(exp, size, keep):
    """`exp` with its sweep's N limited to those for which keep(n) is true
    (unchanged when the sweep has no N axis)."""
    sweep = exp["sweep"].get(size, {})
    if "particles" not in sweep:
        return exp
    out = copy.deepcopy(exp)
    out["sweep"][size]["particles"] = [n for n in sweep["particles"] if keep(n)]
    out["_restricted"] = True  # its sweep is not the file's: the bench gets a copy
    return out


def bench_env(args):
    """Environment of the bench: OpenMP pinning (PINNING), and for a .py
    stand-in (tests/python/fake_bench.py) the repository root on PYTHONPATH,
    since it imports the harness package."""
    env = dict(os.environ)
    for key, value in PINNING.items():
        env.setdefault(key, value)
    if args.bench.suffix == ".py":
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    return env


def launcher(path):
    """The command that starts binary `path`: a .py stand-in
    (tests/python/fake_bench.py) through this interpreter."""
    return [sys.executable, str(path)] if pathlib.Path(path).suffix == ".py" else [str(path)]


def check_builds(args, experiments):
    """The revision each binary these experiments run was built from, refused
    (RunError) where it is not this checkout's code (M.build_mismatch): a
    bench left over from before a commit or a checkout would measure other
    code under this revision's name. --allow-other-build REASON measures
    anyway and records the reason, which the report shows."""
    binaries = [("bench", args.bench, "--revision")]
    families = {exp["benchmark"] for exp in experiments}
    if "counters" in families:
        binaries.append(("counters bench", args.counters_bench, "--revision"))
    if "mpi" in families:
        binaries.append(("sphnl", args.sphnl, "--version"))
    builds = {}
    for what, path, flag in binaries:
        if not pathlib.Path(path).is_file():
            continue  # its own runner says so when it is needed
        rev = M.binary_revision(launcher(path) + [flag], env=bench_env(args))
        builds[what] = rev
        if rev is None:
            print(f"warning: the {what} {path} does not report the revision it was built from; "
                  "its results cannot be tied to this checkout's code", file=sys.stderr)
            continue
        why = M.build_mismatch(rev)
        if why and not args.allow_other_build:
            raise RunError(f"the {what} {path} does not measure this checkout's code: {why}. Rebuild it "
                           "(make build; make counters-build for the counters bench), or pass "
                           "--allow-other-build REASON to measure it anyway (the report shows the reason)", 2)
        if why:
            print(f"warning: measuring with the {what} although {why} (--allow-other-build)", file=sys.stderr)
            builds["other_build_reason"] = f"{args.allow_other_build} ({what}: {why})"
    return builds


def validate_experiments(args, experiments):
    """Every experiment file checked by the bench's own schema (sphnl_bench
    --validate: unknown or duplicate keys, wrong types, values out of range,
    with file:line:col) before any benchmark runs, so a misspelt axis cannot
    run and be saved under the wrong labels."""
    base = launcher(args.bench)
    for exp in experiments:
        path = REPO / "experiments" / (exp["id"] + ".json")
        try:
            out = subprocess.run(base + [f"--experiment={path}", f"--size={args.size}", "--validate"],
                                 capture_output=True, text=True, timeout=60, cwd=REPO, env=bench_env(args))
        except (OSError, subprocess.TimeoutExpired) as e:
            raise RunError(f"cannot validate {path.name} with {args.bench}: {e}", 2) from None
        if out.returncode != 0:
            raise RunError(f"{path.name} is not a valid experiment file; nothing was run:\n  "
                           + "\n  ".join((out.stderr or out.stdout).strip().splitlines()[:10]), 2)


def bench_command(args, exp, out_tmp, exp_file, reps):
    """One round: every configuration `reps` times, repetitions randomly
    interleaved across configurations, one discarded warm-up each."""
    base = launcher(args.bench)
    return base + [
        f"--experiment={exp_file}",
        f"--size={args.size}",
        f"--cache-dir={args.cache_dir}",
        f"--benchmark_out={out_tmp}",
        "--benchmark_out_format=json",
        f"--benchmark_repetitions={reps}",
        "--benchmark_enable_random_interleaving=true",
        WARMUP_FLAG,
        "--benchmark_min_time=0",
    ]


def resume_plan(args, exp, out_path):
    """(experiment to run, earlier document or None): when out_path holds some
    but not all N of the sweep, only the missing N are run; the earlier
    document's entries for the other N (and their rounds) are kept."""
    if args.force or not out_path.exists() or "particles" not in exp["sweep"][args.size]:
        return exp, None
    try:
        doc = R.read_benchmark_json(out_path)
        missing = R.missing_in(doc, exp, args.size)
    except R.ResultsError:
        return exp, None
    rerun = {R.parse_run_name(name)[1]["particles"] for name in missing}

    def n_of(entry):
        family, params = R.parse_run_name(entry.get("run_name", entry.get("name", "")))
        return params.get("particles") if family == exp["benchmark"] else None
    doc["benchmarks"] = [b for b in doc["benchmarks"] if n_of(b) not in (None, *rerun)
                         and b.get("run_type", "iteration") == "iteration"]
    if not doc["benchmarks"]:
        return exp, None
    print(f"  {exp['id']}: keeping {len(doc['benchmarks'])} entries of {out_path.name}; running only "
          f"N = {', '.join(str(n) for n in sorted(rerun))}", flush=True)
    return restrict_particles(exp, args.size, lambda n: n in rerun), doc


class Bench:
    """One bench process (a round): started, its stdout counted for progress,
    its stderr tail kept for the error message, the seconds it spent
    developing snapshots summed."""

    def __init__(self, args, cmd, family, on_line):
        self.tail = collections.deque(maxlen=30)
        self.snapshot_s = 0.0
        try:
            self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                         bufsize=1, cwd=REPO, env=bench_env(args))
        except OSError as e:
            raise RunError(f"cannot start {args.bench}: {e}", 2) from None
        self.args, self.family, self.on_line = args, family, on_line

    def wait(self):
        def pump_stderr():  # keep a tail; show the bench's own messages (snapshots)
            for line in self.proc.stderr:
                self.tail.append(line.rstrip("\n"))
                developed = SNAPSHOT_DEVELOPED.match(line)
                if developed:
                    self.snapshot_s += float(developed.group(1))
                if self.args.verbose or line.startswith("sphnl_bench"):
                    print("  | " + line.rstrip("\n"), file=sys.stderr, flush=True)
        reader = threading.Thread(target=pump_stderr, daemon=True)
        reader.start()
        for line in self.proc.stdout:
            if self.args.verbose:
                print("  > " + line.rstrip("\n"), flush=True)
            token = (line.split() or [""])[0]
            if token.startswith(self.family + "/") and not AGGREGATE.search(token):
                self.on_line()
        rc = self.proc.wait()
        reader.join(timeout=5)
        return rc

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def measuring_seconds(elapsed, rounds):
    """The seconds of `elapsed` the rounds spent measuring, which the budget
    and the next round's length count: a snapshot developed inside a round
    (once per N and flow state, minutes at 10^5-10^6 particles) would
    otherwise spend the budget of a short experiment before its second round."""
    return max(0.0, elapsed - sum(r.get("snapshot_s") or 0.0 for r in rounds))


def run_round(args, exp, k, offset, reps, exp_file, tmp, progress):
    """Round k of `exp`: (iteration entries tagged sphnl_round = offset + k,
    the bench's JSON context, the round's record for `sphnl_rounds`)."""
    threads = max(exp["sweep"][args.size].get("threads", [1]))
    probe = M.NoiseProbe(threads)
    bench = Bench(args, bench_command(args, exp, tmp, exp_file, reps), exp["benchmark"], progress)
    try:
        rc = bench.wait()
    finally:  # on any failure or Ctrl-C: no bench left running
        bench.kill()
    noise = probe.finish(bench_env(args))
    if rc != 0:
        raise RunError(f"{exp['id']}: {args.bench} exited with status {rc} in round {k + 1}; nothing "
                       "saved.\nLast lines of its stderr:\n  " + "\n  ".join(bench.tail or ["(empty)"]))
    try:
        doc = R.read_benchmark_json(tmp)
    except R.ResultsError as e:
        raise RunError(f"{exp['id']}: the bench exited 0 but its output is unusable: {e}") from None
    entries = [b for b in doc["benchmarks"] if b.get("run_type", "iteration") == "iteration"]
    order, warmups = P.executed_order(entries)
    for e in entries:
        e["sphnl_round"] = offset + k
    record = {"round": offset + k, **noise, "order": order, "warmups_discarded": warmups,
              "snapshot_s": round(bench.snapshot_s, 1),
              "git_revision": args.part["git_revision"], "bench_sha256": args.part["bench_sha256"]}
    if record["cpu_mhz"] == [] and doc.get("context", {}).get("mhz_per_cpu"):
        record["cpu_mhz"] = [float(doc["context"]["mhz_per_cpu"])] * len(record["cpu_affinity"] or [1])
        record["cpu_mhz_source"] = "Google Benchmark context (nominal)"
    return entries, doc.get("context", {}), record


def run_experiment(args, exp, out_path, label):
    """Run one experiment round by round; its JSON appears at out_path only
    when complete. Returns the seconds its rounds took."""
    size, full_exp = args.size, exp
    exp, earlier = resume_plan(args, exp, out_path)
    proto = P.protocol_of(exp, size)
    configs, reps = len(R.sweep_points(exp, size)), proto["reps_per_round"]
    print(f"{label} {exp['id']}: {configs} configurations x {reps} repetitions per round, "
          f"{proto['min_rounds']}-{proto['max_rounds']} rounds (target +-{proto['target_halfwidth_pct']:g} %, "
          f"budget {hms(proto['budget_s'])}), {exp['window_steps'][size]} steps each "
          f"(model estimate {hms(estimate_seconds(exp, size))})", flush=True)
    tmp = out_path.with_name(f".{out_path.name}.partial")
    exp_file = REPO / "experiments" / (exp["id"] + ".json")
    if exp.get("_restricted"):  # the bench reads its sweep from a file: give it the restricted one
        exp_file = out_path.with_name(f".{exp['id']}.experiment.json")
        write_atomic(exp_file, json.dumps({k: v for k, v in exp.items() if k != "_restricted"},
                                          indent=1) + "\n")
    old_rounds = list(earlier.get("sphnl_rounds", [])) if earlier else []
    offset = 1 + max([r.get("round", -1) for r in old_rounds] + [-1]) if earlier else 0
    if earlier and not old_rounds:  # entries of an older harness: no round tag; one process
        offset = 1
    entries, rounds, context = [], [], {}
    start = time.monotonic()
    lines = [0]
    elapsed_rounds = [0.0]  # seconds of the rounds already done

    per_round_model = round_seconds(exp, size)

    def progress():
        # Google Benchmark reports a configuration when its last repetition
        # ends, and the interleaved repetitions of every configuration are
        # spread over the whole round, so most configurations report near
        # its end: a rate of reported configurations says nothing early in a
        # round. Rounds already done give the measured round time.
        lines[0] += 1
        done, per_round = lines[0], configs * reps
        if done % reps:
            return
        elapsed = time.monotonic() - start
        in_round = done - per_round * len(rounds)
        round_s = elapsed_rounds[0] / len(rounds) if rounds else per_round_model
        source = "measured" if rounds else "model"
        left_rounds = max(0, proto["min_rounds"] - len(rounds) - 1)
        eta = max(0.0, round_s - (elapsed - elapsed_rounds[0])) + left_rounds * round_s
        print(f"  {exp['id']}: round {len(rounds) + 1}, configurations reported {in_round // reps}/{configs} "
              f"(each reports when its last interleaved repetition ends), elapsed {hms(elapsed)}, "
              f"ETA {hms(eta)} ({source} round time {hms(round_s)}; more rounds if the target is not met)",
              flush=True)
    try:
        reason = None
        while reason is None:
            k = len(rounds)
            round_entries, context, record = run_round(args, exp, k, offset, reps, exp_file, tmp, progress)
            entries += round_entries
            rounds.append(record)
            elapsed = time.monotonic() - start
            elapsed_rounds[0] = elapsed
            measuring = measuring_seconds(elapsed, rounds)
            reason = P.stop_reason(P.metric_samples(entries, exp), proto, len(rounds), measuring,
                                   measuring / len(rounds))
            if record["under_load"]:
                print(f"  {exp['id']}: round {k + 1} ran under load (load average "
                      f"{record['loadavg_before']} -> {record['loadavg_after']}, others busy "
                      f"{record['other_busy_cores']} cores, steal {record['steal_pct']} %)", flush=True)
        kept = earlier["benchmarks"] if earlier else []
        for b in kept:  # entries of an older harness had one process: round 0
            b.setdefault("sphnl_round", 0)
        doc = {"context": context, "benchmarks": kept + entries,
               "sphnl_rounds": old_rounds + rounds,
               "sphnl_protocol": {"rounds": len(rounds), "reps_per_round": reps,
                                  "min_rounds": proto["min_rounds"], "max_rounds": proto["max_rounds"],
                                  "target_halfwidth_pct": proto["target_halfwidth_pct"],
                                  "budget_s": proto["budget_s"], "stop_reason": reason,
                                  "metric": exp.get("metric", "s_per_step"),
                                  "seconds": round(time.monotonic() - start, 1)}}
        if earlier:
            doc["context"]["sphnl_merged"] = (f"{len(kept)} entries kept from an earlier run "
                                              "of this experiment (other N)")
            doc["sphnl_protocol_earlier"] = ([earlier["sphnl_protocol"]] if "sphnl_protocol" in earlier
                                             else []) + earlier.get("sphnl_protocol_earlier", [])
        missing = R.missing_in(doc, full_exp, size)
        if missing:
            raise RunError(f"{exp['id']}: the bench output lacks {len(missing)} of "
                           f"{len(R.sweep_points(full_exp, size))} sweep points (names must follow "
                           "docs/CONTRACTS.md), e.g.\n  " + "\n  ".join(missing[:5]))
        write_atomic(out_path, json.dumps(doc, indent=2) + "\n")
    finally:  # on any failure or Ctrl-C: no partial JSON left
        tmp.unlink(missing_ok=True)
        if exp.get("_restricted"):
            exp_file.unlink(missing_ok=True)
    seconds = time.monotonic() - start
    print(f"  {exp['id']}: {len(rounds)} rounds ({reason}) in {hms(seconds)} -> {out_path}", flush=True)
    return seconds


def run_counters(args, exp, out_path, label):
    """A `counters` experiment (experiments/counters.py): one round of callgrind
    runs, no protocol; its errors end the run like a bench failure."""
    try:
        return CNT.run(args, exp, out_path, label, bench_env(args),
                       progress=lambda msg: print(msg, flush=True))
    except (CNT.CountersError, R.ResultsError) as e:
        raise RunError(str(e), 2) from None


def run_mpi(args, exp, out_path, label):
    """An `mpi` experiment (experiments/mpi_runs.py): `sphnl run` under
    mpirun, rounds of interleaved runs; its errors end the run like a bench failure."""
    try:
        return MPI.run(args, exp, out_path, label, bench_env(args), progress=lambda msg: print(msg, flush=True))
    except (MPI.MpiRunError, R.ResultsError) as e:
        raise RunError(str(e), 2) from None


def status(out_path, exp, size):
    """'complete', or why the experiment must (re)run."""
    if not out_path.exists():
        return "not run"
    try:
        missing = R.missing_points(out_path, exp, size)
    except R.ResultsError as e:
        return f"unreadable ({e})"
    return "complete" if not missing else f"incomplete ({len(missing)} sweep points missing)"


def has_results(out_dir):
    """Whether a run folder already holds an experiment's results."""
    return out_dir.is_dir() and any(p.name != "machine.json" and not p.name.startswith(".")
                                    for p in out_dir.glob("*.json"))


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
    p.add_argument("--counters-bench", type=pathlib.Path,
                   default=REPO / "build-counters/benchmarks/sphnl_bench",
                   help="the bench valgrind runs for the counters experiments (default: "
                        "build-counters/benchmarks/sphnl_bench, built by `make counters-build`)")
    p.add_argument("--sphnl", type=pathlib.Path, default=REPO / "build/sphnl",
                   help="the sphnl command the mpi experiments run (default: build/sphnl)")
    p.add_argument("--mpirun", default="mpirun", help="MPI launcher of the mpi experiments (default: mpirun)")
    p.add_argument("--valgrind", default="valgrind", help="valgrind executable (counters experiments)")
    p.add_argument("--counters-jobs", type=int, default=2,
                   help="valgrind processes at a time for the counters experiments (default 2; the "
                        "counts do not depend on the load)")
    p.add_argument("--only", help="comma-separated experiment ids (default: every experiment "
                                  "that draws a figure; a uses-only id runs its source)")
    p.add_argument("--force", action="store_true", help="rerun experiments already complete")
    p.add_argument("--skip-counters", action="store_true",
                   help="leave out the counters experiments (valgrind and `make counters-build`); "
                        "the report then marks what needs them 'not measured'")
    p.add_argument("--cache-dir", type=pathlib.Path,
                   help="snapshot cache passed to the bench (default: RESULTS_DIR/cache)")
    p.add_argument("--max-n", type=int, metavar="N",
                   help="leave out sweep points with more than N particles (a long FULL run in "
                        "parts: rerun later without it and only the missing N run)")
    p.add_argument("--force-merge", metavar="REASON",
                   help="add results to a run folder even though the code differs from its earlier "
                        "parts' (dirty tree, other revision or bench binary); REASON is recorded in "
                        "machine.json and shown in the report")
    p.add_argument("--allow-other-build", metavar="REASON",
                   help="measure with a bench (or sphnl) built from other code than this checkout's "
                        "(another revision whose code differs, or uncommitted changes on one side); "
                        "REASON is recorded in machine.json and shown in the report")
    p.add_argument("--dry-run", action="store_true",
                   help="print the plan and the model time estimate, run nothing")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="echo the bench command, its stdout and stderr")
    args = p.parse_args(argv)
    if args.force_merge is not None and not args.force_merge.strip():
        p.error("--force-merge needs a reason (it is shown in the report), e.g. "
                "--force-merge 'comment-only change between the parts'")
    if args.allow_other_build is not None and not args.allow_other_build.strip():
        p.error("--allow-other-build needs a reason (it is shown in the report), e.g. "
                "--allow-other-build 'bench of the previous commit, only a comment changed'")
    if args.max_n is not None and args.max_n < 1:
        p.error(f"--max-n must be a positive particle count, not {args.max_n}")
    args.run_id = args.run_id or args.size
    args.cache_dir = (args.cache_dir or args.results_dir / "cache").resolve()
    args.bench = args.bench.resolve() if args.bench.exists() else args.bench
    args.counters_bench = args.counters_bench.resolve() if args.counters_bench.exists() else args.counters_bench
    args.sphnl = args.sphnl.resolve() if args.sphnl.exists() else args.sphnl
    args.repo, args.step_seconds = REPO, step_seconds
    return args


def main(argv=None):
    args = parse_args(argv)
    try:
        experiments = R.load_experiments(REPO / "experiments")
        chosen = select(experiments, args.only)
        if args.skip_counters:
            chosen = [e for e in chosen if e["benchmark"] != "counters"]
        if args.max_n is not None:
            capped = [restrict_particles(e, args.size, lambda n: n <= args.max_n) for e in chosen]
            for e in capped:
                if "particles" in e["sweep"][args.size] and not e["sweep"][args.size]["particles"]:
                    print(f"{e['id']}: no sweep point with N <= {args.max_n}, left out")
            chosen = [e for e in capped if e["sweep"][args.size].get("particles", True)]
        out_dir = args.results_dir / args.run_id
        plan = []
        for exp in chosen:
            out = out_dir / f"{exp['id']}.json"
            state = status(out, exp, args.size)
            plan.append((exp, out, state if args.force or state != "complete" else None))
        todo = [(exp, out) for exp, out, why in plan if why]
        for exp, out, why in plan:
            print(f"{exp['id']}: {'run (' + why + ')' if why else 'complete, skipped (--force reruns)'}")
        for exp, _ in todo:
            if exp["benchmark"] == "counters":
                print(f"  {exp['id']}: {estimate_seconds(exp, args.size):.0f} s under valgrind, one process at a "
                      f"time (--counters-jobs {args.counters_jobs} divides it), one round: counts are deterministic")
                continue
            rounds = P.protocol_of(exp, args.size)
            print(f"  {exp['id']}: {round_seconds(exp, args.size):.0f} s per round x "
                  f"{rounds['min_rounds']}-{rounds['max_rounds']} rounds (budget {hms(rounds['budget_s'])})")
        total = sum(estimate_seconds(e, args.size) for e, _ in todo)
        snaps = snapshot_seconds([e for e, _ in todo], args.size, args.cache_dir)
        most = sum(most_seconds(e, args.size) for e, _ in todo)
        print(f"{len(todo)} of {len(plan)} experiments to run, model estimate {hms(total + snaps)} "
              f"({hms(total)} at the minimum rounds + {hms(snaps)} developing missing snapshots; "
              f"at most {hms(most + snaps)} if every experiment adds rounds to its budget)", flush=True)
        if args.dry_run or not todo:
            return 0
        if not (args.bench.is_file() and os.access(args.bench, os.X_OK)):
            raise RunError(f"benchmark binary {args.bench} not found or not executable; "
                           "build it first with `make build`", 2)
        validate_experiments(args, [exp for exp, _ in todo])
        machine_path = out_dir / "machine.json"
        args.part = part_record(args)
        args.part["builds"] = check_builds(args, [exp for exp, _ in todo])
        old = read_machine(machine_path)
        before = earlier_parts(old) if has_results(out_dir) else []
        refusal = M.merge_refusal(before, args.part) if before else None
        if refusal and not args.force_merge:
            raise RunError(f"{out_dir} already holds results of other code: {refusal}, or pass "
                           "--force-merge REASON (make reproduce FORCE_MERGE=REASON) to merge "
                           "anyway, which the report shows", 2)
        forced = args.force_merge if refusal else None
        if forced:
            args.part.update(forced_merge=True, forced_merge_reason=f"{forced} ({refusal})")
            print(f"warning: merging into {out_dir} although {refusal} (--force-merge)", file=sys.stderr)
            forced = args.part["forced_merge_reason"]
        out_dir.mkdir(parents=True, exist_ok=True)

        def save_machine():
            write_atomic(machine_path, json.dumps(machine_record(args, args.part, before, forced),
                                                  indent=2) + "\n")
        save_machine()
        start, modelled, measured = time.monotonic(), 0.0, 0.0
        try:
            for k, (exp, out) in enumerate(todo, 1):
                if modelled:  # the model scaled by how fast this machine has measured so far
                    left = sum(estimate_seconds(e, args.size) for e, _ in todo[k - 1:])
                    print(f"overall: {k - 1}/{len(todo)} experiments done in "
                          f"{hms(time.monotonic() - start)}, about {hms(left * measured / modelled)} "
                          "left at the rate measured so far", flush=True)
                if exp["benchmark"] == "counters":
                    measured += run_counters(args, exp, out, f"[{k}/{len(todo)}]")
                elif exp["benchmark"] == "mpi":
                    measured += run_mpi(args, exp, out, f"[{k}/{len(todo)}]")
                else:
                    measured += run_experiment(args, exp, out, f"[{k}/{len(todo)}]")
                modelled += estimate_seconds(exp, args.size)
        finally:
            args.part["loadavg_end"] = M.loadavg()
            args.part["ended"] = M.now()
            save_machine()
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
