"""The `counters` benchmark kind (docs/CONTRACTS.md §1-3): instructions and
simulated cache misses per particle-step, in total and per phase of Table I,
counted by callgrind inside the timed window of sphnl_bench.

experiments/run.py calls `run` for every experiment whose `benchmark` is
`counters`. Each configuration of the sweep runs in its own valgrind process
(the step window of the `step` kind: a warm-up window, discarded as in the
timed benchmarks, then the measured window, both from the cached snapshot of
the developed flow), with the caches of its `cache_model` axis
(harness/valgrind.py: `this_machine`, `nehalem_2010`). The counts repeat
exactly, so every configuration is measured once, in one round; the
processes run `--counters-jobs` at a time, since the load of the machine
does not enter the counts.

The bench must be a build valgrind 3.19 can execute (no AVX-512):
`make counters-build` (build-counters/). Snapshots are developed first by a
native run of that bench (valgrind would take hours to develop a flow).
"""
import concurrent.futures
import hashlib
import json
import os
import pathlib
import queue
import shutil
import subprocess
import time

from harness import machine as M
from harness import results as R
from harness import valgrind as V
from harness.fsio import write_atomic

FAMILY = "counters"
# GB 1.7.1 runs one discarded warm-up call of each benchmark with this flag,
# exactly as experiments/run.py times the `step` kind.
WARMUP_FLAG = "--benchmark_min_warmup_time=0.000001"
WINDOWS_PER_RUN = 2  # the warm-up window, then the measured one
# Counters of the bench's own JSON kept in a counters entry (those that do not
# depend on time; the bench's seconds under valgrind mean nothing).
KEPT = ("n_particles", "n_fluid", "window_steps", "rebuilds", "mean_steps_per_list", "max_steps_per_list",
        "candidates_per_particle", "interactions_per_particle", "nl_bytes", "list_bytes",
        "forced_rebuilds", "skin_over_h", "snapshot_time", "list_pairs_built_per_particle_step")
# result field prefix -> callgrind events summed (--cache-sim=yes event names)
EVENTS = {"ir": ("Ir",), "d1_misses": ("D1mr", "D1mw"), "ll_misses": ("DLmr", "DLmw")}
TOTAL_ONLY = {"i1_misses": ("I1mr",), "ll_instr_misses": ("ILmr",)}
# glibc raises its mmap threshold when a large block is freed (the warm-up's
# Simulation), so where the measured window's arrays land, hence their cache
# sets, would depend on the history of the process; fixed at glibc's initial
# 128 KiB the layout repeats from run to run (measured: D1 and LL counts
# identical in two processes, where they differed by up to 20x in LL before).
MALLOC_TUNABLE = "glibc.malloc.mmap_threshold=131072"
# valgrind's callgrind with cache simulation runs the step about this many
# times slower than native (measured here: docs/MEASUREMENT.md), for the plan.
SLOWDOWN = 120.0
START_S = 4.0  # valgrind start, snapshot load under instrumentation


class CountersError(Exception):
    """The counts cannot be made; the message says why and what to do."""


def counter_fields(profile, particle_steps):
    """The per-particle-step fields of one measured window's Profile:
    `<event>_per_particle_step`, `<event>_<phase>_per_particle_step` for
    ir, d1_misses, ll_misses and each phase of Table I, and window totals."""
    out = {}
    for name, events in EVENTS.items():
        total = sum(profile.total(e) for e in events)
        out[f"{name}_total"] = total
        out[f"{name}_per_particle_step"] = total / particle_steps
        for phase, functions in V.PHASE_FUNCTIONS.items():
            out[f"{name}_{phase}_per_particle_step"] = \
                sum(profile.of(functions, e) for e in events) / particle_steps
    for name, events in TOTAL_ONLY.items():
        out[f"{name}_per_particle_step"] = sum(profile.total(e) for e in events) / particle_steps
    # What the three phases leave out (step bookkeeping, the memory samples
    # of timed_window): a check that the phase functions were found.
    covered = sum(out[f"ir_{p}_per_particle_step"] for p in V.PHASE_FUNCTIONS)
    out["ir_phase_coverage"] = covered / out["ir_per_particle_step"] if out["ir_per_particle_step"] else 0.0
    return out


