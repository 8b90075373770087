#!/usr/bin/python3
"""Where a results file's scatter comes from, and how much pairing removes.

    /usr/bin/python3 -m plots.noise results/<run>/<experiment>.json
    /usr/bin/python3 -m plots.noise results/<run>/fig14.json --pair list=cll --any list_steps

Reads one experiment's benchmark JSON (every repetition with its round and
its place in the round's run order, docs/CONTRACTS.md) and prints:

1. the scatter of identical configurations: the coefficient of variation of
   the repetitions inside one round (median over configurations and rounds)
   against that of a configuration's round medians (drift between rounds);
2. whether the noise inside a round is slow: the lag-1 autocorrelation of
   the repetitions' residuals (log value minus its configuration's mean in
   that round) in run order, and their rank correlation with the machine
   witnesses measured beside each repetition;
3. with --pair KEY=VALUE, every other configuration against its baseline
   (the configurations with KEY=VALUE and the same parameters, apart from the
   --any keys): the ratio of medians paired by round, as the report reads it,
   beside each repetition paired with the baseline repetition nearest to it
   in the same round's run order; the 95 % interval of both (rounds and then
   repetitions resampled), and the repetitions per configuration each would
   need for an interval of +-2 % (half-widths shrink as one over the square
   root of the repetitions).

Nothing here changes a verdict: it measures what a finer pairing would buy.
--out writes the same numbers as JSON.
"""
import argparse
import json
import math
import pathlib
import sys

import numpy as np
import pandas as pd

from harness import stats as S
from harness.fsio import write_atomic
from harness.results import BOOKKEEPING, ResultsError, entry_rows, param_columns, parse_value, read_benchmark_json

WITNESSES = ("witness_core_gflops", "witness_mem_gbps")
TARGET_HALFWIDTH_PCT = 2.0


def load(path, metric=None):
    """(rows, metric): one row per repetition with its configuration's
    parameters, `value`, `round` and `run_sequence`."""
    doc = read_benchmark_json(path)
    df = pd.DataFrame(entry_rows(doc, pathlib.Path(path).stem))
    if df.empty:
        raise ResultsError(f"{path}: no repetitions in the file")
    df = df[~df["error_occurred"]]
    metric = metric or (doc.get("sphnl_protocol") or {}).get("metric") or "real_time_s"
    if metric not in df.columns:
        raise ResultsError(f"{path}: no column '{metric}' (choose one with --metric)")
    if "run_sequence" not in df.columns:
        raise ResultsError(f"{path}: its repetitions carry no run_sequence (measured before the "
                           "protocol); the run order this analysis needs is unknown")
    df = df.assign(value=df[metric].astype(float))
    return df[np.isfinite(df["value"]) & (df["value"] > 0)].copy(), metric


def config_columns(df):
    return [c for c in param_columns(df) if c not in BOOKKEEPING]


def scatter(df):
    """CVs within a round and between rounds, and the slowness of the noise."""
    keys = config_columns(df)
    by = df.groupby(keys + ["round"])["value"]
    within = (by.std(ddof=1) / by.mean()).dropna()
    round_medians = by.median().unstack("round")
    between = (round_medians.std(axis=1, ddof=1) / round_medians.mean(axis=1)).dropna()
    log_v = np.log(df["value"])
    resid = log_v - log_v.groupby([df[k] for k in keys + ["round"]]).transform("mean")
    df = df.assign(resid=resid)
    lag1 = []
    for _, r in df.sort_values("run_sequence").groupby("round"):
        x = r["resid"].to_numpy()
        if x.size > 3 and np.std(x) > 0:
            lag1.append(float(np.corrcoef(x[:-1], x[1:])[0, 1]))
    out = {
        "configurations": int(df.groupby(keys).ngroups),
        "rounds": int(df["round"].nunique()),
        "within_round_cv_pct": 100 * float(within.median()) if len(within) else math.nan,
        "between_round_cv_pct": 100 * float(between.median()) if len(between) else math.nan,
        "lag1_autocorrelation": float(np.median(lag1)) if lag1 else math.nan,
    }
    for w in WITNESSES:
        if w in df.columns and df[w].notna().sum() > 3 and df[w].nunique() > 1:
            out[f"rank_correlation_{w}"] = float(df["resid"].corr(df[w], method="spearman"))
    return out


