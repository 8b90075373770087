#!/usr/bin/python3
"""Distributed runs projected from the decomposition model (harness/decomposition_model.py):
ghosts per rank and bytes per step for P = 1..1024 from the real particle
distribution of the dam break, extrapolated in N, and the step time and
parallel efficiency under a stated network model.

    /usr/bin/python3 -m plots.mpi_projection --out results/mpi_model \\
        [--sphnl build/sphnl] [--particles 31239,250000,1000000] [--ranks 1,2,4,...,1024] \\
        [--targets 1e7,1e8,1.2e8] [--latency 1.5e-6] [--bandwidth 10e9] \\
        [--cost-from SUMMARY.json | --s-per-particle-step S]

The case at each `--particles` is made by `sphnl run` (one step; its t = 0
snapshot is the distribution counted: owned particles, ghosts and the pairs
each rank evaluates, with the ranges cut by the code's weights and, as a
what-if, by pairs). The compute cost per particle-step is
the measured serial one: `--cost-from` a summary.json of a serial `sphnl run`
(seconds_per_step / n_total; its interactions give the cost per pair), or
given, or a results folder (`results/full`: the serial CLL step of fig12
at its largest N, 10^6). Writes OUT/decomposition_counts.json (the counts, reused on the next
run), OUT/projection.json, OUT/projection.md and OUT/decomposition_model.png|svg.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("SOURCE_DATE_EPOCH", "0")
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

plt.rcParams["svg.hashsalt"] = "sphnl"  # the same SVG from the same numbers
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from harness import decomposition_model as D  # noqa: E402
from harness.fsio import write_atomic  # noqa: E402
from harness.results import format_n  # noqa: E402

POWERS = [2 ** k for k in range(11)]


def case_distribution(sphnl, particles):
    """(x, y, z, types, h, n) of the dam break at t = 0 with `particles` requested."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [str(sphnl), "run", "--quiet", "--overwrite", "--out", tmp, "--set", f"particles={particles}",
               "--set", "steps=1", "--set", "output_interval=1", "--set", "progress=false"]
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            raise D.ModelError(f"{' '.join(cmd)} exited {p.returncode}: {p.stderr.strip()[-800:]}")
        summary = json.loads((Path(tmp) / "summary.json").read_text(encoding="utf-8"))
        df = pd.read_csv(Path(tmp) / summary["snapshots"][0]["csv"])
    return (df["x"].to_numpy(), df["y"].to_numpy(), df["z"].to_numpy(), df["type"].to_numpy(),
            float(summary["h"]), int(summary["n_total"]))


ORDERS = ("sort_x", "hilbert")
ORDER_STYLE = {"sort_x": "-", "hilbert": "--"}


def count(sphnl, particles_list, ranks_list):
    rows = []
    for particles in particles_list:
        x, y, z, types, h, n = case_distribution(sphnl, particles)
        pairs = D.interacting_pairs(x, y, z, types, h)
        for order in ORDERS:
            for balance in D.BALANCES:
                counts = D.decompose(x, y, z, types, h, 2 * h, ranks_list, order=order, balance=balance,
                                     pairs=pairs)
                rows += [dict(D.summary_row(n, p, c), order=order, balance=balance) for p, c in counts.items()]
        print(f"mpi_projection: N = {n}: counted P = {min(counts)}..{max(counts)}", file=sys.stderr)
    return rows


def cost_of(args):
    """(seconds per particle-step, seconds per pair, source) of the serial run."""
    if args.s_per_particle_step:
        return args.s_per_particle_step, None, "given (--s-per-particle-step)"
    if Path(args.cost_from).is_dir():  # a results folder: the serial CLL step of fig12 at its largest N
        from harness import results as R
        med = R.medians(R.load_run(args.cost_from).query("experiment == 'fig12'"))
        row = med[(med["list"] == "cll")].sort_values("N").iloc[-1]
        pairs = row["N"] * row["interactions_per_particle"] / 2
        return row["t"] / row["N"], row["t"] / pairs, (f"{args.cost_from}/fig12.json: serial CLL step at "
                                                        f"N = {row['N']:.0f} (median of {int(row['reps'])})")
    s = json.loads(Path(args.cost_from).read_text(encoding="utf-8"))
    if s.get("ranks", 1) != 1:
        raise D.ModelError(f"{args.cost_from}: a run on {s['ranks']} ranks; the cost must be a serial run's")
    steps = max(1, s["steps"])
    per_particle = s["seconds_per_step"] / s["n_total"]
    pairs_per_step = s["neighbour_stats"]["interactions"] / steps
    return per_particle, s["seconds_per_step"] / pairs_per_step, \
        f"{args.cost_from}: N = {s['n_total']}, {steps} steps, {s['config']['threads']} thread(s)"