def entry(name, bench_entry, profile, model, seconds):
    """The results entry (Google-Benchmark-shaped, docs/CONTRACTS.md §3) of one configuration."""
    n, steps = bench_entry.get("n_particles"), bench_entry.get("window_steps")
    if not n or not steps:
        raise CountersError(f"{name}: the bench's JSON lacks the n_particles / window_steps counters")
    fields = counter_fields(profile, float(n) * float(steps))
    if fields["ir_phase_coverage"] < 0.5:
        raise CountersError(f"{name}: the phase functions {sum(V.PHASE_FUNCTIONS.values(), ())} hold only "
                            f"{100 * fields['ir_phase_coverage']:.0f} % of the window's instructions: were "
                            "they inlined? (they are [[gnu::noinline]] in core/src/simulation.cpp)")
    out = {"name": name, "run_name": name, "run_type": "iteration", "repetitions": 1,
           "repetition_index": 0, "threads": 1, "iterations": 1, "real_time": seconds,
           "cpu_time": seconds, "time_unit": "s", "sphnl_round": 0}
    out.update({k: bench_entry[k] for k in KEPT if k in bench_entry})
    out.update(fields)
    out.update(per_pair_built(fields, bench_entry.get("list_pairs_built_per_particle_step")))
    out.update(model.fields())
    return out


def per_pair_built(fields, pairs_built_per_particle_step):
    """`<event>_neighbour_list_per_pair_built`: the list phase's counts per
    pair the Verlet-list builds stored, so that builds of lists of different
    lengths (N, skin) compare per unit of work. {} for CLL (no list) and for
    benches older than the `list_pairs_built_per_particle_step` counter."""
    if not pairs_built_per_particle_step:
        return {}
    return {f"{name}_neighbour_list_per_pair_built":
            fields[f"{name}_neighbour_list_per_particle_step"] / pairs_built_per_particle_step
            for name in EVENTS}


def _stem(name):
    """A fixed-length file stem per configuration (see valgrind_env: every
    argument of a valgrind run has the same length whatever the folders)."""
    return "cg-" + hashlib.sha256(name.encode()).hexdigest()[:16]


# Variables a valgrind run inherits from the caller's environment; the rest
# is dropped (see valgrind_env).
KEPT_ENV_PREFIXES = ("OMP_", "GOMP_", "SPHNL_MEMORY_AVAILABLE")


def valgrind_env(env):
    """The environment of a valgrind run, the same whoever starts it.

    Which cache sets the data fall in depends on where they lie, and a
    process's stack starts below its environment and arguments: one more
    variable of 20 bytes moved the stack and changed the simulated D1 misses
    by 0.25 % here (docs/MEASUREMENT.md). So the run gets a fixed minimal
    environment (OpenMP settings, a fixed PATH and locale, glibc's mmap
    threshold), starts in its work folder with the same relative paths
    (experiment.json, cache/, the bench as ./bench: links there), and runs
    without address-space randomisation where setarch allows it."""
    out = {k: v for k, v in env.items() if k.startswith(KEPT_ENV_PREFIXES)}
    out.update({"PATH": "/usr/bin:/bin", "LC_ALL": "C", "GLIBC_TUNABLES": MALLOC_TUNABLE})
    return dict(sorted(out.items()))


def no_aslr_prefix():
    """['setarch', '-R'] where it works here (a container may forbid the
    personality call), else []."""
    setarch = shutil.which("setarch")
    if setarch is None:
        return []
    try:
        ok = subprocess.run([setarch, "-R", "true"], capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        ok = False
    return [setarch, "-R"] if ok else []


def bench_command(bench, exp_file, size, cache_dir, out_file, name=None, warmup=True):
    cmd = [str(bench), f"--experiment={exp_file}", f"--size={size}", f"--cache-dir={cache_dir}",
           f"--benchmark_out={out_file}", "--benchmark_out_format=json",
           "--benchmark_repetitions=1", "--benchmark_min_time=0"]
    if name is not None:
        cmd.append(f"--benchmark_filter={V.gb_filter(name)}")
    if warmup:
        cmd.append(WARMUP_FLAG)
    return cmd


def _run(cmd, log, env, cwd):
    with open(log, "a") as f:
        f.write("$ " + " ".join(cmd) + "\n")
        f.flush()
        proc = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, env=env, cwd=cwd)
    if proc.returncode != 0:
        tail = "\n  ".join(pathlib.Path(log).read_text(errors="replace").splitlines()[-15:])
        raise CountersError(f"exit status {proc.returncode} of\n  {' '.join(cmd)}\nlast lines of {log}:\n  {tail}")


