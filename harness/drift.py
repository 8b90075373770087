"""The machine's drift inside a round, estimated from the repetitions that ran
next to each one and divided out of its times (docs/MEASUREMENT.md, "Drift
correction").

On the shared VMs sphnl is measured on, identical repetitions inside one
round scatter by 3-6 %, successive repetitions in run order are correlated
(lag-1 autocorrelation 0.2-0.5) and follow the machine witness: the machine
speeds up and slows down over seconds to minutes, for every configuration
alike. Pairing A and B by round does not cancel that; pairing each
repetition with its neighbours in run order does (plots/noise.py measures
both). Because the bench interleaves the configurations of a round at
random, the neighbours of a repetition are a random mix of configurations,
so their residuals (log time minus their own configuration's mean) measure
the machine's state at that moment and nothing about the configuration in
between. Each repetition's times are divided by exp(mean residual of its k
neighbours on each side, itself left out): a leave-one-out estimate, so a
repetition's own noise never corrects itself, and in expectation the
correction is 1 for every configuration (no ratio is biased, only its
scatter shrinks).

Between experiments, measured hours apart, the machine's level differs too,
and a configuration several experiments measured is pooled: each
experiment's times are then divided by its level against the others, the
median over the configurations it shares of its median over their mean
(`levels`; no ratio inside an experiment changes).

The window k is chosen per experiment as the one (of WINDOWS, or none) that
leaves the smallest scatter of the corrected residuals, a held-out measure
since each estimate excludes the value it corrects. An experiment whose
repetitions carry no run order (results measured before the protocol), or
where no window beats leaving the times alone, is left as measured.
The raw values stay in the results files; this is a derived view.
"""
import math

import numpy as np

from harness.stats import config_keys

WINDOWS = (1, 2, 4, 8, 16)       # neighbours on each side of a repetition
# The time whose residuals measure the machine: per step where the family
# has steps (experiments time windows of different lengths, 10 to 84 steps,
# and pool their configurations per step), else the timed call.
PER_STEP, RESIDUAL_OF = "s_per_step", "real_time_s"
# Columns that scale with the machine's speed: times are divided by the
# factor, rates multiplied. Witnesses, counts, bytes and fractions are left alone.
TIME_PREFIX = "s_"
TIME_COLUMNS = ("real_time_s", "cpu_time_s")
RATE_COLUMNS = ("pairs_per_s", "entries_per_s", "force_gflops", "force_peak_fraction")
FACTOR = "drift_factor"          # the factor divided out, kept as a column of the view


def time_columns(rows):
    return [c for c in rows.columns if (c in TIME_COLUMNS or c.startswith(TIME_PREFIX))
            and rows[c].dtype.kind == "f"]


def rate_columns(rows):
    return [c for c in RATE_COLUMNS if c in rows.columns and rows[c].dtype.kind == "f"]


def neighbour_mean(values, k):
    """Leave-one-out mean of up to k values on each side of every position."""
    values = np.asarray(values, float)
    n = values.size
    if n < 2:
        return np.zeros(n)
    csum = np.concatenate([[0.0], np.cumsum(values)])
    idx = np.arange(n)
    lo, hi = np.maximum(0, idx - k), np.minimum(n, idx + k + 1)
    total = csum[hi] - csum[lo] - values
    return total / (hi - lo - 1)


def _residuals(rows):
    """log time minus the mean over its configuration's repetitions (in `rows`:
    one experiment's)."""
    keys = config_keys(rows)
    log_t = np.log(_time(rows))
    return log_t - log_t.groupby([rows[k] for k in keys], dropna=False).transform("mean")


def _estimates(rows, resid, k):
    """The leave-one-out drift estimate of every row (aligned with rows)."""
    est = np.zeros(len(rows))
    order = rows.assign(_r=resid.to_numpy(), _i=np.arange(len(rows))).sort_values("run_sequence")
    for _, one in order.groupby("round", sort=False):
        est[one["_i"].to_numpy()] = neighbour_mean(one["_r"].to_numpy(), k)
    return est


def _time(rows):
    t = rows[RESIDUAL_OF].astype(float)
    if PER_STEP in rows:
        per_step = rows[PER_STEP].astype(float)
        t = per_step.where(np.isfinite(per_step) & (per_step > 0), t)
    return t