def projection_figure(counts, proj, out):
    """Ghosts per rank against P (counted, and extrapolated in N), and the
    projected parallel efficiency and communication share against P."""
    fig, axes = plt.subplots(1, 3, figsize=(19.2, 4.8))
    c = pd.DataFrame(counts)
    c = c[c["balance"] == "interactions"]  # the ranges the code cuts by default
    big = c[(c["N"] == c["N"].max()) & (c["P"] > 1)]  # one rank has no ghosts
    for order in ORDERS:
        part = big[big["order"] == order].sort_values("P")
        axes[0].plot(part["P"], part["ghosts_max"], ORDER_STYLE[order], marker="o", label=f"ghosts, {order}")
    axes[0].plot(part["P"], part["owned_max"], ":", color="0.3", label="owned (both orders)")
    axes[0].set(xscale="log", yscale="log", xlabel="P (ranks)", ylabel="particles per rank (busiest rank)",
                title=f"counted: N = {format_n(c['N'].max())}, cells of 2h, t = 0")
    p = pd.DataFrame(proj)
    colours = {}
    for (order, n), part in p.groupby(["order", "N"]):
        part = part.sort_values("P")
        colour = colours.setdefault(n, f"C{len(colours)}")
        label = f"{order}, N = {n:.3g}" + (" *" if part["extrapolated"].any() else "")
        for ax, col in ((axes[1], "efficiency"), (axes[2], "communication_share")):
            ax.plot(part["P"], 100 * part[col], ORDER_STYLE[order], color=colour, marker="o", ms=3, label=label)
    axes[1].axhline(90, color="0.4", lw=0.8, ls="--")
    axes[1].set(xscale="log", xlabel="P (ranks)", ylabel="parallel efficiency (%)", ylim=(0, 105),
                title="projected strong scaling, CLL (* N extrapolated)")
    axes[2].set(xscale="log", xlabel="P (ranks)", ylabel="communication share of the step (%)", ylim=(0, 100),
                title="projected communication share")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.text(0.99, -0.01, "model: harness/decomposition_model.py (docs/FINDINGS.md)", ha="right", va="top",
             fontsize=7, color="0.4")
    out.mkdir(parents=True, exist_ok=True)
    for ext in ("png", "svg"):
        import io
        buf = io.BytesIO()
        fig.savefig(buf, format=ext, metadata={"Software": None} if ext == "png" else {"Date": None},
                    bbox_inches="tight")
        write_atomic(out / f"decomposition_model.{ext}", buf.getvalue())
    plt.close(fig)


