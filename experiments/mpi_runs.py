"""The `mpi` benchmark kind (docs/CONTRACTS.md §1-3): `sphnl run` on P ranks
(mpirun) of T OpenMP threads each, timed by the run's own phase timers.

experiments/run.py calls `run` for every experiment whose `benchmark` is
`mpi`. A sweep point (`particles`, `list`, `list_steps`, `ranks`, `threads`,
optionally `balance_by`, run once on one rank; the top-level `max_cores`
leaves out the layouts with ranks x threads above it) is one process group: `mpirun -np P sphnl run` (no launcher for P = 1)
of `window_steps` steps from t = 0, no output but summary.json. Its entry
holds the slowest rank's seconds per step in each phase, the communication
share of the step, the bytes sent and the ghosts per rank.

The protocol is the timed kinds' (docs/MEASUREMENT.md): rounds of every
configuration `reps_per_round` times in one shuffled sequence (seeded by the
round, recorded as `run_sequence` and the round's `order`), after one
discarded warm-up run of each configuration; rounds are added until every
configuration's median is known to `target_halfwidth_pct` or the budget
ends. Every repetition is kept in the results.

What differs from the `step` kind: each repetition is a fresh process group
started from the case at rest (t = 0; `sphnl run` does not restore the
developed-flow snapshots the bench uses), so the window covers the first
`window_steps` steps of the collapse, in which particles move slowly and
VL_X keeps its lists longer than in the paper's developed flow (t = 0.35 s).
"""
import json
import os
import pathlib
import random
import shutil
import subprocess
import tempfile
import time

from harness import machine as M
from harness import protocol as P
from harness import results as R
from harness.fsio import write_atomic

FAMILY = "mpi"
# mpirun and `sphnl run` start, the case built, its first neighbour search (s),
# and the case setup per particle: for the plan only.
START_S, SETUP_S_PER_PARTICLE = 0.6, 4e-6
# OpenMPI's shared-memory transport: containers often forbid its
# cross-memory attach; copying through the shared segment works everywhere.
MPI_ENV = {"OMPI_MCA_btl_vader_single_copy_mechanism": "none"}


class MpiRunError(Exception):
    """A run of the mpi kind failed; the message says which and why."""


def launcher(mpirun, ranks, threads, cores):
    """The launch prefix of one configuration: none for one rank; else each
    rank bound to its own `threads` cores when the machine has ranks x
    threads cores, unbound (oversubscribed) otherwise. OpenMPI refuses to
    run as root without --allow-run-as-root."""
    if ranks == 1:
        return [], "none (one process)"
    cmd = [mpirun, "-np", str(ranks)]
    if ranks * threads <= cores:
        cmd += ["--map-by", f"slot:PE={threads}", "--bind-to", "core"]
        binding = f"each rank on {threads} core{'s' if threads > 1 else ''}"
    else:
        cmd += ["--oversubscribe", "--bind-to", "none"]
        binding = "unbound (more ranks x threads than cores)"
    if os.getuid() == 0:
        cmd.append("--allow-run-as-root")
    return cmd, binding


def run_command(args, point, steps, out_dir):
    pre, binding = launcher(args.mpirun, point["ranks"], point["threads"], os.cpu_count() or 1)
    cmd = pre + [str(args.sphnl), "run", "--quiet", "--overwrite", "--out", str(out_dir)]
    settings = [("particles", point["particles"]), ("steps", steps), ("output_interval", 0),
                ("progress", "false"), ("list", point["list"]), ("list_steps", point["list_steps"]),
                ("threads", point["threads"])]
    if "balance_by" in point:  # optional axis
        settings.append(("balance_by", point["balance_by"]))
    for key, value in settings:
        cmd += ["--set", f"{key}={R.format_value(value)}"]
    return cmd, binding


