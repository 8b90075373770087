"""Synthetic experiments whose drift is known, to check harness/drift.py: the
unit tests, and `python3 -m harness.drift_model`, the coverage study quoted
in docs/MEASUREMENT.md ("Drift correction").

The model of a round on this VM: the repetitions of every configuration in a
random order (as the bench interleaves them), the log speed of the machine
an AR(1) process along that order (stationary standard deviation
`sd_drift`, lag-1 correlation `rho`), plus an offset per round and white
noise per repetition. Configuration c1 takes `ratio` times c0.
"""
import argparse
import sys

import numpy as np
import pandas as pd

from harness import drift as D
from harness import stats as S


def experiment(rng, configs=20, reps=3, rounds=3, sd_round=0.05, sd_drift=0.05, rho=0.8,
               sd_white=0.02, ratio=0.9, name="x"):
    """One experiment's rows as harness.results.load_run gives them."""
    mu = np.log(rng.uniform(0.5, 2.0, configs))
    mu[1] = mu[0] + np.log(ratio)
    rows = []
    for k in range(rounds):
        order = np.repeat(np.arange(configs), reps)
        rng.shuffle(order)
        d = np.empty(order.size)
        d[0] = rng.normal(0, sd_drift)
        for t in range(1, order.size):
            d[t] = rho * d[t - 1] + np.sqrt(1 - rho ** 2) * rng.normal(0, sd_drift)
        offset = rng.normal(0, sd_round)
        for t, c in enumerate(order):
            v = float(np.exp(mu[c] + offset + d[t] + rng.normal(0, sd_white)))
            rows.append({"experiment": name, "family": "step", "cfg": f"c{c}", "round": k,
                         "run_sequence": float(t), "repetition_index": t, "real_time_s": v,
                         "s_per_step": v / 10, "pairs_per_s": 1e6 / v, "witness_core_gflops": 50.0,
                         "nl_bytes": 1e6, "error_occurred": False})
    return pd.DataFrame(rows)


def ratio_ci(rows, resamples=200, seed=1):
    """(value, low, high) of median(c1) / median(c0), paired by round as the report reads it."""
    boot = S.RoundBootstrap(rows, resamples=resamples, seed=seed)

    def stat(m):
        return float(m.loc[m.cfg == "c1", "s_per_step"].iloc[0] / m.loc[m.cfg == "c0", "s_per_step"].iloc[0])
    return boot.interval(stat)


def coverage(experiments, seed=0, resamples=200, ratio=0.9, **model):
    """{"raw"|"corrected": (share of intervals covering `ratio`, median half-width %)}
    and the windows chosen, over `experiments` simulated experiments."""
    rng = np.random.default_rng(seed)
    hits = {"raw": 0, "corrected": 0}
    widths = {"raw": [], "corrected": []}
    windows = []
    for _ in range(experiments):
        rows = experiment(rng, ratio=ratio, **model)
        fixed, summary = D.corrected(rows)
        windows.append(summary["x"]["window"])
        for name, data in (("raw", rows), ("corrected", fixed)):
            _, lo, hi = ratio_ci(data, resamples)
            hits[name] += lo <= ratio <= hi
            widths[name].append(100 * (hi - lo) / 2 / ratio)
    out = {k: (hits[k] / experiments, float(np.median(widths[k]))) for k in hits}
    return out, windows


def main(argv=None):
    p = argparse.ArgumentParser(description="Coverage of round-paired 95 % intervals of a ratio, "
                                "from raw and drift-corrected times, in simulated experiments.")
    p.add_argument("--experiments", type=int, default=100, help="simulated experiments per row")
    p.add_argument("--rho", default="0,0.4,0.8", help="comma-separated lag-1 correlations of the drift")
    p.add_argument("--configs", type=int, default=20)
    args = p.parse_args(argv)
    print("| lag-1 of the drift | coverage raw | coverage corrected | half-width raw | "
          "half-width corrected | windows chosen |")
    print("|---|---|---|---|---|---|")
    for i, rho in enumerate(float(r) for r in args.rho.split(",")):
        out, windows = coverage(args.experiments, seed=i, rho=rho, configs=args.configs)
        chosen = pd.Series(["none" if w is None else str(w) for w in windows]).value_counts()
        print(f"| {rho:g} | {out['raw'][0]:.2f} | {out['corrected'][0]:.2f} | {out['raw'][1]:.1f} % | "
              f"{out['corrected'][1]:.1f} % | " + ", ".join(f"{k}: {v}" for k, v in chosen.items()) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
