"""The paper's quantitative claims, measured on our results, with intervals.

Each claim of experiments/<id>.json ("claims": id, text, paper_value, unit,
optional at_n / min_n / tie_within, tolerance {"reproduced": [lo, hi],
"partly": [lo, hi]}, band_reason, source) has one function here, registered
under its id. The function gets a per-configuration median table
(harness.results.medians) and returns (value, note) or (value, note,
{related metric: value}), or raises NotMeasured. A value is a number,
`Margins` for claims that count the points where one configuration beats
another, or `Extremum` for claims about the largest of several values (the
best n_s), whose interval comes from a simultaneous band.

`evaluate` measures the claim with an interval (harness.stats.RoundBootstrap:
the function runs on every bootstrap replicate of the medians, resampled
paired by round) and gives the verdict of `verdict`:

- reproduced: the whole interval inside the reproduced band;
- partly: the whole interval inside the partly band, not wholly in the reproduced one;
- not reproduced: the whole interval outside the partly band;
- unresolved: otherwise, with what would resolve it;
- not measured: the data cannot support the claim (e.g. a tiny run).

Pooled estimates: a configuration measured in several experiments (CLL at
n_s = 7 in Figs. 16, 17 and the thread study, say) enters every claim with
all its repetitions; each experiment's rounds are resampled within that
experiment. The value of each experiment alone is reported beside it.
Flow states: where the rows hold several `flow_time` values, the claim is
measured per state and the value is the mean over the states (each state
weighs the same, whatever its repetitions).
Improvement is the paper's (t_ref - t) / t_ref in percent.
"""
import functools
import math

import numpy as np
import pandas as pd

from harness import stats as S
from harness.results import ResultsError, format_n, idle_seconds, pages_used, pick

MIN_N = 5000  # a claim about performance needs at least this N in the run
CLAIMS = {}
VERDICTS = ("reproduced", "partly", "not reproduced", "unresolved", "not measured")


class NotMeasured(Exception):
    """The results cannot support this claim; the message says why."""


class Margins:
    """Per-point margins (indexed by the point, e.g. N) of a claim that counts
    where one configuration beats another: positive = the claim holds there.
    Each is relative (e.g. (t_other - t) / t_other), so a claim's
    `tie_within` (default 0) is a relative tolerance."""

    def __init__(self, margins, what):
        self.margins = pd.Series(margins, dtype=float)
        self.what = what


class Extremum:
    """Per-point values (indexed by the point, e.g. n_s) of a claim about the
    largest of them: its value is the largest (`of="max"`) or where it lies
    (`of="argmax"`); the other is reported as the related metric `other`.
    `of="min"` is the mirror image: the smallest value (a claim that every
    point reaches a target), its interval from the same band.

    The interval is not the bootstrap of the maximum: each replicate's
    maximum picks whichever point drew high, so over points close together
    (a flat optimum) the replicates sit above the estimate, which itself sits
    above the true largest, and the 95 % interval can miss it nearly always.
    Instead the values get a simultaneous band (harness.stats.simultaneous_band):
    if every true value lies in its interval, the true largest lies between the
    largest low end and the largest high end, and at one of the points whose
    high end reaches that largest low end (the contenders)."""

    def __init__(self, values, what, of="max", other=None):
        if of not in ("max", "argmax", "min"):
            raise ValueError(f"Extremum of={of!r}; allowed: max, argmax, min")
        if of == "min" and other:
            raise ValueError("Extremum of='min' reports no other metric")
        self.values = pd.Series(values, dtype=float)
        self.what, self.of, self.other = what, of, other


def claim(claim_id):
    def register(fn):
        CLAIMS[claim_id] = fn
        return fn
    return register


# ------------------------------------------------------------------- helpers
# The N each _at call chose since the last reset: Evaluator.claim records
# the N a claim was read at (claims.json `at_n`), which is the definition's
# at_n only where the run measured it.
_READ_AT = []


def _at(med, c):
    """The N to measure a claim at: its at_n when measured, else the largest."""
    ns = sorted(med["particles"].dropna().unique())
    want = c.get("at_n")
    n = want if want in ns else ns[-1]
    _READ_AT.append(float(n))
    if want and n != want:
        return n, f"N = {format_n(n)} (paper: N = {format_n(want)})"
    return n, f"N = {format_n(n)}"


def _row(med, **equal):
    """The first configuration matching `equal`, or NotMeasured."""
    rows = pick(med, **equal)
    if rows.empty:
        raise NotMeasured("no run with " + ", ".join(f"{k}={v}" for k, v in equal.items()))
    return rows.iloc[0]


def _one(med, col="t", **equal):
    return float(_row(med, **equal)[col])


def _series(med, col="t", x="N", **equal):
    """Values of `col` indexed by `x` (default: particles simulated) for the runs matching `equal`."""
    rows = pick(med, **equal).sort_values(x)
    return rows.set_index(x)[col].astype(float)


def _need_points(values, k, what):
    if len(values) < k:
        raise NotMeasured(f"needs at least {k} {what}, the run has {len(values)}")


def _gain(med, n, ref, var):
    """Improvement of `var` over `ref` at N = n (two row look-ups: this runs on
    every bootstrap replicate, where a merge would dominate the report's time)."""
    a, b = pick(med, **{**ref, "particles": n}), pick(med, **{**var, "particles": n})
    if a.empty or b.empty:
        raise NotMeasured(f"no pair {ref} / {var} at N = {format_n(n)}")
    t_ref, t = float(a["t"].iloc[0]), float(b["t"].iloc[0])
    return 100.0 * (t_ref - t) / t_ref


def _gain_series(med, ref, var, on, x):
    """Improvements of `var` over `ref` matched on column `on`, indexed by `x` of `var`."""
    a = pick(med, **ref).drop_duplicates(on).set_index(on)["t"]
    b = pick(med, **var).drop_duplicates(on).set_index(on)
    common = b.index.intersection(a.index)
    imp = 100.0 * (a[common] - b.loc[common, "t"]) / a[common]
    xs = common.to_numpy() if x == on else b.loc[common, x].to_numpy()
    return pd.Series(imp.to_numpy(float), index=xs).sort_index()


def _exponent(s):
    """k of the least-squares fit log y = log a + k log N."""
    return float(np.polyfit(np.log(s.index.to_numpy(float)), np.log(s.to_numpy(float)), 1)[0])


def _margins(values, what):
    if len(values) == 0:
        raise NotMeasured(f"no {what} measured")
    return Margins(values, what)


def _rel(other, mine):
    """Relative margin of `mine` below `other`: positive when mine is smaller."""
    return (other - mine) / other


# ------------------------------------------------------------------- Table I
def _share(med, c, lst, col):
    n = med["particles"].max()
    row = _row(med, particles=n, list=lst, list_steps=1, kgc=0)
    total = row["s_neighbour_list"] + row["s_force"] + row["s_update"]
    return 100 * row[col] / total, f"N = {format_n(n)}, share of the three timed phases"


for _lst, _key in (("cll", "cll"), ("vlc", "vl")):
    for _ph, _col in (("list", "s_neighbour_list"), ("force", "s_force"), ("update", "s_update")):
        CLAIMS[f"table1_{_key}_{_ph}"] = functools.partial(_share, lst=_lst, col=_col)


# --------------------------------------------------------- Fig. 6-11 gridders
def _times(med, n, col="t", **equal):
    return {g: _one(med, col, particles=n, gridder=g, **equal) for g in "ABCD"}


@claim("A_slower_3x")
def a_slower_3x(med, c):
    n, note = _at(med, c)
    t = _times(med, n, reorder=0)
    return t["A"] / max(t["B"], t["C"], t["D"]), note