def cpu_slots():
    """A queue of the CPUs this process may run on, one per concurrent
    valgrind job. Each job runs on a CPU of its own (cpu_prefix): under the
    bench's OpenMP pinning (OMP_PROC_BIND=close) every one-thread process
    binds itself to the first CPU it is allowed, so two jobs started alike
    shared one core and each ran at half speed."""
    slots = queue.Queue()
    for cpu in sorted(os.sched_getaffinity(0)):
        slots.put(cpu)
    return slots


def cpu_prefix(cpu):
    """`taskset -c CPU` (util-linux) where it exists: the job's allowed CPUs,
    set before the bench starts, so that OpenMP binds it there. The counts
    are those of an unpinned run to the last instruction (CountsRepeat runs
    one of each). They once differed by about 1e-3: the bench keyed its
    snapshot by the CPUs it was allowed, so a pinned job developed a flow
    of its own, on one thread, under valgrind (benchmarks/bench_common.cpp,
    development_threads). One job at a time runs without it, as always."""
    taskset = shutil.which("taskset")
    return [taskset, "-c", str(cpu)] if taskset and cpu is not None else []


def count_one(name, model, *, valgrind, size, work, env, prefix, cpus=None):
    """(entry, bench context) of one configuration under callgrind, run in
    `work` (which holds the links experiment.json, cache and bench), started
    through `prefix` (no_aslr_prefix) on a CPU taken from the queue `cpus`
    for the run (cpu_slots)."""
    cpu = cpus.get() if cpus is not None else None
    try:
        return _count_one(name, model, valgrind=valgrind, size=size, work=work, env=env,
                          prefix=cpu_prefix(cpu) + prefix)
    finally:
        if cpu is not None:
            cpus.put(cpu)


def _count_one(name, model, *, valgrind, size, work, env, prefix):
    stem = _stem(name)
    cg_out, gb_out, log = (work / f"{stem}{s}" for s in (".out", ".json", ".log"))
    for old in V.dump_files(cg_out) + [cg_out, gb_out, log]:
        old.unlink(missing_ok=True)
    cmd = prefix + V.callgrind_command(valgrind, f"{stem}.out",
                                        bench_command("./bench", "experiment.json", size, "cache",
                                                      f"{stem}.json", name),
                                        cache=model, dump_per_window=True)
    start = time.monotonic()
    _run(cmd, log, valgrind_env(env), work)
    return collect(name, model, work, time.monotonic() - start)


def collect(name, model, work, seconds):
    """(entry, bench context) from the files a finished valgrind run of
    `name` left in `work`: its two window dumps and the bench's JSON."""
    stem = _stem(name)
    cg_out, gb_out, log = (work / f"{stem}{s}" for s in (".out", ".json", ".log"))
    dumps = V.dump_files(cg_out)
    if len(dumps) != WINDOWS_PER_RUN:
        raise CountersError(f"{name}: callgrind wrote {len(dumps)} window dumps, expected {WINDOWS_PER_RUN} "
                            f"(a warm-up and the measured window; does {V.TIMED_SIGNATURE} still name the "
                            f"function of benchmarks/bench_common.hpp?); log: {log}")
    profile = V.parse_callgrind(dumps[-1].read_text(errors="replace"), str(dumps[-1]))
    doc = R.read_benchmark_json(gb_out)
    found = [b for b in doc["benchmarks"] if b.get("run_type", "iteration") == "iteration"
             and b.get("run_name", b["name"]) == name]
    if len(found) != 1 or found[0].get("error_occurred"):
        raise CountersError(f"{name}: the bench did not report exactly one successful entry "
                            f"({found[0].get('error_message') if found else 'none'}); log: {log}")
    return entry(name, found[0], profile, model, seconds), doc.get("context", {})


# A configuration counted in a run that did not finish is kept in the work
# folder as <stem>.done.json, with what makes its counts: the next run of the
# same experiment reuses it instead of counting it again (a 300 000-particle
# window takes over an hour of valgrind).
DONE_SUFFIX = ".done.json"


