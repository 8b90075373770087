"""The paper's quantitative claims, measured on our results.

Each claim of experiments/<id>.json ("claims": id, text, paper_value, unit,
optional at_n / min_n, tolerance {"reproduced": [lo, hi], "partly": [lo, hi]},
source) has one function here, registered under its id. The function gets
the per-configuration medians (results.medians) of the experiment the claim
is drawn from and returns (measured value, note), or raises NotMeasured.
`evaluate` turns the value into a verdict: `reproduced` when it lies in the
reproduced interval, `partly` in the partly interval, else `not reproduced`;
`not measured` when the data cannot support the claim (e.g. a tiny run).
Improvement is the paper's (t_ref - t) / t_ref in percent.
"""
import functools
import math

import numpy as np

from harness.results import improvement, medians, pick

MIN_N = 5000  # a claim about performance needs at least this N in the run
CLAIMS = {}


class NotMeasured(Exception):
    """The results cannot support this claim; the message says why."""


def claim(claim_id):
    def register(fn):
        CLAIMS[claim_id] = fn
        return fn
    return register


# ------------------------------------------------------------------- helpers
def _n_str(n):
    return f"{n:,.0f}".replace(",", " ")


def _at(med, c):
    """The N to measure a claim at: its at_n when measured, else the largest."""
    ns = sorted(med["n"].dropna().unique())
    want = c.get("at_n")
    if want in ns or not want:
        n = want or ns[-1]
        return n, f"N = {_n_str(n)}"
    return ns[-1], f"N = {_n_str(ns[-1])} (paper: N = {_n_str(want)})"


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
    imp = improvement(med, {**ref, "n": n}, {**var, "n": n})
    if imp.empty:
        raise NotMeasured(f"no pair {ref} / {var} at N = {_n_str(n)}")
    return float(imp["imp"].iloc[0])


def _exponent(s):
    """k of the least-squares fit log t = log a + k log N."""
    return float(np.polyfit(np.log(s.index.to_numpy(float)), np.log(s.to_numpy(float)), 1)[0])


def _fraction(flags, what):
    flags = list(flags)
    if not flags:
        raise NotMeasured(f"no {what} measured")
    return sum(flags) / len(flags), f"{sum(flags)} of {len(flags)} {what}"


# ------------------------------------------------------------------- Table I
def _share(med, c, lst, col):
    n = med["n"].max()
    row = _row(med, n=n, list=lst, ns=1, kgc=0)
    total = row["s_neighbour_list"] + row["s_force"] + row["s_update"]
    return 100 * row[col] / total, f"N = {_n_str(n)}, share of the three timed phases"


for _lst, _key in (("cll", "cll"), ("vlc", "vl")):
    for _ph, _col in (("list", "s_neighbour_list"), ("force", "s_force"), ("update", "s_update")):
        CLAIMS[f"table1_{_key}_{_ph}"] = functools.partial(_share, lst=_lst, col=_col)


# --------------------------------------------------------- Fig. 6-11 gridders
def _times(med, n, col="t", **equal):
    return {g: _one(med, col, n=n, gridder=g, **equal) for g in "ABCD"}


@claim("A_slower_3x")
def a_slower_3x(med, c):
    n, note = _at(med, c)
    t = _times(med, n, reorder=0)
    return t["A"] / max(t["B"], t["C"], t["D"]), note


@claim("A_superlinear")
def a_superlinear(med, c):
    _need_points(_series(med, gridder="A", reorder=0), 3, "values of N")
    ks = {g: _exponent(_series(med, gridder=g, reorder=0)) for g in "ABCD"}
    return ks["A"], "t ∝ N^k; k for B, C, D: " + ", ".join(f"{ks[g]:.2f}" for g in "BCD")


def _d_vs(med, c, other):
    n, note = _at(med, c)
    t = _times(med, n, reorder=0)
    fastest = min(t, key=t.get)
    return 100 * (t[other] - t["D"]) / t[other], f"{note}; fastest unsorted: {fastest}"


for _g in "ABC":
    CLAIMS[f"D_vs_{_g}_unsorted"] = functools.partial(_d_vs, other=_g)


