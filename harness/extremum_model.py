"""How well intervals for the largest of several noisy values cover the true
largest: `python3 -m harness.extremum_model`, the study quoted in
docs/MEASUREMENT.md ("The largest of several values").

The model: K configurations with known true values (a gain per n_s), each
estimated with unit normal error, optionally sharing a common error (a
reference time all gains are taken against, correlation `rho`); bootstrap
replicates drawn around the estimates the same way. Four intervals for the
true largest:

- maximum: percentile interval of the replicates' maximum (what the claims
  did before);
- basic: 2 x estimate minus the maximum's quantiles (the textbook bias
  correction);
- at best: percentile interval of the single value the estimate picks;
- band: from harness.stats.simultaneous_band, [largest low end, largest
  high end] (what plots/claims.py uses).
"""
import argparse
import sys

import numpy as np

from harness import stats as S

SHAPES = {
    "flat": [12.0] * 9,
    "gentle": [8, 10, 11, 12, 12, 11.5, 11, 10, 9],
    "peaked": [5, 8, 10, 12, 9, 7, 6, 5, 4],
}
METHODS = ("maximum", "basic", "at best", "band")


def intervals(estimate, reps, level=S.LEVEL):
    """{method: (low, high)} for the largest of the columns."""
    best = estimate.max()
    lo, hi = S.percentile_interval(reps.max(axis=1), level)
    low, high = S.simultaneous_band(reps, level)
    return {"maximum": (lo, hi), "basic": (2 * best - hi, 2 * best - lo),
            "at best": S.percentile_interval(reps[:, int(estimate.argmax())], level),
            "band": (float(low.max()), float(high.max()))}


def study(truth, rho=0.0, experiments=1000, resamples=1000, seed=0):
    """{method: (coverage, mean width)} over simulated experiments."""
    rng = np.random.default_rng(seed)
    truth = np.asarray(truth, float)
    k = truth.size

    def noise(*shape):
        return np.sqrt(rho) * rng.standard_normal(shape[:-1] + (1,)) + \
            np.sqrt(1 - rho) * rng.standard_normal(shape)
    hits = dict.fromkeys(METHODS, 0)
    width = dict.fromkeys(METHODS, 0.0)
    for _ in range(experiments):
        estimate = truth + noise(k)
        reps = estimate + noise(resamples, k)
        for m, (lo, hi) in intervals(estimate, reps).items():
            hits[m] += lo <= truth.max() <= hi
            width[m] += hi - lo
    return {m: (hits[m] / experiments, width[m] / experiments) for m in METHODS}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--experiments", type=int, default=1000)
    ap.add_argument("--resamples", type=int, default=1000)
    args = ap.parse_args(argv)
    print("| true values | shared error | " + " | ".join(f"{m}: coverage, width" for m in METHODS) + " |")
    print("|---|---|" + "---|" * len(METHODS))
    for name, truth in SHAPES.items():
        for rho in (0.0, 0.5):
            res = study(truth, rho, args.experiments, args.resamples)
            print(f"| {name} | {rho:g} | " + " | ".join(f"{c:.2f}, {w:.1f}" for c, w in res.values()) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
