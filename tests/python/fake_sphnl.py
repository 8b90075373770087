#!/usr/bin/python3
"""A stand-in for `sphnl run` (and, as `fake_sphnl.py mpirun ...`, for
mpirun) for the tests of the mpi kind: writes the summary.json fields that
experiments/mpi_runs.py reads, from a cost model, in no time.

Model (seconds per step): N * 1e-6 / cores * (0.9 for VL_X), cores = ranks x
threads; a distributed run is 8 % slower balanced by particles and 1 % by
interactions (its busiest rank's pairs over the mean), adds communication
of 5 % of its step, and the
VL_X gain grows as N/P falls (2 % more per halving of N/P below 31 239)."""
import json
import math
import os
import sys
from pathlib import Path


def launch(argv):
    """(ranks, the command) of `mpirun -np P [options] CMD...`."""
    ranks, i = 1, 0
    while i < len(argv) and argv[i].startswith("-"):
        if argv[i] == "-np":
            ranks = int(argv[i + 1])
        i += 2 if argv[i] in ("-np", "--map-by", "--bind-to") else 1
    return ranks, argv[i:]


def mpirun(argv):
    """mpirun -np P [options] CMD...: runs CMD once with FAKE_RANKS=P."""
    ranks, cmd = launch(argv)
    os.execve(sys.executable, [sys.executable] + cmd, {**os.environ, "FAKE_RANKS": str(ranks)})


def summary(argv, ranks):
    """The summary.json of `sphnl run ARGV` on `ranks` ranks."""
    sets = dict(argv[i + 1].split("=", 1) for i in range(len(argv) - 1) if argv[i] == "--set")
    threads = int(sets.get("threads", "1"))
    n, steps = int(sets["particles"]), int(sets["steps"])
    per = n / ranks
    gain = 0.1 + (0.02 * math.log2(31239 / per) if per < 31239 else 0.0)
    step = n * 1e-6 / (ranks * threads) * ((1 - gain) if sets["list"] == "vlx" else 1.0)
    # by particles the busiest rank holds 8 % more pairs than the mean (by interactions 1 %)
    imbalance = (0.08 if sets.get("balance_by") == "particles" else 0.01) if ranks > 1 else 0.0
    step *= 1 + imbalance
    comm = 0.05 * step if ranks > 1 else 0.0
    total = step + comm
    out = {"n_total": n, "n_fluid": n // 3, "steps": steps,
               "wall_time_s": {"neighbour_list": 0.2 * step * steps, "force": 0.7 * step * steps,
                               "update": 0.1 * step * steps, "communication": comm * steps, "total": total * steps},
               "neighbour_stats": {"builds": steps, "interactions": 20 * n * steps}}
    if ranks > 1:
        pairs = 20 * n * steps / ranks
        out.update(ranks=ranks, particles_per_rank={"min": n // ranks, "max": n - n // ranks},
                   interactions_per_rank={"min": round(pairs * (1 - imbalance)), "max": round(pairs * (1 + imbalance))},
                   ghosts_per_rank={"min": 100, "max": 120}, bytes_sent_per_step=1000.0)
    return out


def run(argv):
    out = Path(argv[argv.index("--out") + 1])
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary(argv, int(os.environ.get("FAKE_RANKS", "1")))))
    return 0


if __name__ == "__main__":
    if sys.argv[1] == "mpirun":
        mpirun(sys.argv[2:])
    sys.exit(run(sys.argv[2:]))
