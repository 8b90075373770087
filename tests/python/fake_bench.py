#!/usr/bin/python3
"""Stand-in for build/benchmarks/sphnl_bench (docs/CONTRACTS.md §2) for the
harness tests: same arguments, Google Benchmark 1.7.1-shaped console output
and JSON, plausible timings that follow the paper's trends. Runs in
milliseconds. Like GB 1.7.1 it honours --benchmark_enable_random_interleaving
(repetitions in a random order, reported per configuration when all are done)
and --benchmark_min_warmup_time > 0 (one discarded call per configuration
first); like sphnl_bench every entry carries the counter `run_sequence`.
Timing noise is drawn per process (seed, name, repetition and process id),
so every round (process) measures afresh; its order likewise.

Test knobs (flag or environment variable):
  --fake-seed S          FAKE_BENCH_SEED     noise seed (default 1)
  --fake-noise R         FAKE_BENCH_NOISE    relative noise of a repetition (default 0.02)
  --fake-nonce X         FAKE_BENCH_NONCE    replaces the process id in the noise seed
  --fake-regress K:V=F   FAKE_BENCH_REGRESS  multiply the time of configs whose
                                             name has segment K:V by F (comma list)
  --fake-error K:V       FAKE_BENCH_ERROR    report configs with segment K:V as errors
  --fake-fail            FAKE_BENCH_FAIL=1   write half the output, then exit 1
  --fake-delay S         FAKE_BENCH_DELAY    sleep S seconds per benchmark
  --revision             FAKE_BENCH_REVISION print it (default "unknown") and exit
  --fake-snapshot S      FAKE_BENCH_SNAPSHOT report (without spending it) S seconds of
                                             snapshot development, as sphnl_bench does
"""
import argparse
import json
import math
import os
import pathlib
import random
import sys
import time

# experiments/run.py starts a .py bench with the repository root on PYTHONPATH.
from harness import results as R

GB_LINE = "-" * 100


def step_model(p):
    """Seconds per step and phase shares of one `step` config (made-up but
    paper-shaped: A quadratic unsorted, reordering helps, VL best near n_s=7)."""
    n = p["particles"]
    t = 1.0e-6 * n * (1 + 0.1 * math.log(n / 1000))
    if p["reorder"] == 0:
        t *= {"D": 1.15}.get(p["gridder"], 1.3)
        t *= {"B": 1.05, "C": 1.08}.get(p["gridder"], 1.0)
    t *= {"sort_x": 1.0, "sort_xy": 1.03, "sort_xyz": 1.04, "hilbert": 1.02}[p["cell_order"]]
    if p["gridder"] == "A":
        t += 2e-11 * n * n if p["reorder"] == 0 else 1.0e-6 * n
    share_list = 0.03
    if p["list"] != "cll":
        gain = 0.05 - 0.04 * math.log(p["list_steps"] / 7) ** 2 + 0.01 * math.log10(n / 31239)
        gain -= 0.01 if p["list"] == "vlc" else 0.0
        t *= 1 - gain * (2 if p["kgc"] else 1)
        share_list = 0.2 if p["list_steps"] == 1 else 0.04
    if p["kgc"]:
        t *= 1.8
    if p["threads"] > 1:
        t /= 0.9 * p["threads"]
    return t, share_list


def memory_model(p):
    """Bytes of the neighbour structures (nl_bytes)."""
    n, cells = p["particles"], p["particles"] * 4
    grid = {"A": 4 * (n + cells), "B": 4 * (2 * n + cells), "C": 4 * cells * 41,
            "D": 4 * (2 * n + cells)}[p["gridder"]]
    if p["reorder"]:
        grid += n * (2 if p["gridder"] != "D" else 6)
    if p["list"] == "cll":
        return grid
    skin = 0.04 * p["list_steps"] * (1.2 if p["list"] == "vlc" else 1.0)
    return grid + int(4 * 55 * n * (1 + skin) ** 3)