@claim("A_superlinear")
def a_superlinear(med, c):
    """Section 3.1: A's runtime grows faster with N than the others'. The
    exponent of t_A / t_B separates A from the common growth of all four
    (B-D alone grow as N^1.3 here: the interactions per particle rise with N)."""
    a = _series(med, gridder="A", reorder=0)
    b = _series(med, gridder="B", reorder=0)
    common = a.index.intersection(b.index)
    _need_points(common, 3, "values of N with both A and B")
    ks = {g: _exponent(_series(med, gridder=g, reorder=0)) for g in "ABCD"}
    return (_exponent(a[common] / b[common]),
            f"(t_A / t_B) ∝ N^k over N = {format_n(common.min())}..{format_n(common.max())}",
            {f"k_{g}": ks[g] for g in "ABCD"})


def _d_vs(med, c, other):
    n, note = _at(med, c)
    t = _times(med, n, reorder=0)
    fastest = min(t, key=t.get)
    return 100 * (t[other] - t["D"]) / t[other], f"{note}; fastest unsorted: {fastest}"


for _g in "ABC":
    CLAIMS[f"D_vs_{_g}_unsorted"] = functools.partial(_d_vs, other=_g)


@claim("C_memory_20x")
def c_memory_20x(med, c):
    n = med["particles"].max()
    m = _times(med, n, "nl_bytes", reorder=0)
    return m["C"] / max(m["A"], m["B"], m["D"]), f"N = {format_n(n)}"


@claim("A_least_memory")
def a_least_memory(med, c):
    margins = {}
    for n in sorted(med["particles"].unique()):
        m = _times(med, n, "nl_bytes", reorder=0)
        margins[n] = _rel(min(m["B"], m["C"], m["D"]), m["A"])
    return _margins(margins, "values of N where A needs least"), "margin: (min of B-D − A) / min of B-D"


def _memory_at(med, c, gridder):
    """MB at the claim's N, extrapolated linearly (bytes per particle) if not run."""
    n, note = _at(med, c)
    row = _row(med, particles=n, gridder=gridder, reorder=0)
    per = row["nl_bytes"] / row["N"]
    if n == c["at_n"]:
        return row["nl_bytes"] / 1e6, f"{note}, {per:.1f} B/particle"
    return per * c["at_n"] / 1e6, (f"extrapolated linearly from N = {format_n(row['N'])} "
                                   f"({per:.1f} B/particle)")


for _g in "CD":
    CLAIMS[f"{_g}_memory_150k"] = functools.partial(_memory_at, gridder=_g)


def _reorder_gains(med, n):
    return {g: _gain(med, n, {"gridder": g, "reorder": 0}, {"gridder": g, "reorder": 1})
            for g in "ABCD"}


@claim("reorder_gain_BCD")
def reorder_gain_bcd(med, c):
    n, note = _at(med, c)
    g = _reorder_gains(med, n)
    return min(g["B"], g["C"], g["D"]), note + "; smallest of B, C, D", {f"gain_{k}": v for k, v in g.items()}


@claim("reorder_gain_A")
def reorder_gain_a(med, c):
    n, note = _at(med, c)
    return _reorder_gains(med, n)["A"], note


@claim("D_lowest_gain")
def d_lowest_gain(med, c):
    n, note = _at(med, c)
    g = _reorder_gains(med, n)
    return g["D"] - min(g["A"], g["B"], g["C"]), note + "; D's gain minus the smallest other", \
        {f"gain_{k}": v for k, v in g.items()}


@claim("BCD_equal_after_reorder")
def bcd_equal_after_reorder(med, c):
    n, note = _at(med, c)
    t = _times(med, n, reorder=1)
    bcd = [t["B"], t["C"], t["D"]]
    return 100 * (max(bcd) - min(bcd)) / min(bcd), note


@claim("A_2x_after_reorder")
def a_2x_after_reorder(med, c):
    n, note = _at(med, c)
    t = _times(med, n, reorder=1)
    return t["A"] / float(np.median([t["B"], t["C"], t["D"]])), note


@claim("B_less_memory_than_D_reordered")
def b_less_memory_than_d(med, c):
    n, note = _at(med, c)
    return _one(med, "nl_bytes", particles=n, gridder="B", reorder=1) / \
        _one(med, "nl_bytes", particles=n, gridder="D", reorder=1), note


# ---------------------------------------------------------- Fig. 9, orderings
@claim("sortx_beats_zorder")
def sortx_beats_zorder(med, c):
    n, note = _at(med, c)
    g = {o: _gain(med, n, {"cell_order": o, "reorder": 0}, {"cell_order": o, "reorder": 1})
         for o in ("sort_x", "sort_xy", "sort_xyz")}
    return g["sort_x"] - max(g["sort_xy"], g["sort_xyz"]), \
        f"{note}; SortX's gain minus the larger Z-order gain", {f"gain_{k}": v for k, v in g.items()}


ORDER_NAMES = ["sort_x", "sort_xy", "sort_xyz", "hilbert"]


@claim("zorder_index_100x")
def zorder_index_100x(med, c):
    n = med["particles"].max()
    per = {o: _one(med, "s_per_particle", particles=n, cell_order=o) for o in ORDER_NAMES}
    return per["sort_xyz"] / per["sort_x"], f"N = {format_n(n)}", \
        {f"{o}_over_sort_x": per[o] / per["sort_x"] for o in ORDER_NAMES[1:]}


# ------------------------------------------------------ Fig. 12-13, CLL vs VL
@claim("vl_ns1_slower_13pct")
def vl_ns1_slower(med, c):
    n, note = _at(med, c)
    return _gain(med, n, {"list": "cll"}, {"list": "vlc"}), note


@claim("neighbour_search_NlnN")
def neighbour_search_nlnn(med, c):
    """Section 4: a list brings the pair evaluations per step from N^2 to N ln N.
    The value is the exponent of the candidate pairs examined per step against
    N (N ln N has local exponent 1 + 1/ln N, 1.11 to 1.08 over 8 000-300 000);
    the interactions (pairs within 2h) and the runtime per interaction are
    reported beside it, since runtime mixes the pair count with cache effects."""
    rows = pick(med, list="cll", gridder="B", reorder=1, kgc=0).sort_values("N")
    if "candidates_per_particle" not in rows or "interactions_per_particle" not in rows:
        raise NotMeasured("the results have no candidates_per_particle / interactions_per_particle counters")
    _need_points(rows, 3, "values of N")
    n = rows["N"].to_numpy(float)
    cand = pd.Series(rows["candidates_per_particle"].to_numpy(float) * n, index=n)
    inter = pd.Series(rows["interactions_per_particle"].to_numpy(float) * n, index=n)
    per_inter = pd.Series(rows["t"].to_numpy(float), index=n) / inter
    return _exponent(cand), (f"candidate pairs per step ∝ N^k over N = {format_n(n[0])}..{format_n(n[-1])}; "
                             f"related: interactions per step, runtime per interaction"), \
        {"k_interactions": _exponent(inter), "k_runtime_per_interaction": _exponent(per_inter),
         "k_runtime": _exponent(pd.Series(rows["t"].to_numpy(float), index=n))}


@claim("vl_memory_18x")
def vl_memory_18x(med, c):
    n, note = _at(med, c)
    return _one(med, "nl_bytes", particles=n, list="vlc") / _one(med, "nl_bytes", particles=n, list="cll"), note


# ----------------------------------------------------- Fig. 14-15, n_s sweep
def _ns_gains(med, c, lst):
    n, note = _at(med, c)
    m = pick(med, particles=n, kgc=0)
    return _gain_series(m, {"list": "cll"}, {"list": lst}, "list_steps", "list_steps"), note


@claim("vl_beats_cll_3_to_15")
def vl_beats_cll_mid_ns(med, c):
    gc, note = _ns_gains(med, c, "vlc")
    gx, _ = _ns_gains(med, c, "vlx")
    mid = [ns for ns in gx.index if 3 <= ns <= 15 and ns in gc.index]
    return _margins({ns: min(gc[ns], gx[ns]) / 100 for ns in mid}, "n_s in [3, 15] where both are faster"), \
        f"{note}; margin: the smaller improvement of VL_C and VL_X"


@claim("best_ns_near_7")
def best_ns_near_7(med, c):
    g, note = _ns_gains(med, c, "vlx")
    _need_points(g, 3, "values of n_s")
    return Extremum(g, "improvements over n_s", of="argmax", other="best_gain_pct"), \
        f"{note}; n_s of VL_X's largest improvement"


