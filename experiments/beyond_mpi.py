"""beyond_mpi: `sphnl run` on P ranks (mpirun) against one rank, CLL and VL_X.

Beyond the paper (which is serial): strong scaling of the dam break for
P = 1, 2 ranks with CLL and VL_X (n_s = 7); hybrid (P ranks x T threads)
against pure OpenMP (1 rank x P T threads) at the same core count; the
share of the step spent communicating; VL_X's improvement over CLL
(t_CLL / t_VLX) against the particles per rank N / P. Each point is one
`sphnl run` of a fixed number of steps from t = 0, timed by its own phase
timers (summary.json), so the numbers carry the run-to-run noise of one run:
a sanity check, not a measurement protocol (experiments/run.py's step
benchmarks are serial).

    python3 -m experiments.beyond_mpi --sphnl build/sphnl --out results/beyond_mpi \\
        [--particles 31239] [--steps 100] [--ranks 1,2] [--threads 1]

Writes OUT/beyond_mpi.json (every run's summary fields) and OUT/beyond_mpi.md
(the tables). Run it under `flock /tmp/sphnl-timed.lock` on a shared machine.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


def mpirun_prefix(mpirun, ranks):
    if ranks == 1:
        return []
    cmd = [mpirun, "-np", str(ranks), "--oversubscribe"]
    if os.getuid() == 0:
        cmd.append("--allow-run-as-root")  # OpenMPI refuses root without it
    return cmd


def points(ranks, threads):
    """(name, ranks, threads, list) of every run: each list at every rank count,
    and pure OpenMP at the cores of the largest hybrid run."""
    out = []
    for lst in ("cll", "vlx"):
        for p in ranks:
            out.append((f"{lst}_p{p}_t{threads}", p, threads, lst))
        cores = max(ranks) * threads
        if max(ranks) > 1:
            out.append((f"{lst}_p1_t{cores}", 1, cores, lst))
    return out


def run_point(args, ranks, threads, lst, out_dir):
    sets = [f"particles={args.particles}", f"steps={args.steps}", "output_interval=0", "progress=false",
            f"list={lst}", "list_steps=7", f"threads={threads}"]
    cmd = mpirun_prefix(args.mpirun, ranks) + [str(args.sphnl), "run", "--quiet", "--overwrite", "--out", str(out_dir)]
    for s in sets:
        cmd += ["--set", s]
    env = dict(os.environ, OMP_PROC_BIND="false")
    env.setdefault("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {p.returncode}:\n{p.stderr}")
    return json.loads((out_dir / "summary.json").read_text())


def row(name, ranks, threads, lst, s):
    t = s["wall_time_s"]
    steps = max(s["steps"], 1)
    return {"name": name, "ranks": ranks, "threads": threads, "list": lst, "n": s["n_total"],
            "n_per_rank": s["n_total"] / ranks, "s_per_step": t["total"] / steps,
            "communication_share": t.get("communication", 0.0) / t["total"] if t["total"] > 0 else 0.0,
            "bytes_sent_per_step": s.get("bytes_sent_per_step", 0.0),
            "ghosts_max": s.get("ghosts_per_rank", {}).get("max", 0)}


def tables(rows):
    """Markdown: every run; speed-up over one rank; VL_X over CLL per N/P."""
    by = {(r["list"], r["ranks"], r["threads"]): r for r in rows}
    lines = ["| run | ranks | threads | N/P | s/step | communication | bytes sent/step | ghosts (max) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['name']} | {r['ranks']} | {r['threads']} | {r['n_per_rank']:.0f} | {r['s_per_step']:.4g} "
                     f"| {100 * r['communication_share']:.1f} % | {r['bytes_sent_per_step']:.0f} | {r['ghosts_max']} |")
    lines += ["", "| list | ranks x threads | speed-up over 1 x 1 (or 1 x T) |", "|---|---|---|"]
    for (lst, p, t), r in sorted(by.items()):
        base = by.get((lst, 1, t))
        if base and p > 1:
            lines.append(f"| {lst} | {p} x {t} | {base['s_per_step'] / r['s_per_step']:.2f} |")
    lines += ["", "| ranks x threads | N/P | t_CLL / t_VLX |", "|---|---|---|"]
    for (lst, p, t), r in sorted(by.items()):
        if lst == "vlx" and ("cll", p, t) in by:
            lines.append(f"| {p} x {t} | {r['n_per_rank']:.0f} | {by[('cll', p, t)]['s_per_step'] / r['s_per_step']:.2f} |")
    return "\n".join(lines) + "\n"


def write_atomically(path, text):
    tmp = path.with_name(path.name + f".tmp.{os.getpid()}")
    tmp.write_text(text)
    tmp.replace(path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sphnl", type=Path, default=Path("build/sphnl"))
    ap.add_argument("--mpirun", default="mpirun")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--particles", type=int, default=31239)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--ranks", default="1,2", help="comma-separated rank counts")
    ap.add_argument("--threads", type=int, default=1, help="OpenMP threads per rank")
    args = ap.parse_args(argv)
    ranks = [int(x) for x in args.ranks.split(",")]
    if any(p > 1 for p in ranks):
        found = shutil.which(args.mpirun)
        if not found:
            print(f"beyond_mpi: mpirun not found (looked for {args.mpirun!r}); install OpenMPI "
                  "(apt-get install openmpi-bin libopenmpi-dev, or `make deps`), rebuild, or pass --ranks 1",
                  file=sys.stderr)
            return 2
        args.mpirun = found
    args.out.mkdir(parents=True, exist_ok=True)
    rows, summaries = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, p, t, lst in points(ranks, args.threads):
            s = run_point(args, p, t, lst, Path(tmp) / name)
            summaries[name] = s
            rows.append(row(name, p, t, lst, s))
            print(f"beyond_mpi: {name}: {rows[-1]['s_per_step']:.4g} s/step", file=sys.stderr)
    write_atomically(args.out / "beyond_mpi.json", json.dumps({"rows": rows, "summaries": summaries}, indent=2) + "\n")
    write_atomically(args.out / "beyond_mpi.md", tables(rows))
    print(tables(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