def usable(rows):
    """Rows of one experiment the correction can use: measured with a run
    order, without error, with a positive time."""
    if "run_sequence" not in rows or RESIDUAL_OF not in rows:
        return rows.iloc[0:0]
    ok = ~rows["error_occurred"].astype(bool) & rows["run_sequence"].notna()
    t = _time(rows)
    return rows[ok & np.isfinite(t) & (t > 0)]


def choose_window(use, windows=WINDOWS):
    """(k or None, {k: scatter %}, log drift estimate of every row) for one
    experiment's usable rows: the scatter is the standard deviation, in
    percent, of the residuals left after dividing by the window's estimate
    (None: no correction, an estimate of 0)."""
    if len(use) < 4 or use["round"].value_counts().max() < 3:
        return None, {}, np.zeros(len(use))
    resid = _residuals(use)
    estimates = {None: np.zeros(len(use))}
    estimates.update((k, _estimates(use, resid, k)) for k in windows)
    scatter = {k: 100.0 * float(np.std(resid.to_numpy() - e)) for k, e in estimates.items()}
    best = min(scatter, key=lambda k: (scatter[k], k is not None))
    return best, scatter, estimates[best]


def levels(rows):
    """{experiment: log factor} that brings each experiment to the common
    level of the configurations it shares with others: the median, over
    those configurations, of the log of its median over the mean of every
    experiment's log median. An experiment that shares none is left out."""
    t = _time(rows)
    keep = ~rows["error_occurred"].astype(bool) & np.isfinite(t) & (t > 0)
    use = rows[keep]
    if use.empty:
        return {}
    log_med = np.log(t[keep]).groupby([use[k] for k in config_keys(use)] + [use["experiment"]],
                                      dropna=False).median()
    table = log_med.unstack("experiment")
    shared = table[table.notna().sum(axis=1) > 1]
    offset = shared.sub(shared.mean(axis=1), axis=0)
    return {e: float(offset[e].median()) for e in offset.columns if offset[e].notna().any()}


def corrected(rows, windows=WINDOWS):
    """(rows with every time divided by its drift factor and every rate
    multiplied by it, {experiment: {"window", "scatter_pct_before",
    "scatter_pct_after", "repetitions", "level_pct"}}); level_pct is None for
    an experiment that shares no configuration with another.

    Two steps. Inside each experiment, each repetition's drift from its
    neighbours in run order (choose_window). Then between experiments, the
    level: a configuration several experiments measured is pooled, and an
    experiment measured hours later on a slower machine would move the pooled
    value of only the configurations it shares; every time of an experiment
    is divided by its level (`levels`, from the shared configurations), which
    changes no ratio inside it. Rows the correction cannot use keep their
    values and a factor of 1."""
    out = rows.copy() if rows.index.is_unique else rows.reset_index(drop=True)
    out[FACTOR] = 1.0
    summary = {}
    if out.empty or "experiment" not in out:
        return out, summary
    used = []
    for exp, part in out.groupby("experiment", sort=True):
        use = usable(part)
        k, scatter, estimate = choose_window(use, windows)
        used.append(use.index)
        summary[exp] = {"window": k, "scatter_pct_before": scatter.get(None, math.nan),
                        "scatter_pct_after": scatter.get(k, math.nan), "repetitions": int(len(use)),
                        "level_pct": None}
        out.loc[use.index, FACTOR] = np.exp(estimate)
    inside = out.loc[np.concatenate(used)].copy()
    for col in (RESIDUAL_OF, PER_STEP):  # the times as corrected so far
        if col in inside:
            inside[col] = inside[col] / inside[FACTOR]
    for exp, log_f in levels(inside).items():
        summary[exp]["level_pct"] = 100.0 * math.expm1(log_f)
        out.loc[inside.index[inside["experiment"] == exp], FACTOR] *= math.exp(log_f)
    factor = out[FACTOR].to_numpy()
    times, rates = time_columns(out), rate_columns(out)
    out[times] = out[times].to_numpy(float) / factor[:, None]
    if rates:
        out[rates] = out[rates].to_numpy(float) * factor[:, None]
    return out, summary