def _best_gain(med, c, lst):
    g, note = _ns_gains(med, c, lst)
    _need_points(g, 3, "values of n_s")
    return Extremum(g, "improvements over n_s", of="max", other="at_ns"), f"{note}; the largest over n_s"


CLAIMS["vlx_best_gain_4pct"] = functools.partial(_best_gain, lst="vlx")
CLAIMS["vlc_best_gain_3pct"] = functools.partial(_best_gain, lst="vlc")


def _vlx_below_vlc(med, c, col, x, what):
    """Margins, per value of `x` (n_s at one N, or N), of VL_X's `col` below VL_C's."""
    note = ""
    if x == "list_steps":
        n, note = _at(med, c)
        med = pick(med, particles=n, kgc=0)
    else:
        med = pick(med, kgc=0)
    vlx = pick(med, list="vlx").set_index(x)[col]
    vlc = pick(med, list="vlc").set_index(x)[col]
    common = vlx.index.intersection(vlc.index)
    return _margins(_rel(vlc[common], vlx[common]), what), \
        (f"{note}; " if note else "") + f"margin: (VL_C − VL_X) / VL_C of {col}"


CLAIMS["vlx_faster_than_vlc"] = functools.partial(_vlx_below_vlc, col="t", x="list_steps",
                                                  what="values of n_s where VL_X is faster")
CLAIMS["vlx_lighter_than_vlc"] = functools.partial(_vlx_below_vlc, col="nl_bytes", x="list_steps",
                                                   what="values of n_s where VL_X is lighter")
CLAIMS["vlx_faster_than_vlc_all_N"] = functools.partial(_vlx_below_vlc, col="t", x="particles",
                                                        what="values of N where VL_X is faster")


def _memory_mb(med, c, lst, at_max_ns):
    n, note = _at(med, c)
    rows = pick(med, particles=n, list=lst, kgc=0)
    if rows.empty:
        raise NotMeasured(f"no {lst} run at N = {format_n(n)}")
    row = rows.loc[rows["list_steps"].idxmax()] if at_max_ns else rows.iloc[0]
    return row["nl_bytes"] / 1e6, note + (f", n_s = {row['list_steps']}" if at_max_ns else "")


CLAIMS["cll_memory_31239"] = functools.partial(_memory_mb, lst="cll", at_max_ns=False)
CLAIMS["vlx_memory_high_ns"] = functools.partial(_memory_mb, lst="vlx", at_max_ns=True)
CLAIMS["vlc_memory_high_ns"] = functools.partial(_memory_mb, lst="vlc", at_max_ns=True)


@claim("vl_memory_30x_ns7")
def vl_memory_30x_ns7(med, c):
    n, note = _at(med, c)
    rows = pick(med, particles=n, kgc=0)
    cll = _one(rows, "nl_bytes", list="cll")
    return (_one(rows, "nl_bytes", list="vlx", list_steps=7) / cll, note,
            {"vlc_over_cll": _one(rows, "nl_bytes", list="vlc", list_steps=7) / cll})


# ---------------------------------------------------- Fig. 16-17, n_s = 7 vs N
def _gains_vs_n(med, lst, kgc=0):
    return _gain_series(pick(med, list_steps=7, kgc=kgc), {"list": "cll"}, {"list": lst}, "particles", "N")


@claim("vlx_gain_ns7_150k")
def vlx_gain_ns7(med, c):
    n, note = _at(med, c)
    return _gain(med, n, {"list": "cll", "list_steps": 7, "kgc": 0}, {"list": "vlx", "list_steps": 7, "kgc": 0}), note


@claim("gain_grows_with_N")
def gain_grows_with_n(med, c):
    g = _gains_vs_n(med, "vlx")
    _need_points(g, 3, "values of N")
    slope = np.polyfit(np.log(g.index.to_numpy(float)), g.to_numpy(float), 1)[0]
    span = math.log(g.index.max() / g.index.min())
    return float(slope * span), (f"fitted change of the VL_X improvement (a + b ln N) from "
                                 f"N = {format_n(g.index.min())} to {format_n(g.index.max())}")


@claim("vl_faster_than_cll_all_N")
def vl_faster_all_n(med, c):
    gc, gx = _gains_vs_n(med, "vlc"), _gains_vs_n(med, "vlx")
    return _margins({n: min(gc[n], gx[n]) / 100 for n in gx.index if n in gc.index},
                    "values of N where both are faster"), "margin: the smaller improvement of VL_C and VL_X"


@claim("kgc_gain_8pct")
def kgc_gain_8pct(med, c):
    n, note = _at(med, c)
    return _gain(med, n, {"list": "cll", "kgc": 1}, {"list": "vlx", "kgc": 1}), note


@claim("kgc_gain_exceeds_plain")
def kgc_gain_exceeds_plain(med, c):
    n, note = _at(med, c)
    with_kgc = _gain(med, n, {"list": "cll", "kgc": 1}, {"list": "vlx", "kgc": 1})
    plain = _gain(med, n, {"list": "cll", "kgc": 0}, {"list": "vlx", "kgc": 0})
    return with_kgc - plain, note, {"gain_with_kgc": with_kgc, "gain_without": plain}


# ------------------------------------- beyond the paper: loops per step (extra_loops)
@claim("vlx_gain_grows_with_loops")
def vlx_gain_grows_with_loops(med, c):
    """The paper's conjecture that more loops per step favour Verlet lists:
    the improvement of VL_X over CLL at n_s = 7 against k extra pair passes,
    as the change from the smallest to the largest k of a fit a + b k."""
    if "extra_loops" not in med:
        raise NotMeasured("no run with an extra_loops axis")
    n, note = _at(med, c)
    rows = pick(med, particles=n, list_steps=7, kgc=0)
    g = _gain_series(rows, {"list": "cll"}, {"list": "vlx"}, "extra_loops", "extra_loops")
    _need_points(g, 3, "loop counts")
    k = g.index.to_numpy(float)
    slope = np.polyfit(k, g.to_numpy(float), 1)[0]
    return (float(slope * (k.max() - k.min())),
            f"{note}: fitted change of the VL_X improvement (a + b k) from k = {k.min():g} to {k.max():g} extra loops",
            {f"gain_k{int(x)}": float(v) for x, v in g.items()})


# ------------------------------------------------------------------- peers
PEER_KEYS = ["cloud", "memory_order", "call", "threads"]


@claim("sphnl_over_nanoflann")
def sphnl_over_nanoflann(med, c):
    """Entries per second of sphnl over nanoflann, paired configuration by
    configuration (cloud, memory order, call, threads) at one N; the value is
    the geometric mean of the ratios, the smallest and largest beside it."""
    n, note = _at(med, c)
    note = note.replace("(paper: ", "(claim read at ")  # a target of ours, not the paper's
    m = pick(med, particles=n)
    if "impl" not in m:
        raise NotMeasured("no impl axis in the results")
    sphnl = m[m["impl"] == "sphnl"]
    mine = sphnl.set_index(PEER_KEYS)["entries_per_s"]
    peer = m[m["impl"] == "nanoflann"].set_index(PEER_KEYS)["entries_per_s"]
    common = mine.index.intersection(peer.index)
    if not len(common):
        raise NotMeasured(f"no configuration measured with both sphnl and nanoflann at N = {format_n(n)}")
    ratio = (mine[common] / peer[common]).to_numpy(float)
    related = {"smallest_ratio": float(ratio.min()), "largest_ratio": float(ratio.max())}
    for call in sorted(set(common.get_level_values("call"))):
        sel = np.asarray(common.get_level_values("call") == call)
        related[f"{call}_call"] = float(np.exp(np.mean(np.log(ratio[sel]))))
    return float(np.exp(np.mean(np.log(ratio)))), \
        f"{note}; geometric mean over {len(common)} paired configurations{_pages_used(sphnl)}", related


def _pages_used(rows):
    """', sphnl on base pages' (or huge, or both); '' where the rows predate
    the huge_pages counter."""
    used = pages_used(rows)
    return f", sphnl on {used} pages" if used else ""