def entry(name, point, summary, steps, repetition, sequence, seconds):
    """The results entry (Google-Benchmark-shaped, docs/CONTRACTS.md §3) of one run."""
    wall = summary["wall_time_s"]
    done = max(1, int(summary.get("steps", steps)))
    total = float(wall["total"])
    ranks = point["ranks"]
    n = float(summary["n_total"])
    per_rank = summary.get("particles_per_rank", {"min": n, "max": n})
    ghosts = summary.get("ghosts_per_rank", {"min": 0, "max": 0})
    stats = summary.get("neighbour_stats", {})
    pairs = float(stats.get("interactions", 0))
    pairs_per_rank = summary.get("interactions_per_rank", {"min": pairs, "max": pairs})
    return {"name": name, "run_name": name, "run_type": "iteration", "repetitions": 1,
            "repetition_index": repetition, "threads": 1, "iterations": 1,
            "real_time": total, "cpu_time": total, "time_unit": "s",
            "n_particles": n, "n_fluid": float(summary["n_fluid"]), "window_steps": done,
            "s_per_step": total / done,
            "s_neighbour_list": wall["neighbour_list"] / done, "s_force": wall["force"] / done,
            "s_update": wall["update"] / done, "s_communication": wall.get("communication", 0.0) / done,
            # the slowest rank's communication (waits for the others included) in its slowest step total
            "communication_share": wall.get("communication", 0.0) / total if total > 0 else 0.0,
            "bytes_sent_per_step": float(summary.get("bytes_sent_per_step", 0.0)),
            "n_per_rank": n / ranks, "particles_per_rank_max": float(per_rank["max"]),
            "particles_per_rank_min": float(per_rank["min"]),
            "ghosts_per_rank_max": float(ghosts["max"]), "ghosts_per_rank_min": float(ghosts["min"]),
            "rebuilds": float(stats.get("builds", 0)), "cores": float(ranks * point["threads"]),
            # how even the pair work was: the busiest rank's pairs over the mean, minus one
            "pair_imbalance": float(pairs_per_rank["max"]) / (pairs / ranks) - 1.0 if pairs > 0 else 0.0,
            "wall_s_process": seconds, "run_sequence": sequence}


def check(exp, size, args):
    """Refusals before anything runs: axes outside the kind, no sphnl, no
    mpirun where a point needs one."""
    unknown = [a for a in exp["sweep"][size] if a not in R.FAMILY_KEYS[FAMILY]]
    if unknown:
        raise MpiRunError(f"experiments/{exp['id']}.json: sweep.{size}: axes {unknown} are not axes of the "
                          f"mpi kind; allowed: {', '.join(R.FAMILY_KEYS[FAMILY])}")
    points = R.sweep_points(exp, size)
    if not points:
        raise MpiRunError(f"experiments/{exp['id']}.json: sweep.{size} has no point with ranks x threads "
                          f"<= max_cores ({exp.get('max_cores')})")
    sphnl = pathlib.Path(args.sphnl)
    if not (sphnl.is_file() and os.access(sphnl, os.X_OK)):
        raise MpiRunError(f"{sphnl} not found or not executable: build it with `make build`")
    if any(p["ranks"] > 1 for p in points):
        found = shutil.which(args.mpirun)
        if not found:
            raise MpiRunError(f"mpirun not found (looked for {args.mpirun!r}): install OpenMPI (apt-get "
                              "install openmpi-bin libopenmpi-dev, or `make deps`) and rebuild, or leave "
                              f"{exp['id']} out of --only")
        args.mpirun = found
    return points


def estimate_seconds(exp, size, step_seconds):
    """Model of one experiment at its minimum rounds: per run the start, the
    case setup and the window at the serial cost over ranks x threads cores."""
    proto = P.protocol_of(exp, size)
    window = exp["window_steps"][size]
    per_run = [START_S + SETUP_S_PER_PARTICLE * p["particles"]
               + window * step_seconds({**p, "threads": p["ranks"] * p["threads"]})
               for p in R.sweep_points(exp, size)]
    return sum(per_run) * (proto["reps_per_round"] + 1) * proto["min_rounds"]


def round_sequence(names, reps, seed):
    """[(name, repetition or None for the discarded warm-up)] of one round:
    every configuration's warm-up in shuffled order, then all repetitions of
    all configurations in one shuffled sequence (interleaved, so drift of the
    machine spreads over every configuration)."""
    rng = random.Random(seed)
    warm = list(names)
    rng.shuffle(warm)
    timed = [(n, r) for n in names for r in range(reps)]
    rng.shuffle(timed)
    return [(n, None) for n in warm] + timed