def counters(p, t, share_list, steps):
    """The user counters of docs/CONTRACTS.md §2 for one `step` repetition."""
    t *= {0.2: 0.97, 0.5: 1.04}.get(p.get("flow_time", 0.35), 1.0)  # the flow spreads
    rebuilds = steps if p["list"] == "cll" else max(1, math.ceil(steps / p["list_steps"]))
    return {"n_particles": p["particles"], "n_fluid": int(p["particles"] * 0.4), "window_steps": steps,
            "s_per_step": t, "s_neighbour_list": t * share_list,
            "s_force": t * (0.98 - share_list), "s_update": t * 0.02,
            "nl_bytes": memory_model(p), "peak_rss_bytes": 50_000_000 + 400 * p["particles"],
            "rebuilds": rebuilds, "mean_steps_per_list": steps / rebuilds,
            "max_steps_per_list": math.ceil(steps / rebuilds),
            "candidates_per_particle": 120.0, "interactions_per_particle": 55.0,
            "pairs_per_s": 27.5 * p["particles"] / t, "vl_misses": 0,
            "s_per_particle_step": t / p["particles"], "snapshot_time": p.get("flow_time", 0.35) + 1e-4}


def parse_args(argv):
    env = os.environ.get
    p = argparse.ArgumentParser()
    p.add_argument("--experiment", required=True)
    p.add_argument("--size", required=True, choices=R.SIZES)
    p.add_argument("--cache-dir")
    p.add_argument("--benchmark_out")
    p.add_argument("--benchmark_out_format", default="json")
    p.add_argument("--benchmark_repetitions", type=int, default=1)
    p.add_argument("--benchmark_min_time", default="0")
    p.add_argument("--benchmark_min_warmup_time", type=float, default=0.0)
    p.add_argument("--benchmark_enable_random_interleaving", default="false")
    p.add_argument("--validate", action="store_true")
    p.add_argument("--fake-noise", type=float, default=float(env("FAKE_BENCH_NOISE", "0.02")))
    p.add_argument("--fake-nonce", default=env("FAKE_BENCH_NONCE", str(os.getpid())))
    p.add_argument("--fake-seed", default=env("FAKE_BENCH_SEED", "1"))
    p.add_argument("--fake-regress", default=env("FAKE_BENCH_REGRESS", ""))
    p.add_argument("--fake-error", default=env("FAKE_BENCH_ERROR", ""))
    p.add_argument("--fake-fail", action="store_true", default=env("FAKE_BENCH_FAIL") == "1")
    p.add_argument("--fake-delay", type=float, default=float(env("FAKE_BENCH_DELAY", "0")))
    p.add_argument("--fake-snapshot", type=float, default=float(env("FAKE_BENCH_SNAPSHOT", "0")))
    return p.parse_args(argv)