def _select(df, pair):
    key, sep, value = pair.partition("=")
    if not sep or key not in df.columns:
        raise ResultsError(f"--pair {pair!r}: expected KEY=VALUE with KEY one of "
                           f"{', '.join(config_columns(df))}")
    is_base = df[key] == parse_value(value)
    if not is_base.any():
        raise ResultsError(f"--pair {pair!r}: no configuration has {key} = {value} "
                           f"(values: {', '.join(map(str, sorted(df[key].unique(), key=str)))})")
    return key, is_base


def _median_ci(rounds, resamples, seed):
    """(median, low, high) of the pooled values given one array per round,
    resampled as the report does (harness.stats.RoundBootstrap: rounds with
    replacement, then the values inside each drawn round)."""
    rows = pd.DataFrame([{"experiment": "x", "family": "f", "round": k, "repetition_index": i,
                          "value": float(v), "error_occurred": False}
                         for k, values in enumerate(rounds) for i, v in enumerate(values)])
    boot = S.RoundBootstrap(rows, resamples=resamples, seed=seed)
    return boot.interval(lambda med: float(med["value"].iloc[0]))


def pairing(df, pair, any_keys=(), resamples=S.RESAMPLES, seed=0):
    """One row per compared configuration: the ratio to its baseline paired
    by round and paired with the nearest baseline repetition."""
    key, is_base = _select(df, pair)
    for k in any_keys:
        if k not in df.columns:
            raise ResultsError(f"--any {k}: not a parameter of this file "
                               f"({', '.join(config_columns(df))})")
    keys = config_columns(df)
    match = [k for k in keys if k != key and k not in any_keys]
    base, others = df[is_base], df[~is_base]
    rows = []
    for cfg, x in others.groupby(keys):
        cfg = dict(zip(keys, cfg))
        b = base
        for k in match:
            b = b[b[k] == cfg[k]]
        common = sorted(set(x["round"]) & set(b["round"]))
        if not common:
            continue
        a_rounds = [x.loc[x["round"] == r, "value"].to_numpy() for r in common]
        b_rounds = [b.loc[b["round"] == r, "value"].to_numpy() for r in common]
        value, lo, hi = S.paired_ratio_ci(a_rounds, b_rounds, resamples=resamples, seed=seed)
        nearest = []
        for r in common:
            xr, br = x[x["round"] == r], b[b["round"] == r]
            seq_b, val_b = br["run_sequence"].to_numpy(), br["value"].to_numpy()
            nearest.append(np.array([v / val_b[np.argmin(np.abs(seq_b - s))]
                                     for s, v in zip(xr["run_sequence"], xr["value"])]))
        n_value, n_lo, n_hi = _median_ci(nearest, resamples, seed)
        n_reps = int(sum(len(a) for a in a_rounds))
        rows.append({**cfg, "repetitions": n_reps,
                     "by_round": value, "by_round_low": lo, "by_round_high": hi,
                     "nearest": n_value, "nearest_low": n_lo, "nearest_high": n_hi})
    if not rows:
        raise ResultsError(f"--pair {pair}: no configuration shares a round with a baseline")
    out = pd.DataFrame(rows)
    for m in ("by_round", "nearest"):
        hw = 100 * (out[f"{m}_high"] - out[f"{m}_low"]) / 2 / out[m]
        out[f"{m}_halfwidth_pct"] = hw
        out[f"{m}_reps_for_target"] = np.ceil(out["repetitions"] * (hw / TARGET_HALFWIDTH_PCT) ** 2)
    return out