def run_one(args, cmd, env, work):
    start = time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=args.repo)
    seconds = time.monotonic() - start
    if p.returncode != 0:
        raise MpiRunError(f"exit status {p.returncode} of\n  {' '.join(cmd)}\n  "
                          + "\n  ".join((p.stderr or p.stdout).strip().splitlines()[-12:]))
    return json.loads((work / "summary.json").read_text(encoding="utf-8")), seconds


def run(args, exp, out_path, label, env, progress=print):
    """Measure every configuration of `exp` into out_path (written only when
    complete). Returns the seconds it took."""
    size = args.size
    points = check(exp, size, args)
    proto = P.protocol_of(exp, size)
    reps, steps = proto["reps_per_round"], exp["window_steps"][size]
    names = [R.format_run_name(FAMILY, p) for p in points]
    by_name = dict(zip(names, points))
    env = {**env, **{k: v for k, v in MPI_ENV.items() if k not in env}}
    progress(f"{label} {exp['id']}: {len(points)} configurations x {reps} repetitions per round (+1 warm-up "
             f"each), {proto['min_rounds']}-{proto['max_rounds']} rounds, {steps} steps from t = 0 per run "
             f"(model estimate {estimate_seconds(exp, size, args.step_seconds):.0f} s)")
    entries, rounds, bindings = [], [], {}
    start = time.monotonic()
    reason = None
    with tempfile.TemporaryDirectory(prefix=f".{exp['id']}.", dir=out_path.parent) as tmp:
        work = pathlib.Path(tmp)
        while reason is None:
            k = len(rounds)
            probe = M.NoiseProbe(max(p["ranks"] * p["threads"] for p in points))
            order, round_entries = [], []
            for seq, (name, rep) in enumerate(round_sequence(names, reps, seed=k)):
                cmd, bindings[name] = run_command(args, by_name[name], steps, work)
                try:
                    summary, seconds = run_one(args, cmd, env, work)
                except (MpiRunError, OSError, ValueError) as e:
                    raise MpiRunError(f"{exp['id']}: {name}, round {k + 1}: {e}") from None
                if rep is None:
                    continue  # the discarded warm-up
                order.append(name)
                e = entry(name, by_name[name], summary, steps, rep, seq, seconds)
                e["sphnl_round"] = k
                round_entries.append(e)
            record = {"round": k, **probe.finish(env), "order": order, "warmups_discarded": len(names),
                      "git_revision": args.part["git_revision"], "bench": M.relative_to_repo(args.sphnl),
                      "bench_sha256": M.sha256(args.sphnl)}
            entries += round_entries
            rounds.append(record)
            elapsed = time.monotonic() - start
            reason = P.stop_reason(P.metric_samples(entries, exp), proto, len(rounds), elapsed,
                                   elapsed / len(rounds))
            progress(f"  {exp['id']}: round {k + 1} done, elapsed {elapsed:.0f} s"
                     + (" (under load)" if record["under_load"] else ""))
    context = {"sphnl_experiment": exp["id"], "sphnl_size": size, "sphnl_git_revision": args.part["git_revision"],
               "sphnl_mpi_kind": "sphnl run under mpirun, seconds of the slowest rank (summary.json)",
               "sphnl_mpirun": args.mpirun if any(p["ranks"] > 1 for p in points) else None,
               "sphnl_binary": M.relative_to_repo(args.sphnl), "sphnl_window_from": "t = 0 (case at rest)",
               "sphnl_binding": bindings, "num_cpus": os.cpu_count()}
    doc = {"context": context, "benchmarks": entries, "sphnl_rounds": rounds,
           "sphnl_protocol": {"rounds": len(rounds), "reps_per_round": reps, "min_rounds": proto["min_rounds"],
                              "max_rounds": proto["max_rounds"], "target_halfwidth_pct": proto["target_halfwidth_pct"],
                              "budget_s": proto["budget_s"], "stop_reason": reason,
                              "metric": exp.get("metric", "s_per_step"),
                              "seconds": round(time.monotonic() - start, 1)}}
    missing = R.missing_in(doc, exp, size)
    if missing:
        raise MpiRunError(f"{exp['id']}: results lack {missing[:3]}")
    write_atomic(out_path, json.dumps(doc, indent=2) + "\n")
    seconds = time.monotonic() - start
    progress(f"  {exp['id']}: {len(rounds)} rounds ({reason}) in {seconds:.0f} s -> {out_path}")
    return seconds