@claim("C_memory_20x")
def c_memory_20x(med, c):
    n = med["n"].max()
    m = _times(med, n, "nl_bytes", reorder=0)
    return m["C"] / max(m["A"], m["B"], m["D"]), f"N = {_n_str(n)}"


@claim("A_least_memory")
def a_least_memory(med, c):
    flags = []
    for n in sorted(med["n"].unique()):
        m = _times(med, n, "nl_bytes", reorder=0)
        flags.append(min(m, key=m.get) == "A")
    return _fraction(flags, "values of N where A needs least")


def _memory_at(med, c, gridder):
    """MB at the claim's N, extrapolated linearly (bytes per particle) if not run."""
    n, note = _at(med, c)
    row = _row(med, n=n, gridder=gridder, reorder=0)
    per = row["nl_bytes"] / row["N"]
    if n == c["at_n"]:
        return row["nl_bytes"] / 1e6, f"{note}, {per:.1f} B/particle"
    return per * c["at_n"] / 1e6, (f"extrapolated linearly from N = {_n_str(row['N'])} "
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
    return min(g["B"], g["C"], g["D"]), note + "; " + ", ".join(f"{k} {v:.1f} %" for k, v in g.items())


@claim("reorder_gain_A")
def reorder_gain_a(med, c):
    n, note = _at(med, c)
    return _reorder_gains(med, n)["A"], note


@claim("D_lowest_gain")
def d_lowest_gain(med, c):
    n, note = _at(med, c)
    g = _reorder_gains(med, n)
    return g["D"] - min(g["A"], g["B"], g["C"]), note + "; " + ", ".join(
        f"{k} {v:.1f} %" for k, v in g.items())


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
    return _one(med, "nl_bytes", n=n, gridder="B", reorder=1) / \
        _one(med, "nl_bytes", n=n, gridder="D", reorder=1), note


# ---------------------------------------------------------- Fig. 9, orderings
@claim("sortx_beats_zorder")
def sortx_beats_zorder(med, c):
    def gains(n):
        return {o: _gain(med, n, {"order": o, "reorder": 0}, {"order": o, "reorder": 1})
                for o in ("sort_x", "sort_xy", "sort_xyz")}
    n, note = _at(med, c)
    every = {m: gains(m) for m in sorted(med["n"].unique())}
    _, always = _fraction([g["sort_x"] > max(g["sort_xy"], g["sort_xyz"]) for g in every.values()],
                          "values of N")
    g = every[n]
    return g["sort_x"] - max(g["sort_xy"], g["sort_xyz"]), (
        f"{note}; gains " + ", ".join(f"{k} {v:.1f} %" for k, v in g.items())
        + f"; SortX ahead at {always}")


ORDER_NAMES = ["sort_x", "sort_xy", "sort_xyz", "hilbert"]


@claim("zorder_index_100x")
def zorder_index_100x(med, c):
    n = med["n"].max()
    per = {o: _one(med, "s_per_particle", n=n, order=o) for o in ORDER_NAMES}
    ratios = ", ".join(f"{o} {per[o] / per['sort_x']:.2f}x" for o in ORDER_NAMES[1:])
    return per["sort_xyz"] / per["sort_x"], f"N = {_n_str(n)}; vs SortX: {ratios}"


# ------------------------------------------------------ Fig. 12-13, CLL vs VL
@claim("vl_ns1_slower_13pct")
def vl_ns1_slower(med, c):
    n, note = _at(med, c)
    gains = {m: _gain(med, m, {"list": "cll"}, {"list": "vlc"}) for m in sorted(med["n"].unique())}
    _, slower = _fraction([g < 0 for g in gains.values()], "values of N")
    return gains[n], f"{note}; VL slower at {slower}"


@claim("neighbour_search_NlnN")
def neighbour_search_nlnn(med, c):
    s = _series(med, list="cll", gridder="B", reorder=1, kgc=0)
    _need_points(s, 3, "values of N")
    n, t = s.index.to_numpy(float), s.to_numpy(float)

    def rms(f):  # relative rms residual of the best fit t = a f(N)
        a = np.sum(f / t) / np.sum((f / t) ** 2)
        return float(np.sqrt(np.mean((a * f / t - 1) ** 2)))
    r_nln, r_n = rms(n * np.log(n)), rms(n)
    better = "a·N·ln N" if r_nln < r_n else "a·N"
    return _exponent(s), (f"t ∝ N^k over N = {_n_str(n[0])}..{_n_str(n[-1])}; rms relative residual "
                          f"a·N·ln N {100 * r_nln:.1f} %, a·N {100 * r_n:.1f} %: {better} fits better")


@claim("vl_memory_18x")
def vl_memory_18x(med, c):
    n, note = _at(med, c)
    ratio = {m: _one(med, "nl_bytes", n=m, list="vlc") / _one(med, "nl_bytes", n=m, list="cll")
             for m in sorted(med["n"].unique())}
    first = min(ratio)
    return ratio[n], f"{note}; ratio {ratio[first]:.1f} at N = {_n_str(first)}"


# ----------------------------------------------------- Fig. 14-15, n_s sweep
def _ns_gains(med, c, lst):
    n, note = _at(med, c)
    imp = improvement(pick(med, n=n, kgc=0), {"list": "cll"}, {"list": lst}, on=("n", "ns"), x="ns")
    return imp.set_index("ns")["imp"], note


@claim("vl_beats_cll_3_to_15")
def vl_beats_cll_mid_ns(med, c):
    gc, note = _ns_gains(med, c, "vlc")
    gx, _ = _ns_gains(med, c, "vlx")
    mid = [ns for ns in gx.index if 3 <= ns <= 15 and ns in gc.index]
    value, frac = _fraction([gc[ns] > 0 and gx[ns] > 0 for ns in mid], "n_s in [3, 15]")
    ends = f"at n_s = {gx.index.min()}: VL_X {gx.iloc[0]:.1f} %; at n_s = {gx.index.max()}: {gx.iloc[-1]:.1f} %"
    return value, f"{note}; both faster at {frac}; {ends}"


@claim("best_ns_near_7")
def best_ns_near_7(med, c):
    g, note = _ns_gains(med, c, "vlx")
    _need_points(g, 3, "values of n_s")
    return float(g.idxmax()), f"{note}; improvement there {g.max():.1f} %"


def _best_gain(med, c, lst):
    g, note = _ns_gains(med, c, lst)
    _need_points(g, 3, "values of n_s")
    return float(g.max()), f"{note}; at n_s = {g.idxmax()}"


CLAIMS["vlx_best_gain_4pct"] = functools.partial(_best_gain, lst="vlx")
CLAIMS["vlc_best_gain_3pct"] = functools.partial(_best_gain, lst="vlc")


def _vlx_below_vlc(med, c, col, x, what):
    """Fraction of the values of `x` (n_s at one N, or N) where VL_X's `col` is below VL_C's."""
    note = ""
    if x == "ns":
        n, note = _at(med, c)
        med = pick(med, n=n)
    vlx = pick(med, list="vlx").set_index(x)[col]
    vlc = pick(med, list="vlc").set_index(x)[col]
    common = vlx.index.intersection(vlc.index)
    value, frac = _fraction(vlx[common] < vlc[common], what)
    return value, f"{note}; {frac}" if note else frac


CLAIMS["vlx_faster_than_vlc"] = functools.partial(_vlx_below_vlc, col="t", x="ns", what="values of n_s")
CLAIMS["vlx_lighter_than_vlc"] = functools.partial(_vlx_below_vlc, col="nl_bytes", x="ns",
                                                   what="values of n_s")
CLAIMS["vlx_faster_than_vlc_all_N"] = functools.partial(_vlx_below_vlc, col="t", x="n",
                                                        what="values of N")


def _memory_mb(med, c, lst, at_max_ns):
    n, note = _at(med, c)
    rows = pick(med, n=n, list=lst, kgc=0)
    if rows.empty:
        raise NotMeasured(f"no {lst} run at N = {_n_str(n)}")
    row = rows.loc[rows["ns"].idxmax()] if at_max_ns else rows.iloc[0]
    return row["nl_bytes"] / 1e6, note + (f", n_s = {row['ns']}" if at_max_ns else "")


CLAIMS["cll_memory_31239"] = functools.partial(_memory_mb, lst="cll", at_max_ns=False)
CLAIMS["vlx_memory_high_ns"] = functools.partial(_memory_mb, lst="vlx", at_max_ns=True)
CLAIMS["vlc_memory_high_ns"] = functools.partial(_memory_mb, lst="vlc", at_max_ns=True)


@claim("vl_memory_30x_ns7")
def vl_memory_30x_ns7(med, c):
    n, note = _at(med, c)
    rows = pick(med, n=n, kgc=0)
    cll = _one(rows, "nl_bytes", list="cll")
    return (_one(rows, "nl_bytes", list="vlx", ns=7) / cll,
            f"{note}; VL_C: {_one(rows, 'nl_bytes', list='vlc', ns=7) / cll:.1f}x")


# ---------------------------------------------------- Fig. 16-17, n_s = 7 vs N
def _gains_vs_n(med, lst, kgc=0):
    imp = improvement(pick(med, ns=7, kgc=kgc), {"list": "cll"}, {"list": lst})
    return imp.set_index("N")["imp"]


@claim("vlx_gain_ns7_150k")
def vlx_gain_ns7(med, c):
    n, note = _at(med, c)
    return _gain(med, n, {"list": "cll", "ns": 7, "kgc": 0}, {"list": "vlx", "ns": 7, "kgc": 0}), note


@claim("gain_grows_with_N")
def gain_grows_with_n(med, c):
    g = _gains_vs_n(med, "vlx")
    _need_points(g, 3, "values of N")
    slope = np.polyfit(np.log(g.index.to_numpy(float)), g.to_numpy(float), 1)[0]
    span = math.log(g.index.max() / g.index.min())
    return float(slope * span), (f"fitted change of the VL_X improvement from N = {_n_str(g.index.min())} "
                                 f"({g.iloc[0]:.1f} %) to {_n_str(g.index.max())} ({g.iloc[-1]:.1f} %)")


@claim("vl_faster_than_cll_all_N")
def vl_faster_all_n(med, c):
    gc, gx = _gains_vs_n(med, "vlc"), _gains_vs_n(med, "vlx")
    return _fraction([gc[n] > 0 and gx[n] > 0 for n in gx.index if n in gc.index],
                     "values of N where both are faster")


@claim("kgc_gain_8pct")
def kgc_gain_8pct(med, c):
    n, note = _at(med, c)
    return _gain(med, n, {"list": "cll", "kgc": 1}, {"list": "vlx", "kgc": 1}), note


@claim("kgc_gain_exceeds_plain")
def kgc_gain_exceeds_plain(med, c):
    n, note = _at(med, c)
    with_kgc = _gain(med, n, {"list": "cll", "kgc": 1}, {"list": "vlx", "kgc": 1})
    plain = _gain(med, n, {"list": "cll", "kgc": 0}, {"list": "vlx", "kgc": 0})
    return with_kgc - plain, f"{note}; with KGC {with_kgc:.1f} %, without {plain:.1f} %"


# ------------------------------------------------------------------ verdicts
def in_interval(value, bounds):
    lo, hi = bounds
    return (lo is None or value >= lo) and (hi is None or value <= hi)


def verdict(value, tolerance):
    if value is None or not math.isfinite(value):
        return "not measured"
    if in_interval(value, tolerance["reproduced"]):
        return "reproduced"
    return "partly" if in_interval(value, tolerance["partly"]) else "not reproduced"


def evaluate(c, data):
    """{claim fields..., measured, verdict, note} of claim `c` on raw rows `data`."""
    result = {**c, "measured": None, "verdict": "not measured", "note": ""}
    fn = CLAIMS.get(c["id"])
    med = medians(data) if len(data) else data
    min_n = c.get("min_n", MIN_N)
    try:
        if fn is None:
            raise NotMeasured("no measurement function for this claim in plots/claims.py")
        if med.empty or "n" not in med:
            raise NotMeasured("no results")
        if med["n"].max() < min_n:
            raise NotMeasured(f"largest N measured is {_n_str(med['n'].max())}; "
                              f"the claim needs N ≥ {_n_str(min_n)}")
        value, note = fn(med, c)
        result.update(measured=float(value), note=note,
                      verdict=verdict(float(value), c["tolerance"]))
    except NotMeasured as e:
        result["note"] = str(e)
    return result