def _fmt(v, digits=3):
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{digits}g}"


def markdown(path, metric, sc, pairs, pair, any_keys):
    lines = [f"# Noise in {path} ({metric})", "",
             f"{sc['configurations']} configurations, {sc['rounds']} rounds.", "",
             "| measure | value |", "|---|---|",
             f"| CV of identical repetitions inside a round (median) | {_fmt(sc['within_round_cv_pct'])} % |",
             f"| CV of a configuration's round medians (median) | {_fmt(sc['between_round_cv_pct'])} % |",
             f"| lag-1 autocorrelation of residuals in run order (median over rounds) | "
             f"{_fmt(sc['lag1_autocorrelation'], 2)} |"]
    for w in WITNESSES:
        if f"rank_correlation_{w}" in sc:
            lines.append(f"| rank correlation of residuals with {w} | {_fmt(sc[f'rank_correlation_{w}'], 2)} |")
    if pairs is not None:
        keys = [c for c in pairs.columns if c not in {
            "repetitions", "by_round", "by_round_low", "by_round_high", "nearest", "nearest_low",
            "nearest_high", "by_round_halfwidth_pct", "nearest_halfwidth_pct",
            "by_round_reps_for_target", "nearest_reps_for_target"}
                and (c == pair.partition("=")[0] or pairs[c].nunique() > 1)]
        lines += ["", f"Against the baseline {pair}" + (f" (any {', '.join(any_keys)})" if any_keys else "")
                  + ": ratio [95 % interval], half-width, repetitions for ±2 %.", "",
                  "| " + " | ".join(keys) + " | reps | paired by round | ± % | reps for ±2 % "
                  "| nearest in run order | ± % | reps for ±2 % |",
                  "|" + "---|" * (len(keys) + 7)]
        for _, r in pairs.iterrows():
            lines.append("| " + " | ".join(str(r[k]) for k in keys) + f" | {r['repetitions']} | "
                         f"{r['by_round']:.3f} [{r['by_round_low']:.3f}, {r['by_round_high']:.3f}] | "
                         f"{r['by_round_halfwidth_pct']:.1f} | {r['by_round_reps_for_target']:.0f} | "
                         f"{r['nearest']:.3f} [{r['nearest_low']:.3f}, {r['nearest_high']:.3f}] | "
                         f"{r['nearest_halfwidth_pct']:.1f} | {r['nearest_reps_for_target']:.0f} |")
        lines += ["", f"Median half-width: paired by round {pairs['by_round_halfwidth_pct'].median():.1f} %, "
                  f"nearest in run order {pairs['nearest_halfwidth_pct'].median():.1f} %."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("results", type=pathlib.Path, help="results/<run>/<experiment>.json")
    p.add_argument("--metric", help="column to analyse (default: the file's protocol metric)")
    p.add_argument("--pair", help="KEY=VALUE selecting the baseline configurations, e.g. list=cll")
    p.add_argument("--any", default="", help="comma-separated keys in which the baseline may differ "
                   "(e.g. list_steps: CLL ignores n_s)")
    p.add_argument("--resamples", type=int, default=S.RESAMPLES)
    p.add_argument("--out", type=pathlib.Path, help="also write the numbers as JSON")
    args = p.parse_args(argv)
    any_keys = [k for k in args.any.split(",") if k]
    if any_keys and not args.pair:
        p.error("--any needs --pair")
    try:
        df, metric = load(args.results, args.metric)
        sc = scatter(df)
        pairs = pairing(df, args.pair, any_keys, args.resamples) if args.pair else None
    except ResultsError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(markdown(args.results, metric, sc, pairs, args.pair, any_keys), end="")
    if args.out:
        doc = {"file": str(args.results), "metric": metric, "scatter": sc,
               "pairs": [] if pairs is None else json.loads(pairs.to_json(orient="records"))}
        write_atomic(args.out, json.dumps(doc, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