def _first_call_over_peer(med, c, freed_memory):
    """The smallest sphnl / nanoflann entries-per-second ratio over the first
    calls (cloud, memory order, threads) that found their memory in state
    `freed_memory` ("idle": the longest idle_<s>s measured;
    experiments/peers_first_call.json); related, the
    geometric mean of the same ratios."""
    n, note = _at(med, c)
    note = note.replace("(paper: ", "(claim read at ")
    if "freed_memory" not in med or "impl" not in med:
        raise NotMeasured("no freed_memory or impl axis in the results (experiments/peers_first_call.json)")
    if freed_memory == "idle":  # the longest idle_<s>s the run measured
        idle = [v for v in set(med["freed_memory"].dropna()) if (idle_seconds(v) or 0) > 0]
        if not idle:
            raise NotMeasured("no first call measured with freed_memory idle_<s>s")
        freed_memory = max(idle, key=idle_seconds)
    m = pick(med, particles=n, call="first", freed_memory=freed_memory)
    keys = ["cloud", "memory_order", "threads"]
    sphnl = m[m["impl"] == "sphnl"]
    mine = sphnl.set_index(keys)["entries_per_s"]
    peer = m[m["impl"] == "nanoflann"].set_index(keys)["entries_per_s"]
    common = mine.index.intersection(peer.index)
    if not len(common):
        raise NotMeasured(f"no first call with freed_memory={freed_memory} measured with both sphnl and "
                          f"nanoflann at N = {format_n(n)}")
    ratio = (mine[common] / peer[common]).astype(float)
    ratio.index = [f"{cloud}/{order}/{th} thr." for cloud, order, th in common]
    return (Extremum(ratio, "configurations", of="min"),
            f"{note}; first calls, memory {freed_memory.replace('_', ' ')}{_pages_used(sphnl)}",
            {"geometric_mean": float(np.exp(np.mean(np.log(ratio.to_numpy()))))})


CLAIMS["first_call_over_nanoflann_just_freed"] = functools.partial(_first_call_over_peer, freed_memory="just_freed")
CLAIMS["first_call_over_nanoflann_idle"] = functools.partial(_first_call_over_peer, freed_memory="idle")


# ------------------------------------------- beyond the paper: what the public API costs
def _search_seconds(med, n, impl, threads):
    """Median seconds of one call (full lists) of `impl` at N = n on `threads`."""
    if "impl" not in med or "s_call" not in med:
        raise NotMeasured("no impl axis or s_call counter in the results (the search family)")
    return _one(med, col="s_call", particles=n, impl=impl, threads=threads)


def _api_over_engine(med, c, impl):
    """Seconds per call of the public API's `impl` over the bare engine's, one
    thread; related, the same on two threads."""
    n, note = _at(med, c)
    related = {}
    try:
        related["two_threads"] = _search_seconds(med, n, impl, 2) / _search_seconds(med, n, "sphnl", 2)
    except NotMeasured:
        pass
    return (_search_seconds(med, n, impl, 1) / _search_seconds(med, n, "sphnl", 1),
            note.replace("(paper: ", "(claim read at ") + ", one thread", related)


CLAIMS["api_visit_over_engine"] = functools.partial(_api_over_engine, impl="api_visit")
CLAIMS["api_rows_over_engine"] = functools.partial(_api_over_engine, impl="api")


@claim("search_two_threads_over_one")
def search_two_threads_over_one(med, c):
    """Speed-up of the bare engine's full lists on two threads over one;
    related, the same for the API's two ways out."""
    n, note = _at(med, c)
    related = {}
    for impl in ("api_visit", "api"):
        try:
            related[impl] = _search_seconds(med, n, impl, 1) / _search_seconds(med, n, impl, 2)
        except NotMeasured:
            pass
    return (_search_seconds(med, n, "sphnl", 1) / _search_seconds(med, n, "sphnl", 2),
            note.replace("(paper: ", "(claim read at ") + ", engine", related)


# ------------------------------ beyond the paper: first calls and huge pages
def _call_seconds(med, n, threads, call, pages):
    """Median seconds of one sphnl engine call at N = n."""
    if "pages" not in med or "s_call" not in med:
        raise NotMeasured("no pages axis or s_call counter in the results (experiments/first_call.json)")
    return _one(med, col="s_call", particles=n, impl="sphnl", threads=threads, call=call, pages=pages)


def _first_call_ratio(med, c, slow, fast):
    """Seconds of the (call, pages) `slow` over `fast`, one thread; related,
    the same on two threads, and, where the two differ in pages, the same
    ratio on warm calls (what huge pages change besides the faults)."""
    n, note = _at(med, c)
    related = {}
    pairs = {"two_threads": (2, slow, fast)}
    if slow[1] != fast[1]:
        pairs["warm_one_thread"] = (1, ("warm", slow[1]), ("warm", fast[1]))
        pairs["warm_two_threads"] = (2, ("warm", slow[1]), ("warm", fast[1]))
    for name, (threads, a, b) in pairs.items():
        try:
            related[name] = _call_seconds(med, n, threads, *a) / _call_seconds(med, n, threads, *b)
        except NotMeasured:
            pass
    return (_call_seconds(med, n, 1, *slow) / _call_seconds(med, n, 1, *fast),
            note.replace("(paper: ", "(claim read at ") + ", one thread", related)


CLAIMS["first_call_huge_over_base"] = functools.partial(_first_call_ratio, slow=("first", "base"),
                                                        fast=("first", "huge"))
CLAIMS["first_over_warm_huge"] = functools.partial(_first_call_ratio, slow=("first", "huge"),
                                                   fast=("warm", "huge"))


# ------------------------------------- beyond the paper: precision of the pair kernel
PRECISION_SOURCES = (("CLL+KGC", {"list": "cll", "kgc": 1}), ("VL_X", {"list": "vlx", "kgc": 0}),
                     ("VL_X+KGC", {"list": "vlx", "kgc": 1}))


def _precision_row(med, n, precision, list="cll", kgc=0, **more):
    if "precision" not in med:
        raise NotMeasured("no precision axis in the results")
    return _row(med, particles=n, precision=precision, list=list, kgc=kgc, threads=1, **more)


LIST_NAMES = {"cll": "CLL", "vlc": "VL_C", "vlx": "VL_X"}


def _us_per_particle_step(med, c, precision, list="cll", **more):
    """Seconds per step over the particles simulated, without KGC, one
    thread; related, the force phase alone. `more`: further axes (pair_loop)."""
    if any(k not in med for k in more):
        raise NotMeasured("no " + ", ".join(more) + " axis in the results")
    n, note = _at(med, c)
    row = _precision_row(med, n, precision, list=list, **more)
    n_sim = float(row["N"])
    return (1e6 * float(row["t"]) / n_sim, note.replace("(paper: ", "(claim read at ") + f", {LIST_NAMES[list]}, one thread",
            {"force_us_per_particle_step": 1e6 * float(row["s_force"]) / n_sim})


for _precision in ("double", "mixed"):
    CLAIMS[f"step_us_{_precision}"] = functools.partial(_us_per_particle_step, precision=_precision)
    CLAIMS[f"step_us_{_precision}_masked"] = functools.partial(_us_per_particle_step, precision=_precision,
                                                               pair_loop="masked")


@claim("mixed_over_double")
def mixed_over_double(med, c):
    """Time per step in double over mixed, CLL without KGC; related, the same
    ratio for the other pair sources measured and for the force phase."""
    n, note = _at(med, c)
    dbl, mixed = _precision_row(med, n, "double"), _precision_row(med, n, "mixed")
    related = {"force_phase": float(dbl["s_force"]) / float(mixed["s_force"])}
    for name, where in PRECISION_SOURCES:
        try:
            related[name] = _one(med, particles=n, precision="double", threads=1, **where) / \
                _one(med, particles=n, precision="mixed", threads=1, **where)
        except NotMeasured:
            pass
    return float(dbl["t"]) / float(mixed["t"]), note.replace("(paper: ", "(claim read at ") + ", CLL", related


