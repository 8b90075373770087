"""Python's sphnl.neighbours beside the C++ API it binds, timed interleaved.

sphnl.neighbours(points, radius) is a first call of the C++ API every time
(a new Search, new output arrays), so it is compared with the `search`
benchmark row impl:api/call:first on the same cloud (the cubic lattice of
benchmarks/peers/clouds.hpp, x fastest, R = 2.6 spacings): each round times
one Python call in this process, then runs sphnl_bench for that one row and
reads its s_call; which of the two goes first is drawn anew each round.
Prints the medians and their ratio with its bootstrap 95 % interval, paired
by round (harness.stats.paired_ratio_ci: Python and C++ of one round form
one ratio), and the verdict against the target 1.2 (README.md, "What the
API costs").

    /usr/bin/python3 benchmarks/python_vs_cpp.py [--particles 1000000] [--threads 1] [--rounds 9]
"""
import argparse
import json
import random
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from harness.stats import paired_ratio_ci  # noqa: E402

TARGET = 1.2  # Python at most 1.2 times the C++ call
RADIUS = 2.6  # spacings, as benchmarks/search_benchmark.cpp (kRadius)


def lattice(particles):
    """The lattice of peers::make_cloud: side^3 points at integer
    coordinates, x fastest, as a C-contiguous (n, 3) float64 array."""
    side = max(1, round(particles ** (1 / 3)))
    z, y, x = np.meshgrid(np.arange(side), np.arange(side), np.arange(side), indexing="ij")
    return np.ascontiguousarray(np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1), dtype=np.float64)


def experiment(particles, threads):
    """A one-row `search` experiment: the C++ API, first call."""
    point = {"particles": [particles], "gridder": ["B"], "cell_order": ["sort_x"], "reorder": [1],
             "threads": [threads], "impl": ["api"], "call": ["first"]}
    proto = {"min_rounds": 1, "max_rounds": 1, "reps_per_round": 1, "target_halfwidth_pct": 100, "budget_s": 60}
    return {"id": "python_vs_cpp", "figure": None, "title": "C++ API row for benchmarks/python_vs_cpp.py",
            "benchmark": "search", "sweep": {s: point for s in ("tiny", "default", "full")},
            "window_steps": {s: 1 for s in ("tiny", "default", "full")},
            "protocol": {s: proto for s in ("tiny", "default", "full")},
            "metric": "entries_per_s", "uses": None, "claims": []}


def cpp_seconds(bench, exp_path, out_path):
    """s_call of one C++ API call (the bench's own warm-up and pair check untimed)."""
    subprocess.run([str(bench), f"--experiment={exp_path}", "--size=tiny", "--benchmark_min_time=0",
                    "--benchmark_repetitions=1", f"--benchmark_out={out_path}", "--benchmark_out_format=json"],
                   check=True, capture_output=True, text=True)
    rows = [b for b in json.loads(Path(out_path).read_text(encoding="utf-8"))["benchmarks"]
            if b.get("run_type") == "iteration"]
    return float(rows[0]["s_call"])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--particles", type=int, default=1_000_000)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--seed", type=int, default=1, help="seed of the order drawn each round")
    ap.add_argument("--bench", default=str(ROOT / "build" / "benchmarks" / "sphnl_bench"))
    ap.add_argument("--module-dir", default=str(ROOT / "build" / "python"))
    args = ap.parse_args(argv)
    sys.path.insert(0, args.module_dir)
    import sphnl  # noqa: E402  (the module built by `make build`)

    if args.rounds < 3:
        ap.error(f"--rounds {args.rounds}: an interval needs at least 3 rounds")
    points = lattice(args.particles)
    py, cpp = [], []
    order = random.Random(args.seed)
    entries = 0
    with tempfile.TemporaryDirectory() as tmp:
        exp_path = Path(tmp) / "python_vs_cpp.json"
        exp_path.write_text(json.dumps(experiment(args.particles, args.threads)), encoding="utf-8")
        sphnl.neighbours(points[:1000], RADIUS)  # import and first-use costs outside the rounds

        def python_call():
            nonlocal entries
            t0 = time.perf_counter()
            offsets, indices = sphnl.neighbours(points, RADIUS, threads=args.threads)
            py.append(time.perf_counter() - t0)
            entries = len(indices)
            del offsets, indices

        def cpp_call():
            cpp.append(cpp_seconds(args.bench, exp_path, Path(tmp) / "out.json"))

        for k in range(args.rounds):
            calls = [python_call, cpp_call]
            order.shuffle(calls)
            for call in calls:
                call()
            print(f"round {k + 1}/{args.rounds}: python {py[-1]:.4f} s, C++ {cpp[-1]:.4f} s", file=sys.stderr, flush=True)
    mp, mc = statistics.median(py), statistics.median(cpp)
    ratio, lo, hi = paired_ratio_ci([[t] for t in py], [[t] for t in cpp])
    verdict = "met" if hi <= TARGET else "not met" if lo > TARGET else "unresolved"
    print(f"{len(points)} points, {entries} entries, {args.threads} thread(s), {args.rounds} interleaved rounds")
    print(f"python sphnl.neighbours   median {mp:.4f} s  ({', '.join(f'{t:.3f}' for t in py)})")
    print(f"C++ API (impl:api, first) median {mc:.4f} s  ({', '.join(f'{t:.3f}' for t in cpp)})")
    print(f"python / C++ = {ratio:.3f} [{lo:.3f}, {hi:.3f}] (95 % interval, paired by round): "
          f"target <= {TARGET}: {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
