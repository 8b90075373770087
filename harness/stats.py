"""Bootstrap confidence intervals for sphnl's measurements.

Every number the report prints carries a 95 % interval (Hoefler & Belli,
"Scientific benchmarking of parallel computing systems", SC'15, rules 5-6:
report the spread, and use nonparametric intervals for the median, since run
times are not normal). The intervals are *percentile* bootstrap intervals:
BCa needs a jackknife estimate of the acceleration, and the jackknife of a
median is inconsistent (it moves by at most one order statistic), so BCa
adds noise, not accuracy, for the statistic every figure plots. Resampling
is seeded, so a report drawn twice from the same JSON is identical.

Two levels of resampling, matching how sphnl_bench measures (docs/CONTRACTS.md):

- `median_ci`: the median of plain samples (one configuration, one round),
  used by experiments/run.py to decide whether to add rounds.
- `RoundBootstrap`: the medians of many configurations at once, *paired by
  round*: each replicate draws the rounds of each experiment with
  replacement (the same draw for every configuration, so A and B measured in
  the same round stay together and drift between rounds cancels in A / B),
  then the repetitions inside each drawn round. A configuration that
  several experiments measured gets the mean of their medians. Any statistic of the
  per-configuration medians (a ratio, an improvement, a fitted exponent, a
  fraction of points) is evaluated on every replicate; its interval is the
  2.5 and 97.5 percentiles. Exponents thus resample each N's point from its
  own repetitions (the N values themselves are the design, not a sample).

Old results files have no round index: each of their repetitions counts as
its own round (they were separate timed windows; putting them all in one
round would resample nothing between rounds and claim false precision).
"""
import math
import warnings

import numpy as np
import pandas as pd

from harness.results import derive_columns, param_columns

LEVEL = 0.95
RESAMPLES = 1000
ROUND_COLS = ("round", "sphnl_round")  # the round an entry came from (absent in old files)
BOOKKEEPING = {"repetition_index", "round", "sphnl_round", "run_sequence"}
# The steps a repetition times is part of what it measures, so only windows
# of one length are pooled. In results/full-00f0b6f the same configurations
# took 13-23 % less per step over 84 steps (fig14) than over 10 or 21; that
# does not separate the window from drift between experiments (those of
# equal windows differ by -2 to +14 %), but pooling like with like needs no
# such separation.
WINDOW = "window_steps"
ROUND_ID = "_round_id"     # experiment:round, unique across a pooled data set
STRATUM = "_stratum"       # experiment the round belongs to: rounds are drawn within it


def percentile_interval(replicates, level=LEVEL):
    """(low, high) of the finite replicate values, or (nan, nan) if none."""
    r = np.asarray(replicates, float)
    r = r[np.isfinite(r)]
    if r.size == 0:
        return math.nan, math.nan
    lo, hi = np.percentile(r, [50 * (1 - level), 50 * (1 + level)])
    return float(lo), float(hi)


def simultaneous_band(replicates, level=LEVEL):
    """(low, high) arrays, one interval per column of `replicates` (B, K), that
    hold together: percentile intervals at the one per-column level at which
    a `level` share of the replicate rows lies wholly inside every column's
    interval. With one column this is percentile_interval; with K independent
    columns it approaches Bonferroni's, and correlated columns (a shared
    reference time) need less widening. Rows with a non-finite value are left
    out; none left gives NaN.

    Used for a claim about the largest of several values (the best n_s): if
    every true value lies in its interval, the largest lies between the
    largest low end and the largest high end."""
    r = np.asarray(replicates, float)
    r = r[np.all(np.isfinite(r), axis=1)]
    k = r.shape[1]
    if r.shape[0] == 0:
        return np.full(k, np.nan), np.full(k, np.nan)

    def band(tail):
        return np.quantile(r, tail, axis=0), np.quantile(r, 1.0 - tail, axis=0)

    def inside(tail):
        lo, hi = band(tail)
        return np.mean(np.all((r >= lo) & (r <= hi), axis=1))

    # Bisect the tail share of each column: 0 (the whole range, every row
    # inside) to the pointwise (1 - level) / 2. One row of slack: interpolated
    # quantiles of B rows can leave one row fewer than level * B inside.
    target = level - 1.0 / r.shape[0]
    fits, fails = 0.0, (1.0 - level) / 2
    if inside(fails) >= target:
        fits = fails
    else:
        for _ in range(30):
            mid = (fits + fails) / 2
            fits, fails = (mid, fails) if inside(mid) >= target else (fits, mid)
    return band(fits)