# ---------------------------------------------- beyond the paper: the pair loop of CLL
@claim("masked_over_gather")
def masked_over_gather(med, c):
    """Time per step of pair_loop=gather over pair_loop=masked, CLL, double,
    no KGC; related, the same ratio with KGC and in mixed precision, the
    force phase's ratio, and the kernel lanes evaluated per pair."""
    if "pair_loop" not in med:
        raise NotMeasured("no pair_loop axis in the results")
    n, note = _at(med, c)
    value, related = _gather_over_masked(med, {"particles": n, "list": "cll", "threads": 1},
                                         {"precision": "double", "kgc": 0},
                                         (("KGC", {"precision": "double", "kgc": 1}),
                                          ("mixed", {"precision": "mixed", "kgc": 0})))
    return value, note.replace("(paper: ", "(claim read at ") + ", CLL, double", related


def _gather_over_masked(med, at, main, others):
    """pair_loop=gather over masked time per step for the configuration
    at + main; related as _axis_ratio's, with the masked loop's kernel lanes
    per pair."""
    return _axis_ratio(med, "pair_loop", "gather", "masked", at, main, others,
                       lanes={"kernel_lanes_per_pair": "den"})


def _axis_ratio(med, axis, num, den, at, main, others, lanes=None):
    """Time per step with `axis`=num over `axis`=den for the configuration
    at + main; related, the force phase's ratio, the same ratio for each
    (name, where) of `others` that was measured, and kernel_lanes_per_pair
    of the sides named in `lanes` ({related name: "num" or "den"})."""
    rows = {"num": _row(med, **{axis: num}, **main, **at), "den": _row(med, **{axis: den}, **main, **at)}
    related = {"force_phase": float(rows["num"]["s_force"]) / float(rows["den"]["s_force"])}
    for name, where in others:
        try:
            related[name] = _one(med, **{axis: num}, **where, **at) / _one(med, **{axis: den}, **where, **at)
        except NotMeasured:
            pass
    for name, side in (lanes or {}).items():
        if "kernel_lanes_per_pair" in rows[side]:
            related[name] = float(rows[side]["kernel_lanes_per_pair"])
    return float(rows["num"]["t"]) / float(rows["den"]["t"]), related


# ------------------------------- beyond the paper: the order of each cell's particles
@claim("index_over_morton_masked")
def index_over_morton_masked(med, c):
    """Time per step with inner_order=index over inner_order=morton, CLL,
    masked pair loop, double, no KGC; related, the force phase's ratio, the
    same ratio in mixed precision and with the gather loop, and the masked
    loop's kernel lanes per pair in both orders."""
    if "inner_order" not in med or "pair_loop" not in med:
        raise NotMeasured("no inner_order or pair_loop axis in the results")
    n, note = _at(med, c)
    value, related = _axis_ratio(med, "inner_order", "index", "morton",
                                 {"particles": n, "list": "cll", "threads": 1, "kgc": 0},
                                 {"pair_loop": "masked", "precision": "double"},
                                 (("mixed", {"pair_loop": "masked", "precision": "mixed"}),
                                  ("gather", {"pair_loop": "gather", "precision": "double"}),
                                  ("gather mixed", {"pair_loop": "gather", "precision": "mixed"})),
                                 lanes={"kernel_lanes_per_pair_index": "num", "kernel_lanes_per_pair_morton": "den"})
    return value, note.replace("(paper: ", "(claim read at ") + ", CLL, masked, double", related


for _precision in ("double", "mixed"):
    CLAIMS[f"step_us_{_precision}_masked_morton"] = functools.partial(
        _us_per_particle_step, precision=_precision, pair_loop="masked", inner_order="morton")


# ------------------------------------ beyond the paper: the pair loop of the Verlet lists
@claim("vl_masked_over_gather")
def vl_masked_over_gather(med, c):
    """Time per step of a Verlet list's pair_loop=gather over pair_loop=masked,
    VL_X, double; related, VL_C, both lists in mixed precision, VL_X's force
    phase, and the kernel lanes evaluated per pair."""
    if "pair_loop" not in med:
        raise NotMeasured("no pair_loop axis in the results")
    n, note = _at(med, c)
    value, related = _gather_over_masked(med, {"particles": n, "threads": 1, "kgc": 0},
                                         {"precision": "double", "list": "vlx"},
                                         (("VL_C", {"precision": "double", "list": "vlc"}),
                                          ("VL_X mixed", {"precision": "mixed", "list": "vlx"}),
                                          ("VL_C mixed", {"precision": "mixed", "list": "vlc"})))
    return value, note.replace("(paper: ", "(claim read at ") + ", VL_X, double", related


CLAIMS["step_us_vlx_masked"] = functools.partial(_us_per_particle_step, precision="double", list="vlx",
                                                 pair_loop="masked")


# --------------------------------------------- beyond the paper: two threads, one step
def _split_row(med, n, threads, thread_split, thread_updates):
    if "thread_split" not in med or "thread_updates" not in med:
        raise NotMeasured("no thread_split or thread_updates axis in the results")
    return _row(med, particles=n, list="cll", threads=threads, thread_split=thread_split,
                thread_updates=thread_updates)


def _split_speedup(med, n, thread_split, thread_updates, column="t"):
    """One thread's `column` over two threads', CLL, at N = n."""
    return float(_split_row(med, n, 1, thread_split, thread_updates)[column]) / \
        float(_split_row(med, n, 2, thread_split, thread_updates)[column])


def _step_speedup(med, c, thread_split, thread_updates, others):
    """The step's 2-thread speed-up of one way; related, the force phase's
    and the speed-ups of the `others` ways that were measured."""
    n, note = _at(med, c)
    related = {"force_phase": _split_speedup(med, n, thread_split, thread_updates, "s_force")}
    for split, updates in others:
        try:
            related[f"{split}_{updates}"] = _split_speedup(med, n, split, updates)
        except NotMeasured:
            pass
    return _split_speedup(med, n, thread_split, thread_updates), note.replace("(paper: ", "(claim read at ") + \
        f", CLL, thread_split={thread_split}, thread_updates={thread_updates}", related


@claim("step_two_threads_over_one")
def step_two_threads_over_one(med, c):
    """Seconds per step on one thread over two, CLL, split by interactions,
    phased updates; related, the other three ways of two threads and the
    force phase's speed-up."""
    return _step_speedup(med, c, "interactions", "phased",
                         [("fluid", "private"), ("fluid", "phased"), ("interactions", "private")])


@claim("interactions_split_over_fluid")
def interactions_split_over_fluid(med, c):
    """Seconds per step on two threads split by fluid over split by
    interactions, CLL, phased; related, the same with private updates."""
    n, note = _at(med, c)
    related = {}
    try:
        related["private_updates"] = float(_split_row(med, n, 2, "fluid", "private")["t"]) / \
            float(_split_row(med, n, 2, "interactions", "private")["t"])
    except NotMeasured:
        pass
    return float(_split_row(med, n, 2, "fluid", "phased")["t"]) / \
        float(_split_row(med, n, 2, "interactions", "phased")["t"]), \
        note.replace("(paper: ", "(claim read at ") + ", CLL, two threads, thread_updates=phased", related


@claim("step_two_threads_dynamic")
def step_two_threads_dynamic(med, c):
    """Seconds per step on one thread over two, CLL, home cells handed out
    dynamically, private updates; related, the force phase's speed-up and
    the split by interactions."""
    return _step_speedup(med, c, "dynamic", "private", [("interactions", "private")])


@claim("dynamic_split_over_interactions")
def dynamic_split_over_interactions(med, c):
    """Seconds per step on two threads split by interactions over handed out
    dynamically, CLL, private updates; related, the same of the force phase."""
    n, note = _at(med, c)
    cut = _split_row(med, n, 2, "interactions", "private")
    dyn = _split_row(med, n, 2, "dynamic", "private")
    related = {"force_phase": float(cut["s_force"]) / float(dyn["s_force"])}
    return float(cut["t"]) / float(dyn["t"]), note.replace("(paper: ", "(claim read at ") + \
        ", CLL, two threads, thread_updates=private", related