def table(proj, ps=(1, 16, 128, 1024)):
    lines = ["| order | N | P | compute (ms) | exchanges: latency (ms) | exchanges: bytes (ms) | reductions (ms) "
             "| P-vector sum (ms) | step (ms) | communication | efficiency | efficiency, neighbour exchange "
             "| efficiency, ranges by particle weights | efficiency, ranges balanced by pairs |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in proj:
        if r["P"] in ps:
            lines.append(f"| {r['order']} | {r['N']:.3g}{' *' if r['extrapolated'] else ''} | {r['P']} | {1e3 * r['compute']:.3g} "
                         f"| {1e3 * r['exchange_latency']:.3g} | {1e3 * r['exchange_bytes']:.3g} "
                         f"| {1e3 * r['reductions']:.3g} | {1e3 * r['rank_vector_sum']:.3g} | {1e3 * r['step_s']:.3g} "
                         f"| {100 * r['communication_share']:.1f} % | {100 * r['efficiency']:.1f} % "
                         f"| {100 * r['efficiency_neighbour_exchange']:.1f} % "
                         f"| {100 * r['efficiency_weight_balance']:.1f} % "
                         f"| {100 * r['efficiency_pair_balance']:.1f} % |")
    return "\n".join(lines) + "\n\n`*`: N extrapolated from the largest N counted (harness/decomposition_model.py).\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--sphnl", type=Path, default=Path("build/sphnl"))
    ap.add_argument("--particles", default="31239,250000,1000000")
    ap.add_argument("--ranks", default=",".join(map(str, POWERS)))
    ap.add_argument("--targets", default="1e7,1e8,1.2e8", help="N to project (extrapolated past the counted N)")
    ap.add_argument("--latency", type=float, default=D.LATENCY_S, help="seconds per message (default 1.5e-6)")
    ap.add_argument("--bandwidth", type=float, default=D.BANDWIDTH_BPS, help="bytes per second (default 10e9)")
    cost = ap.add_mutually_exclusive_group(required=True)
    cost.add_argument("--cost-from", type=Path, help="summary.json of a serial sphnl run, or a results folder "
                                                     "(its fig12 CLL step at the largest N): the measured cost")
    cost.add_argument("--s-per-particle-step", type=float)
    ap.add_argument("--recount", action="store_true", help="count again even if OUT/decomposition_counts.json exists")
    args = ap.parse_args(argv)
    ranks = [int(v) for v in args.ranks.split(",")]
    particles = [int(float(v)) for v in args.particles.split(",")]
    targets = [int(float(v)) for v in args.targets.split(",")]
    counts_path = args.out / "decomposition_counts.json"
    try:
        counts = None
        if counts_path.exists() and not args.recount:
            counts = json.loads(counts_path.read_text(encoding="utf-8"))["rows"]
            if not all("pairs_serial" in r and "balance" in r for r in counts) or \
                    {r["balance"] for r in counts} != set(D.BALANCES):  # an older model's counts
                print(f"mpi_projection: {counts_path} has no pair counts or not every balance; counting again",
                      file=sys.stderr)
                counts = None
        if counts is None:
            counts = count(args.sphnl, particles, ranks)
            write_atomic(counts_path, json.dumps({"cell": "2h (CLL)", "state": "t = 0",
                                                   "rows": counts}, indent=1) + "\n")
        per_particle, per_pair, source = cost_of(args)
    except (D.ModelError, OSError, KeyError, ValueError) as e:
        print(f"mpi_projection: {e}", file=sys.stderr)
        return 2
    n_list = sorted(set(targets + [r["N"] for r in counts]))
    proj, alphas = [], {}
    for order in ORDERS:
        rows = [r for r in counts if r["order"] == order and r["balance"] == "interactions"]
        by_weight = [r for r in counts if r["order"] == order and r["balance"] == "weight"]
        by_pairs = [r for r in counts if r["order"] == order and r["balance"] == "pairs"]
        kw = dict(latency=args.latency, bandwidth=args.bandwidth, order=order)
        base = D.project(rows, n_list, ranks, per_particle, **kw)
        nbr = D.project(rows, n_list, ranks, per_particle, exchange="neighbour", **kw)
        pw = D.project(by_weight, n_list, ranks, per_particle, **kw)
        pb = D.project(by_pairs, n_list, ranks, per_particle, **kw)
        proj += [dict(r, order=order, efficiency_neighbour_exchange=q["efficiency"],
                      efficiency_weight_balance=w["efficiency"], efficiency_pair_balance=b["efficiency"])
                 for r, q, w, b in zip(base, nbr, pw, pb)]
        alphas[order] = {str(p): D.fit_exponent(rows, "ghosts_max", p) for p in ranks}
    meta = {"latency_s": args.latency, "bandwidth_Bps": args.bandwidth, "s_per_particle_step": per_particle,
            "s_per_pair": per_pair, "cost_source": source,
            "ghost_exponent_alpha": alphas}
    write_atomic(args.out / "projection.json", json.dumps({"model": meta, "rows": proj}, indent=1) + "\n")
    write_atomic(args.out / "projection.md",
                 f"# Distributed runs projected (CLL)\n\nlatency {args.latency:g} s, bandwidth "
                 f"{args.bandwidth:g} B/s, {per_particle:.3g} s per particle-step ({source})\n\n" + table(proj))
    projection_figure(counts, proj, args.out)
    print(table(proj))
    return 0


if __name__ == "__main__":
    sys.exit(main())