def median_ci(samples, level=0.95, seed=0, resamples=2000):
    """(median, low, high): percentile bootstrap interval of the median of `samples`.

    One sample gives a zero-width interval (nothing to resample); NaNs are dropped."""
    x = np.asarray(samples, float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan, math.nan
    med = float(np.median(x))
    if x.size == 1:
        return med, med, med
    rng = np.random.default_rng(seed)
    boot = np.median(x[rng.integers(0, x.size, size=(resamples, x.size))], axis=1)
    lo, hi = percentile_interval(boot, level)
    return med, lo, hi


def config_keys(df):
    """The columns that make rows of several experiments one configuration, to
    pool: the parameters, the flow state and the window length (WINDOW)."""
    keys = [k for k in param_columns(df) if k not in ("experiment", ROUND_ID, STRATUM) and k not in BOOKKEEPING]
    return keys + [k for k in ("flow_time", WINDOW) if k in df and k not in keys]


def with_round_ids(rows):
    """`rows` (harness.results.load_run) with the round identity columns that
    RoundBootstrap resamples. The unit is the entry's round (`round`, from the
    entry's `sphnl_round`); an experiment with a single round (every old file,
    which has no round index, and a one-round tiny run) resamples its
    repetitions instead, each its own unit: there is no between-round spread
    to draw from, and one unit would give a zero-width interval."""
    rows = rows.copy()
    exp = rows["experiment"].astype(str)
    rep = "rep" + rows["repetition_index"].fillna(0).astype(int).astype(str)
    col = next((c for c in ROUND_COLS if c in rows), None)
    if col is None:
        ids = rep
    else:
        rnd = rows[col].fillna(0).astype(int)
        several = rnd.groupby(exp).transform("nunique") > 1
        ids = rep.where(~several, "r" + rnd.astype(str))
    rows[ROUND_ID] = exp + ":" + ids
    rows[STRATUM] = exp
    return rows


class RoundBootstrap:
    """Per-configuration medians of `rows` and `resamples` bootstrap replicates of them.

    `rows`: raw repetitions (one row per iteration entry) with the columns of
    harness.results.load_run; `with_round_ids` is applied unless done already.
    `self.point` is the table of harness.results.medians (plus `flow_time`
    as a key where the rows have several flow states); `table(b)` is the
    same table with replicate b's medians."""

    def __init__(self, rows, resamples=RESAMPLES, seed=0, level=LEVEL):
        self.level, self.resamples = level, resamples
        if ROUND_ID not in rows:
            rows = with_round_ids(rows)
        ok = rows[~rows["error_occurred"].astype(bool)]
        keys = ["experiment"] + config_keys(ok)
        skip = set(keys) | BOOKKEEPING | {ROUND_ID, STRATUM, "run_name",
                            "error_message", "error_occurred"}
        self.numeric = [c for c in ok.columns if c not in skip and ok[c].dtype.kind in "iuf"]
        grouped = ok.groupby(keys, dropna=False, sort=True)
        # A configuration measured by several experiments: the mean of each
        # experiment's median. The median of all its repetitions would pick
        # the boundary between two experiments measured at different machine
        # speeds, moving a ratio outside every experiment's own value.
        med = (ok.groupby(keys + [STRATUM], dropna=False, sort=True)[self.numeric].median()
               .groupby(level=list(range(len(keys))), dropna=False, sort=True).mean().reset_index())
        for col in keys:  # integer axes read as float where other families lack them
            if med[col].dtype == float and med[col].notna().all() and (med[col] % 1 == 0).all():
                med[col] = med[col].astype(int)
        med["reps"] = grouped.size().values
        med["rounds"] = grouped[ROUND_ID].nunique().values
        self.point = derive_columns(med)
        if (med["reps"] == 1).all():  # one value per configuration: nothing to resample
            self.resamples = 1
            self.rep = med[self.numeric].to_numpy(float)[None, :, :]
        else:
            self.rep = self._replicates(ok, grouped, seed)  # (resamples, configurations, columns)

    # ------------------------------------------------------------ resampling
    def _replicates(self, ok, grouped, seed):
        rng = np.random.default_rng(seed)
        strata = {s: sorted(part.unique()) for s, part in ok.groupby(STRATUM)[ROUND_ID]}
        # One draw of rounds per stratum, shared by every configuration: the pairing.
        draws = {s: rng.integers(0, len(r), size=(self.resamples, len(r))) for s, r in strata.items()}
        values = ok[self.numeric].to_numpy(float)
        round_of = ok[ROUND_ID].to_numpy()
        stratum_of = ok[STRATUM].to_numpy()
        out = np.full((self.resamples, len(grouped), len(self.numeric)), np.nan)
        for g, positions in enumerate(grouped.indices.values()):
            rows_by_round = {}
            for pos in positions:
                rows_by_round.setdefault(round_of[pos], []).append(pos)
            mine = sorted({stratum_of[p] for p in positions})
            width = max(len(v) for v in rows_by_round.values())
            table, counts, slots, offset = [], [], [], 0
            for s in mine:
                for rid in strata[s]:
                    got = rows_by_round.get(rid, [])
                    table.append(got + [0] * (width - len(got)))
                    counts.append(len(got))
                slots.append(draws[s] + offset)
                offset += len(strata[s])
            table, counts = np.asarray(table), np.asarray(counts)
            slot = np.concatenate(slots, axis=1)                      # (B, R): drawn rounds
            c = counts[slot]                                          # repetitions in each
            pick = np.floor(rng.random(slot.shape + (width,)) * np.maximum(c, 1)[..., None]).astype(int)
            pos = table[slot[..., None], pick]                        # (B, R, width)
            v = values[pos]                                           # (B, R, width, C)
            v[c == 0] = np.nan                                        # a round without this configuration
            with warnings.catch_warnings():  # all-NaN slices (no such round drawn) stay NaN
                warnings.simplefilter("ignore", RuntimeWarning)
                per_stratum, start = [], 0   # each experiment's median, then their mean
                for s in mine:
                    part = v[:, start:start + len(strata[s])]
                    per_stratum.append(np.nanmedian(part.reshape(self.resamples, -1, len(self.numeric)),
                                                    axis=1))
                    start += len(strata[s])
                out[:, g, :] = np.nanmean(np.stack(per_stratum), axis=0)
        return out

    # ------------------------------------------------------------ evaluation
    def table(self, b):
        """The median table of replicate b (same rows and columns as `point`)."""
        fixed = getattr(self, "_fixed", None)
        if fixed is None:  # the columns no replicate changes, built once
            fixed = self._fixed = self.point.drop(columns=self.numeric + [
                c for c in ("t", "mem_mb", "N") if c in self.point])
        t = pd.concat([fixed, pd.DataFrame(self.rep[b], columns=self.numeric, index=fixed.index)],
                      axis=1)
        return derive_columns(t)

    def tables(self):
        """The replicate tables, built once if cache_tables was called."""
        cached = getattr(self, "_tables", None)
        return iter(cached) if cached is not None else (self.table(b) for b in range(self.resamples))

    def cache_tables(self):
        """Keep the replicate tables: many statistics of the same rows then
        share them (each costs ~2 ms to build)."""
        if getattr(self, "_tables", None) is None:
            self._tables = [self.table(b) for b in range(self.resamples)]

    def subset(self, mask):
        """A RoundBootstrap restricted to the configurations where `mask`
        (boolean, aligned with self.point) is true."""
        sub = object.__new__(RoundBootstrap)
        sub.level, sub.resamples, sub.numeric = self.level, self.resamples, self.numeric
        idx = np.flatnonzero(np.asarray(mask, bool))
        sub.point = self.point.iloc[idx].reset_index(drop=True)
        sub._fixed = None
        sub.rep = self.rep[:, idx, :]
        return sub

    def evaluate(self, fn):
        """(fn(point), array of fn(table(b))): a replicate on which fn raises
        or returns a non-finite value contributes NaN and is left out of the interval."""
        point = fn(self.point)
        shape = np.shape(point)
        reps = np.full((self.resamples,) + shape, np.nan)
        for b, tab in enumerate(self.tables()):
            try:
                reps[b] = fn(tab)
            except Exception:  # noqa: BLE001 - a replicate missing a point is NaN, not a crash
                pass
        return point, reps

    def interval(self, fn):
        """(value, low, high) of a scalar statistic fn(median table)."""
        point, reps = self.evaluate(fn)
        lo, hi = percentile_interval(reps, self.level)
        return float(point), lo, hi


def intervals(reps, level=LEVEL):
    """Element-wise (low, high) arrays of replicate arrays shaped (B, ...)."""
    reps = np.asarray(reps, float)
    lo = np.full(reps.shape[1:], np.nan)
    hi = np.full(reps.shape[1:], np.nan)
    for idx in np.ndindex(*reps.shape[1:]):
        lo[idx], hi[idx] = percentile_interval(reps[(slice(None),) + idx], level)
    return lo, hi


def paired_ratio_ci(a_rounds, b_rounds, level=LEVEL, seed=0, resamples=RESAMPLES,
                    improvement=False):
    """(value, low, high) of median(A) / median(B), or with improvement=True of
    100 (median(B) - median(A)) / median(B), the paper's improvement of A over
    the reference B, resampled paired by round: `a_rounds[k]` and `b_rounds[k]`
    are the repetitions of A and B measured in round k. The same machinery as
    RoundBootstrap (it is built on it), for callers with plain lists."""
    import pandas as pd
    rows = []
    for cfg, per_round in (("a", a_rounds), ("b", b_rounds)):
        for k, values in enumerate(per_round):
            for i, v in enumerate(np.atleast_1d(values)):
                rows.append({"experiment": "x", "family": "f", "cfg": cfg, "round": k,
                             "repetition_index": i, "value": float(v), "error_occurred": False})
    boot = RoundBootstrap(pd.DataFrame(rows), resamples=resamples, seed=seed, level=level)

    def stat(med):
        a = float(med.loc[med["cfg"] == "a", "value"].iloc[0])
        b = float(med.loc[med["cfg"] == "b", "value"].iloc[0])
        return 100.0 * (b - a) / b if improvement else a / b
    return boot.interval(stat)