# ------------------------------------------------- beyond the paper: ranks (mpi kind)
def _on(med, ranks, threads, **equal):
    """Rows of the layout `ranks` x `threads`."""
    return pick(med, ranks=ranks, threads=threads, **equal)


def _vlx_gain_per_rank(med, ranks):
    """VL_X's improvement over CLL (n_s = 7, 1 thread per rank) of the runs
    on `ranks`, indexed by the particles per rank N/P."""
    if "ranks" not in med:
        raise NotMeasured("no ranks axis in the results (the mpi kind)")
    rows = pick(med, threads=1, list_steps=7)
    rows = rows[rows["ranks"].isin(ranks)]
    key = rows["particles"].astype(str) + "/" + rows["ranks"].astype(str)
    g = _gain_series(rows.assign(layout_key=key), {"list": "cll"}, {"list": "vlx"}, "layout_key", "n_per_rank")
    if g.empty:
        raise NotMeasured(f"no CLL / VL_X pair on {sorted(ranks)} rank(s)")
    return g


@claim("vlx_gain_few_particles_per_rank")
def vlx_gain_few_particles_per_rank(med, c):
    """The paper's conjecture (Conclusions) that a parallel code, each node
    holding few particles, suits VL_X: the improvement of VL_X over CLL at the
    smallest N/P of the distributed runs; related, the improvement at every
    N/P (serial runs included) and the fitted change of a + b ln(N/P) from
    the largest N/P to the smallest (positive: the gain grows as N/P falls)."""
    if "ranks" not in med:
        raise NotMeasured("no ranks axis in the results (the mpi kind)")
    ranks = sorted(int(r) for r in med["ranks"].unique() if r > 1)
    if not ranks:
        raise NotMeasured("no run on more than one rank")
    dist = _vlx_gain_per_rank(med, ranks)
    every = _vlx_gain_per_rank(med, sorted(int(r) for r in med["ranks"].unique()))
    related = {f"gain_at_n_per_rank_{x:.0f}": float(v) for x, v in every.items()}
    if len(every) >= 3:
        x = np.log(every.index.to_numpy(float))
        related["fitted_change_largest_to_smallest"] = float(
            -np.polyfit(x, every.to_numpy(float), 1)[0] * (x.max() - x.min()))
    n = dist.index.min()
    return float(dist.loc[n]), f"N/P = {format_n(n)}, on {'/'.join(map(str, ranks))} ranks of 1 thread", related


def _target_at(med, c):
    if "ranks" not in med:
        raise NotMeasured("no ranks axis in the results (the mpi kind)")
    n, note = _at(med, c)
    return n, note.replace("(paper: ", "(claim read at ")  # a target of ours, not the paper's


@claim("mpi_2ranks_vs_2threads")
def mpi_2ranks_vs_2threads(med, c):
    """Speed of 2 ranks x 1 thread over 1 rank x 2 threads (CLL): t(1 x 2) / t(2 x 1)."""
    n, note = _target_at(med, c)
    at = pick(med, particles=n)
    ratio = _one(_on(at, 1, 2), list="cll") / _one(_on(at, 2, 1), list="cll")
    related = {}
    if len(_on(at, 1, 2, list="vlx")) and len(_on(at, 2, 1, list="vlx")):
        related["vlx_ratio"] = _one(_on(at, 1, 2), list="vlx") / _one(_on(at, 2, 1), list="vlx")
    return ratio, f"{note}; speed of 2 ranks over 2 threads, CLL", related


@claim("mpi_communication_share")
def mpi_communication_share(med, c):
    """Communication share of the step (slowest rank, waits included), CLL on 2 ranks x 1 thread."""
    n, note = _target_at(med, c)
    if "communication_share" not in med:
        raise NotMeasured("no communication_share counter in the results")
    at = _on(pick(med, particles=n), 2, 1)
    related = {}
    if len(pick(at, list="vlx")):
        related["vlx_share_pct"] = 100 * _one(at, "communication_share", list="vlx")
    return 100 * _one(at, "communication_share", list="cll"), f"{note}; CLL, 2 ranks x 1 thread", related


def _balance_rows(med, c):
    """The 2 x 1 CLL rows at the claim's N, by balance_by, and the note."""
    n, note = _target_at(med, c)
    if "balance_by" not in med:
        raise NotMeasured("no balance_by axis in the results")
    return n, note, _on(pick(med, particles=n), 2, 1, list="cll")


@claim("mpi_balance_by_interactions")
def mpi_balance_by_interactions(med, c):
    """Speed of 2 ranks cut by estimated pairs over 2 ranks cut by particle
    weights (CLL): t(particles) / t(interactions); related, the busiest
    rank's pairs over the mean in each (counted, not timed)."""
    n, note, rows = _balance_rows(med, c)
    ratio = _one(rows, balance_by="particles") / _one(rows, balance_by="interactions")
    related = {}
    if "pair_imbalance" in rows:
        for mode in ("particles", "interactions"):
            related[f"busiest_rank_pairs_over_mean_pct_{mode}"] = 100 * _one(rows, "pair_imbalance", balance_by=mode)
    return ratio, f"{note}; CLL, 2 ranks x 1 thread", related


@claim("mpi_balanced_2ranks_vs_2threads")
def mpi_balanced_2ranks_vs_2threads(med, c):
    """Speed of 2 ranks x 1 thread balanced by interactions over 1 rank x 2
    threads (CLL): t(1 x 2) / t(2 x 1); related, the same by particles and
    the communication share."""
    n, note, rows = _balance_rows(med, c)
    threads = _one(_on(pick(med, particles=n), 1, 2), list="cll")
    related = {"by_particles_ratio": threads / _one(rows, balance_by="particles")}
    if "communication_share" in rows:
        related["communication_share_pct"] = 100 * _one(rows, "communication_share", balance_by="interactions")
    return threads / _one(rows, balance_by="interactions"), f"{note}; speed of 2 ranks over 2 threads, CLL", related


@claim("mpi_balanced_communication_share")
def mpi_balanced_communication_share(med, c):
    """Communication share of the step (slowest rank, waits included), CLL on 2 ranks x 1 thread cut by interactions."""
    n, note, rows = _balance_rows(med, c)
    if "communication_share" not in rows:
        raise NotMeasured("no communication_share counter in the results")
    related = {"by_particles_pct": 100 * _one(rows, "communication_share", balance_by="particles")}
    return 100 * _one(rows, "communication_share", balance_by="interactions"), f"{note}; CLL, 2 ranks x 1 thread", related


# ------------------------------------------------------------------ verdicts
def validate_claim(c, where):
    """Every band two-sided, finite, reproduced inside partly, with a reason."""
    cid = c.get("id", "?")
    tol = c.get("tolerance")
    if not isinstance(tol, dict) or set(tol) != {"reproduced", "partly"}:
        raise ResultsError(f"{where}: claim '{cid}': tolerance must be "
                           "{\"reproduced\": [lo, hi], \"partly\": [lo, hi]}")
    for name in ("reproduced", "partly"):
        band = tol[name]
        if not (isinstance(band, list) and len(band) == 2 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in band)
                and band[0] <= band[1]):
            raise ResultsError(f"{where}: claim '{cid}': tolerance.{name} is {band}; it must be two "
                               "finite numbers [lo, hi] with lo <= hi (a one-sided band claims more "
                               "than the paper's sentence: give the physical bound, e.g. 100 for a %)")
    (rlo, rhi), (plo, phi) = tol["reproduced"], tol["partly"]
    if not (plo <= rlo and rhi <= phi):
        raise ResultsError(f"{where}: claim '{cid}': the reproduced band {tol['reproduced']} must lie "
                           f"inside the partly band {tol['partly']}")
    if not isinstance(c.get("band_reason"), str) or not c["band_reason"].strip():
        raise ResultsError(f"{where}: claim '{cid}': no band_reason; say why the bands are where they are")


def _edges(band):
    return (-math.inf if band[0] is None else band[0]), (math.inf if band[1] is None else band[1])