def main(argv=None):
    if "--revision" in (sys.argv[1:] if argv is None else argv):
        print(os.environ.get("FAKE_BENCH_REVISION", "unknown"))  # like sphnl_bench: what it was built from
        return 0
    args = parse_args(argv)
    try:
        float(args.benchmark_min_time)  # GB 1.7.1 rejects '0.5s' and exits 1
    except ValueError:
        print(f"invalid --benchmark_min_time={args.benchmark_min_time}", file=sys.stderr)
        return 1
    exp = json.loads(pathlib.Path(args.experiment).read_text(encoding="utf-8"))
    if args.validate:  # the real bench checks the schema; the stand-in only parses
        return 0
    family, size, reps = exp["benchmark"], args.size, args.benchmark_repetitions
    steps = exp["window_steps"][size]
    regress = dict(kv.split("=") for kv in args.fake_regress.split(",") if kv)
    errs = set(filter(None, args.fake_error.split(",")))
    print(f"Running {sys.argv[0]}\nRun on (2 X 2600 MHz CPU s)\n"
          "***WARNING*** Library was built as DEBUG. Timings may be affected.", file=sys.stderr)
    if args.fake_snapshot:
        print(f"sphnl_bench: developed in 100 steps, {args.fake_snapshot:.1f} s wall", file=sys.stderr, flush=True)
    print(f"{GB_LINE}\n{'Benchmark':<60}{'Time':>13}{'CPU':>13} Iterations UserCounters...\n{GB_LINE}",
          flush=True)
    points = R.sweep_points(exp, size)
    if args.fake_fail:
        points = points[: len(points) // 2]
    names = [R.format_run_name(family, p) for p in points]
    schedule = [(i, rep) for i in range(len(points)) for rep in range(reps)]
    if args.benchmark_enable_random_interleaving == "true":
        random.Random(f"order|{args.fake_seed}|{args.fake_nonce}").shuffle(schedule)
    runs, warmed, sequence = {i: [] for i in range(len(points))}, set(), 0
    entries = []
    for index, rep in schedule:
        point, name = points[index], names[index]
        if args.benchmark_min_warmup_time > 0 and index not in warmed:
            warmed.add(index)
            sequence += 1  # the discarded warm-up call
        segs = set(name.split("/")[1:])
        factor = math.prod(float(f) for k, f in regress.items() if k in segs)
        rng = random.Random(f"{args.fake_seed}|{name}|{rep}|{args.fake_nonce}")
        noise = factor * (1 + args.fake_noise * rng.gauss(0, 1))
        if family == "step":
            t, share = step_model(point)
            ctr = counters(point, t * noise, share, steps)
            real = ctr["s_per_step"] * steps
        elif family == "search":  # full lists, 74 entries a point; the peer 8x slower
            real = 2e-7 * point["particles"] * (8 if point.get("impl") == "nanoflann" else 1) \
                / (0.9 * point["threads"] if point["threads"] > 1 else 1) * noise
            ctr = {"n_particles": point["particles"], "entries": 74 * point["particles"], "entries_per_s": 74 * point["particles"] / real,
                   "s_call": real, "bytes": 400 * point["particles"]}
        else:  # cellindex: passes over n particles, >= 2e6 keys in all
            per = {"sort_x": 1e-9, "sort_xy": 3e-9, "sort_xyz": 4e-9, "hilbert": 9e-9}[point["cell_order"]]
            passes = max(1, 2_000_000 // point["particles"])
            real = per * point["particles"] * passes * noise
            ctr = {"n_particles": point["particles"], "s_per_particle": per * noise,
                   "cell_keys": 4 * point["particles"], "cells": 4 * point["particles"]}
        entry = {"name": name, "family_index": 0, "per_family_instance_index": index,
                 "run_name": name, "run_type": "iteration", "repetitions": reps,
                 "repetition_index": rep, "threads": 1, "iterations": 1,
                 "real_time": real * 1e9, "cpu_time": real * 0.99e9, "time_unit": "ns"}
        if segs & errs:
            entry.update(error_occurred=True, error_message="fake error: cell overflow")
        else:
            entry.update(ctr)
        entry["run_sequence"] = sequence
        sequence += 1
        runs[index].append(entry)
        time.sleep(args.fake_delay)
        if len(runs[index]) < reps:
            continue
        # GB 1.7.1 reports a configuration when its last repetition is done.
        for e in sorted(runs[index], key=lambda e: e["repetition_index"]):
            shown = " ERROR OCCURRED: 'fake error'" if segs & errs else \
                f"{e['real_time'] * 1e-6:10.2f} ms {e['cpu_time'] * 1e-6:10.2f} ms          1"
            print(f"{name:<60}{shown}", flush=True)
            entries.append(e)
        if reps > 1 and not segs & errs:
            for agg in ("mean", "median", "stddev", "cv"):
                entries.append({**runs[index][0], "name": f"{name}_{agg}", "run_type": "aggregate",
                                "aggregate_name": agg, "aggregate_unit": "time"})
                entries[-1].pop("repetition_index")
                print(f"{name + '_' + agg:<60}{0.0:10.2f} ms", flush=True)
    doc = {"context": {"date": "2024-01-01T00:00:00+00:00", "host_name": "fake",
                       "executable": sys.argv[0], "num_cpus": 2, "mhz_per_cpu": 2600,
                       "cpu_scaling_enabled": False, "caches": [], "load_avg": [0, 0, 0],
                       "library_build_type": "debug", "sphnl_build_type": "Release",
                       "sphnl_compiler": "fake", "sphnl_git_revision": "fake",
                       "sphnl_march": "native", "sphnl_cpu": "fake", "sphnl_size": size,
                       "sphnl_experiment": exp["id"]},
           "benchmarks": entries}
    if args.benchmark_out:
        text = json.dumps(doc, indent=2)
        pathlib.Path(args.benchmark_out).write_text(text[: len(text) // 2] if args.fake_fail else text,
                                                    encoding="utf-8")
    if args.fake_fail:
        print("fake failure: snapshot checksum mismatch", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