def done_key(name, model, size, window_steps, bench_sha256):
    """What a kept count must match to be reused: the configuration, the size
    and window, the simulated caches and the bench binary."""
    return {"name": name, "size": size, "window_steps": window_steps, "cache": model.options(),
            "bench_sha256": bench_sha256}


def keep_done(work, key, entry_, context):
    write_atomic(work / (_stem(key["name"]) + DONE_SUFFIX),
                 json.dumps({"key": key, "entry": entry_, "context": context}, indent=1) + "\n")


def load_done(work, key):
    """(entry, context) of a kept count of `key`, or None (none kept, or kept
    for another binary, size, window or cache)."""
    try:
        kept = json.loads((work / (_stem(key["name"]) + DONE_SUFFIX)).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return (kept["entry"], kept["context"]) if kept.get("key") == key else None


def prepare_work(work):
    """The work folder of a run: kept counts (DONE_SUFFIX) stay, everything
    else of an earlier run goes."""
    work.mkdir(parents=True, exist_ok=True)
    for f in work.iterdir():
        if f.name.endswith(DONE_SUFFIX):
            continue
        if f.is_dir() and not f.is_symlink():
            shutil.rmtree(f)
        else:
            f.unlink()


def valgrind_version(valgrind):
    try:
        return subprocess.run([valgrind, "--version"], capture_output=True, text=True,
                              timeout=30).stdout.strip() or None
    except OSError:
        return None


def check(exp, size, args):
    """Refusals before anything runs: valgrind missing, the bench missing,
    a sweep with more than one thread (callgrind serialises threads and
    would count only the main one inside the toggled function)."""
    points = R.sweep_points(exp, size)
    bad = sorted({p.get("threads") for p in points if p.get("threads") != 1})
    if bad:
        raise CountersError(f"experiments/{exp['id']}.json: the counters kind counts one thread only "
                            f"(callgrind toggles counting per thread); threads {bad} are not allowed, use [1]")
    for p in points:
        V.cache_model(p["cache_model"])  # an unknown model or unreadable caches fail here
    if shutil.which(args.valgrind) is None:
        raise CountersError(f"valgrind not found ('{args.valgrind}'): install it (apt-get install valgrind, "
                            "or make deps) to run the counters experiments, or leave them out with --only")
    bench = pathlib.Path(args.counters_bench)
    if not (bench.is_file() and os.access(bench, os.X_OK)):
        raise CountersError(f"counters bench {bench} not found: build it with `make counters-build` "
                            "(an x86-64-v3 build with debug symbols: valgrind 3.19 cannot run AVX-512 code)")
    return points


def estimate_seconds(exp, size, step_seconds):
    """Model of the experiment's time with `jobs` = 1: per configuration the
    valgrind start plus two windows (warm-up, measured) at SLOWDOWN."""
    window = exp["window_steps"][size]
    return sum(START_S + WINDOWS_PER_RUN * window * step_seconds(p) * SLOWDOWN
               for p in R.sweep_points(exp, size))


def run(args, exp, out_path, label, env, progress=print):
    """Count every configuration of `exp` into out_path (written only when
    complete). A run that stops keeps the configurations it counted in its
    work folder, and the next run with the same bench reuses them (recorded
    as kept_from_earlier_run). Returns the seconds it took."""
    size = args.size
    try:
        points = check(exp, size, args)
    except (CountersError, V.ValgrindError) as e:
        raise CountersError(f"{exp['id']}: {e}") from None
    names = [R.format_run_name(FAMILY, p) for p in points]
    models = {p["cache_model"]: V.cache_model(p["cache_model"]) for p in points}
    jobs = max(1, args.counters_jobs)
    progress(f"{label} {exp['id']}: {len(points)} configurations under callgrind (cache simulation), "
             f"{jobs} at a time, one round (counts are deterministic), {exp['window_steps'][size]} steps "
             f"per window (model estimate {estimate_seconds(exp, size, args.step_seconds) / jobs / 60:.0f} min)")
    exp_file = (pathlib.Path(args.repo) / "experiments" / f"{exp['id']}.json").resolve()
    work = out_path.with_name(f".{exp['id']}.counters")
    prepare_work(work)
    pathlib.Path(args.cache_dir).mkdir(parents=True, exist_ok=True)
    (work / "experiment.json").symlink_to(exp_file)
    (work / "cache").symlink_to(pathlib.Path(args.cache_dir).resolve())
    started, start = M.now(), time.monotonic()
    entries, context = {}, {}
    try:
        # Snapshots first, natively: the same bench, every configuration once, no valgrind.
        progress(f"  {exp['id']}: developing or loading the snapshots with a native run of {args.counters_bench}")
        _run(bench_command(pathlib.Path(args.counters_bench).resolve(), "experiment.json", size, "cache",
                           "native.json", warmup=False), work / "native.log", env, work)
        (work / "bench").symlink_to(pathlib.Path(args.counters_bench).resolve())
        common = dict(valgrind=shutil.which(args.valgrind), size=size, work=work, env=env,
                      prefix=no_aslr_prefix(), cpus=cpu_slots() if jobs > 1 else None)
        bench_sha = M.sha256(args.counters_bench)
        keys = {name: done_key(name, models[p["cache_model"]], size, exp["window_steps"][size], bench_sha)
                for name, p in zip(names, points)}
        for name in names:
            kept = load_done(work, keys[name])
            if kept:
                entries[name], context = kept
        if entries:
            progress(f"  {exp['id']}: {len(entries)} of {len(names)} configurations kept from an earlier "
                     f"run that did not finish (same bench, size, window and caches); counting the rest")
        kept_names = sorted(entries)
        todo = [(name, p) for name, p in zip(names, points) if name not in entries]
        with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(count_one, name, models[p["cache_model"]], **common): name for name, p in todo}
            for done, future in enumerate(concurrent.futures.as_completed(futures), 1):
                name = futures[future]
                entries[name], context = future.result()
                keep_done(work, keys[name], entries[name], context)
                elapsed = time.monotonic() - start
                progress(f"  {exp['id']}: {done}/{len(todo)} counted ({name}), elapsed "
                         f"{elapsed / 60:.1f} min, ETA {elapsed / done * (len(todo) - done) / 60:.1f} min")
        seconds = time.monotonic() - start
        context = dict(context, sphnl_counters_valgrind=valgrind_version(args.valgrind) or "unknown",
                       sphnl_counters_tool="callgrind --cache-sim=yes, counting inside "
                                           f"{V.TIMED_FUNCTION}, the window after one warm-up window")
        for model in models.values():
            context[f"sphnl_cache_model_{model.name}"] = f"{' '.join(model.options())} ({model.note})"
        record = {"round": 0, "started": started, "ended": M.now(), "order": names,
                  "warmups_discarded": len(names), "under_load": False,
                  # configurations counted by an earlier run of the same
                  # bench that did not finish (DONE_SUFFIX), reused
                  "kept_from_earlier_run": kept_names,
                  "deterministic": "callgrind counts do not depend on the machine's load",
                  # the revision the part started from (machine.json), not
                  # the checkout's at the end: commits made during an hour of
                  # valgrind do not change what was counted
                  "git_revision": getattr(args, "part", {}).get("git_revision") or M.git_revision(),
                  "bench": M.relative_to_repo(args.counters_bench),
                  "bench_sha256": bench_sha,
                  "valgrind": context["sphnl_counters_valgrind"]}
        doc = {"context": context, "benchmarks": [entries[n] for n in names], "sphnl_rounds": [record],
               "sphnl_protocol": {"rounds": 1, "reps_per_round": 1, "min_rounds": 1, "max_rounds": 1,
                                  "stop_reason": "deterministic counts: one round",
                                  "metric": exp.get("metric", "ll_misses_per_particle_step"),
                                  "seconds": round(seconds, 1)}}
        missing = R.missing_in(doc, exp, size)
        if missing:
            raise CountersError(f"{exp['id']}: {len(missing)} configurations were not counted, e.g. {missing[0]}")
        write_atomic(out_path, json.dumps(doc, indent=2) + "\n")
    except BaseException:
        progress(f"  {exp['id']}: {len(entries)} of {len(names)} configurations counted are kept in {work} "
                 "for the next run of this experiment")
        raise
    shutil.rmtree(work, ignore_errors=True)
    progress(f"  {exp['id']}: {len(names)} configurations counted in {seconds / 60:.1f} min -> {out_path}")
    return seconds