def _inside(lo, hi, band):
    a, z = _edges(band)
    return a <= lo and hi <= z


def verdict(value, lo, hi, band):
    """(verdict, what would resolve it or '') of a value with interval [lo, hi]."""
    if value is None or not all(math.isfinite(v) for v in (value, lo, hi)):
        return "not measured", ""
    if _inside(lo, hi, band["reproduced"]):
        return "reproduced", ""
    if _inside(lo, hi, band["partly"]):
        return "partly", ""
    plo, phi = _edges(band["partly"])
    if hi < plo or lo > phi:
        return "not reproduced", ""
    # The interval crosses an edge of the partly band (the one nearer the value if both).
    crossed = [e for e in (plo, phi) if lo < e < hi or e in (lo, hi)]
    edge = min(crossed or [plo, phi], key=lambda e: abs(value - e))
    reach = (value - lo) if edge < value else (hi - value)
    dist = abs(value - edge)
    if dist <= 1e-12 * max(1.0, abs(edge)) or reach <= 0:
        return "unresolved", (f"the value lies on the band edge {edge:g}: more rounds cannot move "
                              "it off the edge; only a different measurement can")
    k = reach / dist
    return "unresolved", (f"more rounds: the interval reaches {k:.1f}x farther than the value's "
                          f"distance to the band edge {edge:g} (width falls as 1/sqrt(rounds): "
                          f"about {max(2, math.ceil(k * k))}x the rounds)")


# ---------------------------------------------------------------- evaluation
def _unpack(out):
    value, note, *rest = out
    return value, note, (rest[0] if rest else {})


def _layout(fn, c, med):
    """Evaluate fn per flow state on the point medians; return the states, the
    outputs and the layout [(state, kind, key)] of the flat statistic vector."""
    states = [None]
    if "flow_time" in med and med["flow_time"].nunique() > 1:
        states = sorted(med["flow_time"].unique())
    outs, layout = [], []
    for s in states:
        value, note, extras = _unpack(fn(med if s is None else med[med["flow_time"] == s], c))
        outs.append((value, note, extras))
        if isinstance(value, Margins):
            layout += [(s, "margin", i) for i in value.margins.index]
        elif isinstance(value, Extremum):
            layout += [(s, "point", i) for i in value.values.index]
        else:
            layout.append((s, "value", None))
        layout += [(s, "extra", k) for k in sorted(extras)]
    return states, outs, layout


def _flat(fn, c, med, states, layout):
    vec = []
    for s in states:
        value, _, extras = _unpack(fn(med if s is None else med[med["flow_time"] == s], c))
        for st, kind, key in layout:
            if st != s:
                continue
            if kind == "margin":
                vec.append(value.margins.get(key, np.nan))
            elif kind == "point":
                vec.append(value.values.get(key, np.nan))
            elif kind == "value":
                vec.append(float(value))
            else:
                vec.append(float(extras[key]))
    return np.asarray(vec, float)


TIE, UNDECIDED = "tie", "undecided"


def _classify(lo, hi, tie):
    """1: the claim holds at this point (the margin's interval above the tie
    tolerance), -1: it fails (below minus the tolerance), TIE: the interval
    lies within ±tie (equal within resolution: a tie is not a ranking, so the
    point does not count for the claim), UNDECIDED: the interval straddles."""
    if lo > tie:
        return 1
    if hi < -tie:
        return -1
    if tie > 0 and -tie <= lo and hi <= tie:
        return TIE
    return UNDECIDED


def measure(fn, c, boot):
    """Value, interval, per flow state and related metrics of claim `c` on
    RoundBootstrap `boot`; raises NotMeasured."""
    states, outs, layout = _layout(fn, c, boot.point)
    point = _flat(fn, c, boot.point, states, layout)
    reps = np.full((boot.resamples, len(layout)), np.nan)
    for b, tab in enumerate(boot.tables()):
        try:
            reps[b] = _flat(fn, c, tab, states, layout)
        except Exception:  # noqa: BLE001 - a replicate that lost a point is left out
            pass
    cols = {key: [i for i, (s, k, kk) in enumerate(layout) if (k, kk) == key] for key in
            dict.fromkeys((k, kk) for _, k, kk in layout)}
    level = boot.level
    res = {"per_flow_time": [], "related": {}}
    is_margin = isinstance(outs[0][0], Margins)
    if is_margin:
        tie = float(c.get("tie_within", 0.0))
        idx = [i for i, (_, k, _) in enumerate(layout) if k == "margin"]
        cls = {}
        for i in idx:
            lo, hi = S.percentile_interval(reps[:, i], level)
            cls[i] = _classify(lo, hi, tie)
        if not idx:
            raise NotMeasured(f"no {outs[0][0].what} measured")

        def frac(ii):
            """Point fraction, and its interval: undecided points may go either way."""
            wins = sum(cls[i] == 1 for i in ii)
            undecided = sum(cls[i] == UNDECIDED for i in ii)
            return sum(point[i] > tie for i in ii) / len(ii), wins / len(ii), (wins + undecided) / len(ii)
        value, lo, hi = frac(idx)
        for s in states:
            ii = [i for i in idx if layout[i][0] == s]
            if s is not None and ii:
                v, a, z = frac(ii)
                res["per_flow_time"].append({"flow_time": s, "value": v, "ci_low": a, "ci_high": z})
        what = outs[0][0].what

        def where(kind):
            return [layout[i] for i in idx if cls[i] == kind]
        ties, undecided = where(TIE), where(UNDECIDED)
        note = f"{sum(v == 1 for v in cls.values())} of {len(idx)} {what}"
        if ties:
            note += (f"; {len(ties)} tie(s), margin within ±{tie:g}: not a ranking, not counted "
                     f"({', '.join(_fmt_key(s, k) for s, _, k in ties)})")
        if undecided:
            note += (f"; {len(undecided)} undecided, the margin's interval contains "
                     f"{'0' if tie == 0 else f'±{tie:g}'} ({', '.join(_fmt_key(s, k) for s, _, k in undecided)})")
        res["note"] = "; ".join(x for x in (outs[0][1], note) if x)
        if undecided:
            res["ties"] = (f"more rounds: {len(undecided)} point(s) whose margin's interval straddles "
                           f"{'0' if tie == 0 else 'the tie tolerance'} (the claim's interval is the range "
                           "of fractions they allow)")
    elif isinstance(outs[0][0], Extremum):
        res["note"] = outs[0][1]
        value, lo, hi = _extremum(outs[0][0], point, reps, states, layout, level, res)
    else:
        vi = cols[("value", None)]
        pooled = np.mean(reps[:, vi], axis=1)
        value = float(np.mean(point[vi]))
        lo, hi = S.percentile_interval(pooled, level)
        for s, i in zip(states, vi):
            if s is not None:
                a, z = S.percentile_interval(reps[:, i], level)
                res["per_flow_time"].append({"flow_time": s, "value": float(point[i]), "ci_low": a, "ci_high": z})
        res["note"] = outs[0][1]
    for (kind, key), ii in cols.items():
        if kind == "extra":
            a, z = S.percentile_interval(np.mean(reps[:, ii], axis=1), level)
            res["related"][key] = {"value": float(np.mean(point[ii])), "ci_low": a, "ci_high": z}
    res.update(value=float(value), ci_low=float(lo), ci_high=float(hi))
    return res


def _extremum(ext, point, reps, states, layout, level, res):
    """Value and interval of an Extremum claim (see Extremum): per flow state,
    then the mean over the states; fills res's per_flow_time, related, note."""
    idx = [i for i, (_, k, _) in enumerate(layout) if k == "point"]
    if not idx:
        raise NotMeasured(f"no {ext.what} measured")
    low, high = S.simultaneous_band(reps[:, idx], level)
    band = dict(zip(idx, zip(low, high)))
    per = {}
    for s in states:
        ii = [i for i in idx if layout[i][0] == s]
        best = max(ii, key=lambda i: point[i])
        floor = max(band[i][0] for i in ii)
        contenders = [layout[i][2] for i in ii if band[i][1] >= floor]
        per[s] = {"max": (point[best], floor, max(band[i][1] for i in ii)),
                  "argmax": (layout[best][2], min(contenders), max(contenders)),
                  "contenders": contenders}
        if ext.of == "min":  # mirrored: the smallest lies between the smallest low end and the smallest high end
            worst = min(ii, key=lambda i: point[i])
            ceiling = min(band[i][1] for i in ii)
            per[s]["min"] = (point[worst], min(band[i][0] for i in ii), ceiling)
            per[s]["contenders"] = [layout[i][2] for i in ii if band[i][0] <= ceiling]
    other = "argmax" if ext.of == "max" else "max"
    for s in states:
        if s is not None:
            v, a, z = per[s][ext.of]
            res["per_flow_time"].append({"flow_time": s, "value": float(v), "ci_low": float(a),
                                         "ci_high": float(z)})
    if ext.other:
        v, a, z = np.mean([per[s][other] for s in states], axis=0)
        res["related"][ext.other] = {"value": float(v), "ci_low": float(a), "ci_high": float(z)}
    may = "; ".join((f"t = {s:g} s: " if s is not None else "") + ", ".join(_fmt_key(None, k) for k in per[s]["contenders"])
                    for s in states)
    word = "smallest" if ext.of == "min" else "largest"
    res["note"] = (f"{res['note']}; interval of the {word} of {len(idx)} {ext.what} from a "
                   f"simultaneous {100 * level:g} % band (the bootstrap of a{' minimum is biased down' if ext.of == 'min' else ' maximum is biased up'}); "
                   f"may be the {word}: {may}").lstrip("; ")
    v, a, z = np.mean([per[s][ext.of] for s in states], axis=0)
    return float(v), float(a), float(z)


def _fmt_key(state, key):
    k = format_n(key) if isinstance(key, (int, float)) and key >= 1000 else f"{key:g}" \
        if isinstance(key, (int, float)) else str(key)
    return k if state is None else f"{k} (t = {state:g} s)"


class Evaluator:
    """Evaluates the claims of every experiment on one run's rows, pooling
    each configuration over all the experiments that measured it."""

    def __init__(self, rows, resamples=S.RESAMPLES, per_experiment_resamples=100, seed=0):
        self.resamples, self.per_exp, self.seed = resamples, per_experiment_resamples, seed
        self.rows = S.with_round_ids(rows) if len(rows) else rows
        if len(rows):
            ok = self.rows[~self.rows["error_occurred"].astype(bool)]
            self.rows = ok
            self.keys = S.config_keys(ok)
            self.key_str = _norm_keys(ok, self.keys).set_axis(ok.index)

    def sources(self, src):
        """{experiment: its rows of the configurations `src` measured}, `src` first."""
        if not len(self.rows):
            return {}
        own = self.rows["experiment"] == src
        if not own.any():
            return {}
        wanted = set(self.key_str[own])
        match = self.key_str.isin(wanted)
        out = {src: self.rows[own]}
        for exp in sorted(set(self.rows.loc[match & ~own, "experiment"])):
            out[exp] = self.rows[match & (self.rows["experiment"] == exp)]
        return out

    def experiment(self, exp, claims):
        """[result] for the claims of experiment definition `exp`."""
        src = exp.get("uses") or exp["id"]
        parts = self.sources(src)
        boot = None
        if parts:
            pooled = pd.concat(parts.values()).assign(experiment=src)
            boot = S.RoundBootstrap(pooled, resamples=self.resamples, seed=self.seed)
        results = [self.claim(c, boot, parts, src) for c in claims]
        return results

    def claim(self, c, boot, parts, src):
        result = {**c, "value": None, "ci_low": None, "ci_high": None, "verdict": "not measured",
                  "note": "", "resolve": "", "per_flow_time": [], "per_experiment": [], "related": {},
                  "repetitions": 0, "rounds": 0, "experiments": sorted(parts)}
        fn = CLAIMS.get(c["id"])
        min_n = c.get("min_n", MIN_N)
        try:
            if fn is None:
                raise NotMeasured("no measurement function for this claim in plots/claims.py")
            if boot is None or boot.point.empty or "particles" not in boot.point:
                raise NotMeasured("no results")
            if boot.point["particles"].max() < min_n:
                raise NotMeasured(f"largest N measured is {format_n(boot.point['particles'].max())}; "
                                  f"the claim needs N ≥ {format_n(min_n)}")
            boot.cache_tables()
            _READ_AT.clear()
            res = measure(fn, c, boot)
            result.update(res)
            read_at = set(_READ_AT)
            if len(read_at) == 1:  # one N: the claim's at_n is where it was read
                n = read_at.pop()
                result["at_n"] = int(n) if n.is_integer() else n
                if c.get("at_n") and result["at_n"] != c["at_n"]:
                    result["at_n_wanted"] = c["at_n"]
            result["repetitions"] = int(boot.point["reps"].min())
            result["rounds"] = int(boot.point["rounds"].min())
            result["verdict"], result["resolve"] = verdict(res["value"], res["ci_low"], res["ci_high"],
                                                           c["tolerance"])
            if result["verdict"] == "unresolved" and res.get("ties"):
                result["resolve"] = res["ties"]
            if len(parts) > 1:
                result["per_experiment"] = self._per_experiment(fn, c, boot, parts, src)
        except NotMeasured as e:
            result["note"] = str(e)
        return result

    def _per_experiment(self, fn, c, boot, parts, src):
        """The claim measured on each experiment alone, for the experiments
        that hold every configuration the claim reads: the pooled value must
        not move when the configurations the experiment lacks are scaled."""
        keys = [k for k in self.keys if k in boot.point]
        pooled_keys = _norm_keys(boot.point, keys)
        base = _flat_point(fn, c, boot.point)
        out = []
        for exp_id, rows in parts.items():
            lacks = ~pooled_keys.isin(set(_norm_keys(rows, keys)))
            if lacks.any() and not all(_same(_flat_point(fn, c, _scaled(boot, lacks, trial)), base)
                                       for trial in (1, 2)):
                continue
            try:
                sub = S.RoundBootstrap(rows.assign(experiment=src), resamples=self.per_exp, seed=self.seed)
                r = measure(fn, c, sub)
            except Exception:  # noqa: BLE001 - that experiment alone cannot support it
                continue
            out.append({"experiment": exp_id, "value": r["value"], "ci_low": r["ci_low"],
                        "ci_high": r["ci_high"], "repetitions": int(sub.point["reps"].min())})
        return out if len(out) > 1 else []


def _flat_point(fn, c, med):
    try:
        states, _, layout = _layout(fn, c, med)
        return _flat(fn, c, med, states, layout)
    except Exception:  # noqa: BLE001 - a table the claim cannot read
        return np.array([np.nan])


def _same(a, b):
    return a.shape == b.shape and np.allclose(a, b, equal_nan=True)


def _scaled(boot, mask, seed):
    """The point medians with the measured columns of the rows in `mask`
    scaled, each row by its own factor in [0.5, 2] (one factor for all would
    leave ratios unchanged)."""
    t = boot.point.copy()
    mask = np.asarray(mask)
    factors = np.random.default_rng(seed).uniform(0.5, 2.0, size=(mask.sum(), 1))
    t.loc[mask, boot.numeric] = t.loc[mask, boot.numeric].to_numpy(float) * factors
    return S.derive_columns(t)


def _norm_keys(df, keys):
    """Configuration identity as text, numbers normalised (8000 == 8000.0)."""
    def norm(v):
        if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
            return "nan" if v != v else f"{float(v):g}"
        return str(v)
    return df[keys].apply(lambda col: col.map(norm)).agg("|".join, axis=1).reset_index(drop=True)



def evaluate(c, data, resamples=200):
    """The result of claim `c` on the rows `data` of one experiment alone (no
    pooling), for tests and one-off checks; the report uses Evaluator."""
    data = data.assign(experiment="_") if len(data) else data
    return Evaluator(data, resamples=resamples).experiment({"id": "_", "claims": [c]}, [c])[0]
