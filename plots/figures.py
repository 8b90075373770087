"""One function per figure of Domínguez et al. (2011), "Neighbour lists in SPH".

Each `figNN(data, out)` takes the rows of the experiment the figure is drawn
from (harness.results.load_run, filtered on `experiment`), writes
out/figNN.png and out/figNN.svg (headless, deterministic, atomic) and returns
one sentence describing what the data show. `table1(data, exp)` returns the
markdown of Table I and its sentence. Every plotted median carries its 95 %
bootstrap interval (harness.stats.RoundBootstrap, resampled by round, so an
improvement's interval is paired: CLL and VL of the same round form one
ratio), drawn as error bars and a shaded band. Axes follow the paper: runtime or memory
against N, improvement (t_ref - t)/t_ref in percent against N or n_s; runtime
is wall seconds per step (the paper plots hours for its whole simulation).
"""
import io
import os

os.environ.setdefault("SOURCE_DATE_EPOCH", "0")  # fixed dates in SVG/PDF metadata
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
import numpy as np  # noqa: E402

from harness import stats as S  # noqa: E402
from harness.fsio import write_atomic  # noqa: E402
from harness.results import format_n, idle_seconds, improvement, medians, pages_used, pick  # noqa: E402

plt.rcParams.update({"svg.hashsalt": "sphnl", "savefig.dpi": 110, "axes.grid": True,
                     "grid.alpha": 0.3, "font.size": 10, "legend.fontsize": 9})
GRIDDERS = {"A": "A sliding vector", "B": "B preconditioned vector",
            "C": "C static matrix", "D": "D linked list"}
LISTS = {"cll": "CLL", "vlc": "VL$_C$", "vlx": "VL$_X$"}
ORDERS = {"sort_x": "SortX", "sort_xy": "SortXY (Z-order)",
          "sort_xyz": "SortXYZ (Z-order)", "hilbert": "Hilbert (ours)"}
SERIAL = {"cell_order": "sort_x", "kgc": 0, "threads": 1}  # the paper's serial SortX runs
SORTED_B = {**SERIAL, "gridder": "B", "reorder": 1}   # its choice from Section 3.3 on
N_LABEL = "N (particles)"
NS_LABEL = "$n_s$ (steps a Verlet list is kept)"
MARKERS = "osD^vx*"
RESAMPLES = 100  # bootstrap replicates per figure; plots/report.py sets it from --resamples
# Set by plots/report.py when the times it passes are drift-corrected (harness/drift.py).
DRIFT_NOTE = ""


class NoData(Exception):
    """The results lack what a figure needs; the message says what."""


class Med:
    """The per-configuration medians of one figure's rows with their bootstrap
    replicates: `point` is the median table, `curves(fn)` evaluates a curve
    builder on it and on every replicate."""

    def __init__(self, boot):
        self.boot, self.point = boot, boot.point

    def where(self, **equal):
        rows = pick(self.point, **equal)
        if rows.empty:
            raise NoData("no successful benchmark entries with "
                         + (", ".join(f"{k}={v}" for k, v in equal.items()) or "any parameters"))
        return Med(self.boot.subset(self.point.index.isin(rows.index)))

    def curves(self, fn):
        """fn(median table) -> [(label, xs, ys)]; returns [(label, xs, ys, lo, hi)]."""
        point = fn(self.point)
        reps = [[] for _ in point]
        for tab in self.boot.tables():
            try:
                got = fn(tab)
            except Exception:  # noqa: BLE001 - a replicate that lost a point is left out
                continue
            if [g[0] for g in got] != [p[0] for p in point]:
                continue
            for i, (g, p) in enumerate(zip(got, point)):
                if len(g[2]) == len(p[2]):
                    reps[i].append(g[2])
        out = []
        for (label, xs, ys), r in zip(point, reps):
            if r:
                lo, hi = S.intervals(np.vstack(r), self.boot.level)
            else:
                lo, hi = np.full(len(ys), np.nan), np.full(len(ys), np.nan)
            out.append((label, xs, ys, lo, hi))
        return out


def _med(data, **equal):
    """The figure's configurations; where the rows hold several flow states
    the figure shows the paper's, t = 0.35 s (the claims pool the states)."""
    if not len(data) or not (~data["error_occurred"].astype(bool)).any():
        raise NoData("no successful benchmark entries")
    if "flow_time" in data and data["flow_time"].nunique() > 1:
        times = data["flow_time"].dropna().unique()
        equal.setdefault("flow_time", min(times, key=lambda t: abs(t - 0.35)))
    return Med(S.RoundBootstrap(data, resamples=RESAMPLES)).where(**equal)


def _footnote(fig, what):
    fig.text(0.99, -0.01, f"medians{DRIFT_NOTE}; {what}: 95 % bootstrap intervals (paired by round)",
             ha="right", va="top", fontsize=7, color="0.4")


def _plain(label):
    return label.replace("$_C$", "_C").replace("$_X$", "_X")


def _curves(med, by, y, labels, x="N"):
    """[(label, xs, ys)] with one curve per value of column `by`, in `labels` order."""
    out = []
    for key, label in labels.items():
        part = med[med[by] == key].sort_values(x)
        if len(part):
            out.append((label, part[x].to_numpy(float), part[y].to_numpy(float)))
    if not out:
        raise NoData(f"no values of {by} among {list(labels)}")
    return out


def _gain_curves(med, labels, ref, var, x="N", on=("particles",)):
    """Improvement curves, one per key of `labels`: runs var(key) against ref(key)."""
    out = []
    for key, label in labels.items():
        imp = improvement(med, ref(key), var(key), on=on, x=x)
        if len(imp):
            out.append((label, imp[x].to_numpy(float), imp["imp"].to_numpy(float)))
    if not out:
        raise NoData(f"no reference runs matching the variants {list(labels)}")
    return out


def _save(fig, out, fig_id):
    for ext, meta in (("png", {"Software": None}), ("svg", {"Date": None})):
        buf = io.BytesIO()
        fig.savefig(buf, format=ext, metadata=meta, bbox_inches="tight")
        write_atomic(out / f"{fig_id}.{ext}", buf.getvalue())
    plt.close(fig)


def _draw(out, fig_id, title, xlabel, panels):
    """Draw panels [(ylabel, curves, zero_line)] side by side and save PNG+SVG."""
    fig, axes = plt.subplots(1, len(panels), figsize=(6.4 * len(panels), 4.4), squeeze=False)
    for ax, (ylabel, curves, zero) in zip(axes[0], panels):
        for i, (label, xs, ys, lo, hi) in enumerate(curves):
            line = ax.errorbar(xs, ys, yerr=[np.clip(ys - lo, 0, None), np.clip(hi - ys, 0, None)],
                               marker=MARKERS[i % len(MARKERS)], capsize=3, label=label)
            if len(xs) > 1 and np.isfinite(lo).all() and np.isfinite(hi).all():
                ax.fill_between(xs, lo, hi, color=line[0].get_color(), alpha=0.15, lw=0)
        xs_all = np.concatenate([c[1] for c in curves])
        if xs_all.min() > 0 and xs_all.max() / xs_all.min() > 50:
            ax.set_xscale("log")
        if zero:
            ax.axhline(0, color="0.3", lw=0.8)
        else:  # runtimes, memory, speed-ups: positive quantities drawn from 0
            ax.set_ylim(bottom=0)
        ax.set(xlabel=xlabel, ylabel=ylabel)
        if xlabel == NS_LABEL:
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.legend()
    fig.suptitle(title)
    _footnote(fig, "bars and bands")
    _save(fig, out, fig_id)


def _at_end(curves, unit, digits=3, best=None):
    """'At N = x: a 1.2 ms, b ...' at the largest x shared by all curves;
    best='min'/'max' ranks the curves and gives ratios to the best."""
    x_end = min(c[1].max() for c in curves)
    vals, ci = {}, {}
    for lab, xs, ys, lo, hi in curves:
        i = int(np.argmin(abs(xs - x_end)))
        vals[lab], ci[lab] = float(ys[i]), (float(lo[i]), float(hi[i]))
    order = sorted(vals, key=vals.get, reverse=best == "max") if best else list(vals)
    parts = [f"{_plain(lab)} {vals[lab]:.{digits}g}{unit} [{ci[lab][0]:.{digits}g}, {ci[lab][1]:.{digits}g}]"
             for lab in order]
    if best == "min" and len(order) > 1 and vals[order[0]] > 0:
        parts = [parts[0]] + [f"{p} ({vals[lab] / vals[order[0]]:.2f}x)"
                              for p, lab in zip(parts[1:], order[1:])]
    return x_end, ", ".join(parts)


METRICS = {"t": ("wall time per step (s)", " s", "seconds per step from fastest"),
           "mem_mb": ("neighbour-structure memory (MB)", " MB", "memory from smallest")}


def _metric_vs_n(data, out, fig_id, title, y, by, labels, **equal):
    """Runtime (y='t') or memory (y='mem_mb') vs N, one curve per value of `by`."""
    ylabel, unit, what = METRICS[y]
    curves = _med(data, **equal).curves(lambda m: _curves(m, by, y, labels))
    _draw(out, fig_id, title, N_LABEL, [(ylabel, curves, False)])
    n, text = _at_end(curves, unit, best="min")
    return f"At N = {format_n(n)}, {what}: {text}."


def _gain_vs_n(data, out, fig_id, title, labels, ref, var, smooth=False, **equal):
    curves = _med(data, **equal).curves(lambda m: _gain_curves(m, labels, ref, var))
    _draw(out, fig_id, title, N_LABEL, [("improvement in time (%)", curves, True)])
    n, text = _at_end(curves, " %", best="max")
    return (f"At N = {format_n(n)}, improvement from largest [95 % interval]: {text}. "
            + (smooth_trend(curves, "ln N", np.log) if smooth else "")).rstrip()


def smooth_trend(curves, xname, transform):
    """Whether the intervals allow a smooth trend where the medians zig-zag:
    a low-order polynomial in `xname` (quadratic; cubic from 6 points),
    fitted to the medians weighted by 1 / interval width, passes through how
    many of the intervals?"""
    parts = []
    for label, xs, ys, lo, hi in curves:
        ok = np.isfinite(lo) & np.isfinite(hi)
        if ok.sum() < 4:
            continue
        x, y = transform(xs[ok]), ys[ok]
        width = np.maximum(hi[ok] - lo[ok], 1e-9)
        degree = 3 if ok.sum() >= 6 else 2
        fit = np.polyval(np.polyfit(x, y, degree, w=1 / width), x)
        inside = int(((fit >= lo[ok] - 1e-12) & (fit <= hi[ok] + 1e-12)).sum())
        signs = np.sign(np.diff(y))
        zigzag = int((signs[1:] * signs[:-1] < 0).sum())
        verdict = ("the intervals allow a smooth trend" if inside == ok.sum()
                   else f"the intervals do not allow a smooth trend ({ok.sum() - inside} point(s) off it)")
        parts.append(f"{_plain(label)}: the medians change direction {zigzag} time(s); a "
                     f"{'cubic' if degree == 3 else 'quadratic'} in {xname} passes through {inside} of "
                     f"{ok.sum()} intervals: {verdict}")
    return ("Smoothness: " + "; ".join(parts) + ".") if parts else ""


def fig06(data, out):
    """Fig. 6: runtime of gridders A-D vs N (CLL, not reordered, SortX)."""
    return _metric_vs_n(data, out, "fig06", "Fig. 6: runtime per gridder (CLL, not reordered)",
                        "t", "gridder", GRIDDERS, **SERIAL, list="cll", reorder=0)


def fig07(data, out):
    """Fig. 7: memory of gridders A-D vs N (not reordered)."""
    return _metric_vs_n(data, out, "fig07", "Fig. 7: memory per gridder (not reordered)",
                        "mem_mb", "gridder", GRIDDERS, **SERIAL, list="cll", reorder=0)


def fig08(data, out):
    """Fig. 8: improvement from reordering per gridder vs N (each vs itself unsorted)."""
    return _gain_vs_n(data, out, "fig08", "Fig. 8: improvement from reordering per gridder (SortX)",
                      GRIDDERS, lambda g: {"gridder": g, "reorder": 0},
                      lambda g: {"gridder": g, "reorder": 1}, **SERIAL, list="cll")


def fig09(data, out):
    """Fig. 9: improvement from reordering per cell ordering vs N, gridder B."""
    return _gain_vs_n(data, out, "fig09", "Fig. 9: improvement from reordering per ordering (gridder B)",
                      ORDERS, lambda o: {"cell_order": o, "reorder": 0},
                      lambda o: {"cell_order": o, "reorder": 1}, list="cll", gridder="B", kgc=0, threads=1)


def fig10(data, out):
    """Fig. 10: runtime of gridders A-D vs N after reordering."""
    return _metric_vs_n(data, out, "fig10", "Fig. 10: runtime per gridder after reordering",
                        "t", "gridder", GRIDDERS, **SERIAL, list="cll", reorder=1)


def fig11(data, out):
    """Fig. 11: memory of gridders A-D vs N after reordering."""
    return _metric_vs_n(data, out, "fig11", "Fig. 11: memory per gridder after reordering",
                        "mem_mb", "gridder", GRIDDERS, **SERIAL, list="cll", reorder=1)


def fig12(data, out):
    """Fig. 12: runtime of CLL and VL (n_s = 1) vs N."""
    return _metric_vs_n(data, out, "fig12", "Fig. 12: runtime of CLL and VL ($n_s$ = 1)",
                        "t", "list", {"cll": "CLL", "vlc": "VL"}, **SORTED_B, list_steps=1)


def fig13(data, out):
    """Fig. 13: memory of CLL and VL (n_s = 1) vs N."""
    return _metric_vs_n(data, out, "fig13", "Fig. 13: memory of CLL and VL ($n_s$ = 1)",
                        "mem_mb", "list", {"cll": "CLL", "vlc": "VL"}, **SORTED_B, list_steps=1)


def _fixed_n(med):
    """Fig. 14/15 are at one N: 31 239 when measured, else the largest.
    Returns the Med at that N and the particles actually simulated."""
    n = 31239 if (med.point["particles"] == 31239).any() else med.point["particles"].max()
    rows = med.where(particles=n)
    return rows, rows.point["N"].median()


def fig14(data, out):
    """Fig. 14: improvement of VL_C and VL_X over CLL vs n_s (CLL paired at each n_s)."""
    med, n = _fixed_n(_med(data, **SORTED_B))
    curves = med.curves(lambda m: _gain_curves(m, {"vlc": LISTS["vlc"], "vlx": LISTS["vlx"]},
                                               lambda _: {"list": "cll"}, lambda lst: {"list": lst},
                                               x="list_steps", on=("particles", "list_steps")))
    _draw(out, "fig14", f"Fig. 14: improvement over CLL vs $n_s$, N = {format_n(n)}", NS_LABEL,
          [("improvement in time (%)", curves, True)])
    best = [f"{_plain(lab)} {ys.max():.2g} % [{lo[ys.argmax()]:.2g}, {hi[ys.argmax()]:.2g}] at "
            f"n_s = {xs[ys.argmax()]:.0f}" for lab, xs, ys, lo, hi in curves]
    return (f"At N = {format_n(n)} the largest improvements over CLL [95 % interval] are "
            + " and ".join(best) + ". " + smooth_trend(curves, "n_s", lambda x: x)).rstrip()


def fig15(data, out):
    """Fig. 15: memory of CLL, VL_X and VL_C vs n_s."""
    med, n = _fixed_n(_med(data, **SORTED_B))
    curves = med.curves(lambda m: _curves(m, "list", "mem_mb", LISTS, x="list_steps"))
    _draw(out, "fig15", f"Fig. 15: memory vs $n_s$, N = {format_n(n)}", NS_LABEL,
          [("neighbour-structure memory (MB)", curves, False)])
    ns, text = _at_end(curves, " MB", best="min")
    return f"At N = {format_n(n)} and n_s = {ns:.0f}, memory from smallest: {text}."


def fig16(data, out):
    """Fig. 16: improvement of VL_C and VL_X over CLL at n_s = 7 vs N."""
    return _gain_vs_n(data, out, "fig16", "Fig. 16: improvement over CLL at $n_s$ = 7",
                      {"vlc": LISTS["vlc"], "vlx": LISTS["vlx"]}, lambda _: {"list": "cll"},
                      lambda lst: {"list": lst}, smooth=True, **SORTED_B, list_steps=7)


def fig17(data, out):
    """Fig. 17: improvement of VL_X over CLL, with and without KGC, n_s = 7 vs N."""
    med = _med(data, cell_order="sort_x", threads=1, gridder="B", reorder=1, list_steps=7)  # both kgc
    curves = med.curves(lambda m: _gain_curves(m, {0: "VL$_X$", 1: "VL$_X$ with KGC"},
                                               lambda k: {"list": "cll", "kgc": k},
                                               lambda k: {"list": "vlx", "kgc": k}))
    _draw(out, "fig17", "Fig. 17: improvement of VL$_X$ over CLL, with and without KGC ($n_s$ = 7)",
          N_LABEL, [("improvement in time (%)", curves, True)])
    n, text = _at_end(curves, " %", best="max")
    return f"At N = {format_n(n)}, improvement of VL_X over CLL (same correction) [95 % interval]: {text}."


def cellindex(data, out):
    """Section 3.2: cost of the cell index per particle for each ordering ('~100x')."""
    med = _med(data, family="cellindex")
    curves = med.curves(lambda m: _curves(m.assign(ns_per=1e9 * m["s_per_particle"]),
                                          "cell_order", "ns_per", ORDERS))
    _draw(out, "cellindex", "Cost of the cell index per particle (Section 3.2)", N_LABEL,
          [("ns per particle", curves, False)])
    n, text = _at_end(curves, " ns", best="min")
    return f"At N = {format_n(n)}, nanoseconds per particle from cheapest: {text}."


def _thread_curves(med):
    med = med.assign(us=1e6 * med["t"] / med["N"], key=med["list"] + "/" + med["threads"].astype(str))
    labels = {f"{lst}/{th}": f"{LISTS[lst]}, {th} thread{'s' if th > 1 else ''}"
              for lst in LISTS for th in sorted(med["threads"].unique())}
    return _curves(med, "key", "us", labels)


def _speedups(med):
    speed = []
    for lst in LISTS:
        one = pick(med, list=lst, threads=1).set_index("particles")
        for th in sorted(t for t in med["threads"].unique() if t > 1):
            many = pick(med, list=lst, threads=th).set_index("particles")
            common = one.index.intersection(many.index)
            if len(common):
                speed.append((f"{LISTS[lst]}, {th} threads", one.loc[common, "N"].to_numpy(float),
                              (one.loc[common, "t"] / many.loc[common, "t"]).to_numpy(float)))
    return speed


def beyond_threads(data, out):
    """Beyond the paper: 1 vs 2 threads for CLL and VL_X (n_s = 7), larger N."""
    med = _med(data)
    per = med.curves(_thread_curves)
    speed = med.curves(_speedups) if _speedups(med.point) else []
    panels = [("wall time per particle and step (µs)", per, False)]
    if speed:
        panels.append(("speed-up over 1 thread", speed, False))
    _draw(out, "beyond_threads", "Beyond the paper: threads and larger N", N_LABEL, panels)
    n, text = _at_end(speed or per, "x" if speed else " µs", best="max" if speed else "min")
    return f"At N = {format_n(n)}, " + (f"speed-up over one thread: {text}." if speed
                                       else f"µs per particle-step: {text}.")


IMPLS = ("sphnl", "nanoflann")
CALLS = {"warm": "warm call (buffers reused)", "first": "first call (fresh objects and memory)"}


def geometric_mean(values):
    return float(np.exp(np.mean(np.log(np.asarray(values, float)))))


def _peer_curves(med, call):
    """Entries per second against N, one curve per implementation and thread
    count: the geometric mean over the clouds and memory orders measured."""
    m = med[med["call"] == call]
    out = []
    for impl in IMPLS:
        for th in sorted(m["threads"].unique()):
            part = m[(m["impl"] == impl) & (m["threads"] == th)]
            if len(part):
                g = part.groupby("particles").agg(N=("N", "first"), eps=("entries_per_s", geometric_mean)).sort_values("N")
                out.append((f"{impl}, {th} thread{'s' if th > 1 else ''}", g["N"].to_numpy(float),
                            g["eps"].to_numpy(float)))
    if not out:
        raise NoData(f"no {call} calls of {', '.join(IMPLS)}")
    return out


def peers(data, out):
    """Beyond the paper: sphnl's search and nanoflann's radius search building
    the same full lists (entries per second, warm and first call)."""
    med = _med(data, family="search")
    if "impl" not in med.point or not set(IMPLS) <= set(med.point["impl"]):
        raise NoData("needs both implementations (impl: sphnl and nanoflann)")
    calls = [c for c in CALLS if c in set(med.point["call"])]
    panels = [(f"entries per second, {CALLS[c]}", med.curves(lambda m, c=c: _peer_curves(m, c)), False)
              for c in calls]
    _draw(out, "peers", "Beyond the paper: full neighbour lists, sphnl and nanoflann "
          "(geometric mean over lattice/random clouds, generated/shuffled order)", N_LABEL, panels)
    n, text = _at_end(panels[0][1], " /s", best="max")
    return (f"At N = {format_n(n)}, list entries per second of a {calls[0]} call from fastest "
            f"[95 % interval]: {text}.\n\n" + _peer_table(med))


PEER_KEYS = ("cloud", "memory_order", "call")


def _peer_ratios(tab, n):
    """{(cloud, order, call, threads): sphnl / nanoflann entries per second} and
    {(impl, cloud, order, call): 2-thread over 1-thread entries per second} at N = n."""
    m = tab[tab["particles"] == n].set_index(["impl", *PEER_KEYS, "threads"])["entries_per_s"]
    ratio, speedup = {}, {}
    for key in m.index:
        impl, rest, th = key[0], key[1:-1], key[-1]
        if impl == "sphnl" and ("nanoflann", *rest, th) in m.index:
            ratio[(*rest, th)] = m[key] / m[("nanoflann", *rest, th)]
        if th == 2 and (impl, *rest, 1) in m.index:
            speedup[(impl, *rest)] = m[key] / m[(impl, *rest, 1)]
    return ratio, speedup


def _peer_table(med):
    """Markdown: every configuration at the largest N, sphnl over nanoflann and
    each implementation's 2-thread speed-up, each with its interval."""
    n = int(med.point["particles"].max())
    ratio, speedup = _peer_ratios(med.point, n)
    keys = [("ratio", k) for k in ratio] + [("speedup", k) for k in speedup]

    def values(tab):
        got = dict(zip(("ratio", "speedup"), _peer_ratios(tab, n)))
        return np.array([got[kind].get(k, np.nan) for kind, k in keys], float)
    point, reps = med.boot.evaluate(values)
    lo, hi = S.intervals(reps, med.boot.level)
    ci = {key: (v, l, h) for key, v, l, h in zip(keys, point, lo, hi)}

    def cell(kind, key):
        if (kind, key) not in ci:
            return "–"
        value, low, high = ci[(kind, key)]
        return f"{value:.3g}" if not np.isfinite(low) else f"{value:.3g} [{low:.3g}, {high:.3g}]"
    threads = sorted({k[-1] for k in ratio})
    rows = sorted({k[:-1] for k in ratio} | {k[1:] for k in speedup})
    head = (["cloud", "memory order", "call"] + [f"sphnl / nanoflann, {t} thr." for t in threads]
            + [f"{impl} 2 thr. / 1" for impl in IMPLS])
    lines = [f"Every configuration at N = {format_n(n)} (entries per second; medians [95 % interval]):", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        cells = [cell("ratio", (*row, t)) for t in threads] + [cell("speedup", (impl, *row)) for impl in IMPLS]
        lines.append("| " + " | ".join([*row, *cells]) + " |")
    lines += ["", "Above 1, sphnl lists faster than nanoflann; the speed-ups are entries per second on two "
              "threads over one, each paired by round."]
    return "\n".join(lines)


def _first_call_table(tab, n):
    """{(state, "ratio"|impl, config): value} at N = n: sphnl / nanoflann
    entries per second, and each implementation's seconds per first call in
    each idle state over its just-freed call, config = (cloud, order, threads)."""
    m = tab[(tab["particles"] == n) & (tab["call"] == "first")]
    m = m.set_index(["impl", "freed_memory", "cloud", "memory_order", "threads"])
    out = {}
    for (impl, state, *config) in m.index:
        config = tuple(config)
        if impl == "sphnl" and ("nanoflann", state, *config) in m.index:
            out[(state, "ratio", config)] = (m.loc[(impl, state, *config), "entries_per_s"]
                                             / m.loc[("nanoflann", state, *config), "entries_per_s"])
        if state != "just_freed" and (impl, "just_freed", *config) in m.index:
            out[(state, impl, config)] = (m.loc[(impl, state, *config), "s_call"]
                                          / m.loc[(impl, "just_freed", *config), "s_call"])
    return out


def _freed_order(state):
    """Just freed first, then the idle states by their seconds."""
    idle = idle_seconds(state)
    return (0, 0) if state == "just_freed" else (1, idle) if idle else (2, 0)


def _freed_label(state):
    idle = idle_seconds(state)
    return "just freed" if state == "just_freed" else f"idle {idle} s" if idle else state


def peers_first_call(data, out):
    """Beyond the paper: first calls of sphnl and nanoflann with the memory
    they find controlled (just freed, or idle long enough for this VM to hand
    it to its host): sphnl over nanoflann per configuration, and what the
    idle memory costs each implementation."""
    med = _med(data, family="search", call="first")
    if "freed_memory" not in med.point or not set(IMPLS) <= set(med.point["impl"]):
        raise NoData("needs both implementations (impl: sphnl and nanoflann) and a freed_memory axis")
    n = int(med.point["particles"].max())
    keys = sorted(_first_call_table(med.point, n), key=str)
    if not keys:
        raise NoData(f"no first call measured with both implementations at N = {format_n(n)}")

    def values(tab):
        got = _first_call_table(tab, n)
        return np.array([got.get(k, np.nan) for k in keys], float)
    point, reps = med.boot.evaluate(values)
    lo, hi = S.intervals(reps, med.boot.level)
    est = {k: (v, a, z) for k, v, a, z in zip(keys, point, lo, hi)}
    configs = sorted({k[2] for k in keys})
    labels = [f"{cloud}\n{order}\n{th} thr." for cloud, order, th in configs]
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6))
    panels = ((axes[0], "ratio", "sphnl / nanoflann, entries per second",
               sorted({k[0] for k in keys if k[1] == "ratio"}, key=_freed_order)),
              (axes[1], None, "seconds of a first call, idle over just freed", None))
    for ax, what, ylabel, states in panels:
        series = ([(st, "ratio") for st in states] if what == "ratio" else
                  sorted({(k[0], k[1]) for k in keys if k[1] != "ratio"}, key=lambda k: (_freed_order(k[0]), k[1])))
        width = 0.8 / max(1, len(series))
        for j, (state, kind) in enumerate(series):
            ys, yl, yh = (np.array([est.get((state, kind, c), (np.nan,) * 3)[i] for c in configs]) for i in range(3))
            x = np.arange(len(configs)) + (j - (len(series) - 1) / 2) * width
            label = _freed_label(state) if kind == "ratio" else f"{kind}, {_freed_label(state)}"
            ax.bar(x, ys, width, label=label, alpha=0.85)
            ax.errorbar(x, ys, yerr=[np.clip(ys - yl, 0, None), np.clip(yh - ys, 0, None)], fmt="none",
                        ecolor="0.2", capsize=3)
        if what == "ratio":
            ax.axhline(5, color="0.3", lw=0.8, ls="--", label="target 5x")
        else:
            ax.axhline(1, color="0.3", lw=0.8)
        ax.set_xticks(range(len(configs)), labels, fontsize=8)
        ax.set(ylabel=ylabel)
        ax.set_ylim(bottom=0)
        ax.legend()
    used = pages_used(med.point[med.point["impl"] == "sphnl"])
    fig.suptitle(f"Beyond the paper: first calls, memory just freed or idle, N = {format_n(n)}"
                 + (f"; sphnl's lists on {used} pages" if used else ""))
    _footnote(fig, "error bars")
    _save(fig, out, "peers_first_call")
    parts = []
    for state in sorted({k[0] for k in keys if k[1] == "ratio"}, key=_freed_order):
        ratios = [(est[(state, "ratio", c)], c) for c in configs if (state, "ratio", c) in est]
        (v, a, z), c = min(ratios, key=lambda r: r[0][0])
        parts.append(f"{_freed_label(state)} {v:.3g}x [{a:.3g}, {z:.3g}] ({c[0]}, {c[1]}, {c[2]} thr.)")
    return (f"At N = {format_n(n)}, the smallest sphnl / nanoflann ratio of entries per second on a first call, "
            f"by the memory it found [95 % interval]: " + "; ".join(parts) + ".")


# ------------------------------------------------------ counters (valgrind)
COUNTER_PHASES = (("neighbour_list", "neighbour list", "///"), ("force", "force", None),
                  ("update", "update", ".."))
COUNTER_METRICS = (("ir", "instructions"), ("d1_misses", "D1 misses"), ("ll_misses", "LL misses"))
CACHE_MODELS = {"this_machine": "this machine's caches", "nehalem_2010": "2010 server (assumed: 8 MiB LL)"}


def _counter_bars(data, out, fig_id, title, configs):
    """Counts per particle-step (rows: cache models; columns: instructions,
    D1 misses, LL misses), one group of bars per N, one bar per
    configuration of `configs` ({label: column values}), stacked by phase of
    Table I. Counts repeat exactly (one round): no intervals to draw."""
    if not len(data) or (data["error_occurred"].astype(bool)).all():
        raise NoData("no successful counters entries")
    med = medians(data[~data["error_occurred"].astype(bool)])
    models = [m for m in CACHE_MODELS if m in set(med.get("cache_model", []))]
    if not models:
        raise NoData("no cache_model among " + ", ".join(CACHE_MODELS))
    ns_ = sorted(med["particles"].unique())
    fig, axes = plt.subplots(len(models), len(COUNTER_METRICS), figsize=(15, 3.9 * len(models)), squeeze=False)
    width = 0.8 / len(configs)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for r, model in enumerate(models):
        for c, (metric, what) in enumerate(COUNTER_METRICS):
            ax = axes[r][c]
            for k, (label, equal) in enumerate(configs.items()):
                bottom = np.zeros(len(ns_))
                for phase, phase_label, hatch in COUNTER_PHASES:
                    ys = np.array([_count(med, metric, phase, particles=n, cache_model=model, **equal) for n in ns_])
                    ax.bar(np.arange(len(ns_)) + (k - (len(configs) - 1) / 2) * width, ys, width, bottom=bottom,
                           color=colours[k % len(colours)], hatch=hatch, edgecolor="white", lw=0.3,
                           label=label if phase == "force" else None)
                    bottom += ys
            ax.set_xticks(range(len(ns_)), [f"N = {format_n(n)}" for n in ns_])
            ax.set(ylabel=f"{what} per particle-step", title=f"{what}, {CACHE_MODELS[model]}")
            if r == 0 and c == 0:
                ax.legend(fontsize=7)
    fig.suptitle(title)
    fig.text(0.99, -0.01, "bars stacked by phase: neighbour list (hatched ///), force (plain), update (dotted); "
             "callgrind counts of one window, exact", ha="right", va="top", fontsize=7, color="0.4")
    _save(fig, out, fig_id)
    n, model = ns_[-1], models[-1]
    parts = [f"{_plain(label).replace('$n_s$', 'n_s')} {_count(med, 'll_misses', None, particles=n, cache_model=model, **eq):.3g}"
             for label, eq in configs.items()]
    return (f"At N = {format_n(n)} with the {CACHE_MODELS[model]}, LL misses per particle-step: "
            + ", ".join(parts) + ".")


def _count(med, metric, phase, **equal):
    rows = pick(med, **equal)
    if rows.empty:
        raise NoData("no counters entry with " + ", ".join(f"{k}={v}" for k, v in equal.items()))
    col = f"{metric}_{phase}_per_particle_step" if phase else f"{metric}_per_particle_step"
    return float(rows[col].iloc[0])


def counters_lists(data, out):
    """Counts per particle-step by phase: CLL, VL_C and VL_X at n_s = 1 and 7."""
    configs = {"CLL": {"list": "cll", "list_steps": 1}}
    for lst in ("vlc", "vlx"):
        for ns in (1, 7):
            configs[f"{LISTS[lst]} $n_s$={ns}"] = {"list": lst, "list_steps": ns}
    return _counter_bars(data, out, "counters_lists", "Counts per particle-step: lists (B, SortX, reordered)",
                         configs)


def counters_reorder(data, out):
    """Counts per particle-step by phase: CLL with and without reordering."""
    return _counter_bars(data, out, "counters_reorder", "Counts per particle-step: reordering (CLL, B, SortX)",
                         {"not reordered": {"reorder": 0}, "reordered": {"reorder": 1}})


def counters_vl_force(data, out):
    """Counts per particle-step by phase: CLL against VL_X (n_s = 7) at each N,
    to split VL_X's shrinking force-phase saving into work and misses."""
    return _counter_bars(data, out, "counters_vl_force",
                         "Counts per particle-step: CLL and VL$_X$ ($n_s$ = 7) against N (B, SortX, reordered)",
                         {"CLL": {"list": "cll"}, f"{LISTS['vlx']} $n_s$=7": {"list": "vlx"}})


# ------------------------------------------------------------ ranks (mpi kind)
LAYOUTS = {(2, 1): "2 ranks x 1 thread", (1, 2): "1 rank x 2 threads", (2, 2): "2 ranks x 2 threads",
           (4, 1): "4 ranks x 1 thread", (1, 4): "1 rank x 4 threads"}


def _layout_label(ranks, threads):
    return LAYOUTS.get((ranks, threads), f"{ranks} ranks x {threads} threads")


def _mpi_speedups(med):
    """Speed-up over 1 rank x 1 thread against N, one curve per list and layout."""
    out = []
    for lst in ("cll", "vlx"):
        one = pick(med, list=lst, ranks=1, threads=1).set_index("particles")
        for (r, t), part in pick(med, list=lst).groupby(["ranks", "threads"]):
            if r * t == 1:
                continue
            part = part.set_index("particles")
            common = one.index.intersection(part.index).sort_values()
            if len(common):
                out.append((f"{LISTS[lst]}, {_layout_label(r, t)}", one.loc[common, "N"].to_numpy(float),
                            (one.loc[common, "t"] / part.loc[common, "t"]).to_numpy(float)))
    return out


def _mpi_gain_per_rank(med):
    """VL_X's improvement over CLL against N/P, one curve per rank count (1 thread per rank)."""
    out = []
    for r in sorted(med["ranks"].unique()):
        imp = improvement(pick(med, ranks=r, threads=1), {"list": "cll"}, {"list": "vlx"}, x="n_per_rank")
        if len(imp):
            out.append((f"{r} rank{'s' if r > 1 else ''} x 1 thread", imp["n_per_rank"].to_numpy(float),
                        imp["imp"].to_numpy(float)))
    return out


def _mpi_comm_share(med):
    out = []
    for lst in ("cll", "vlx"):
        for (r, t), part in pick(med, list=lst).groupby(["ranks", "threads"]):
            if r > 1:
                part = part.sort_values("N")
                out.append((f"{LISTS[lst]}, {_layout_label(r, t)}", part["N"].to_numpy(float),
                            100 * part["communication_share"].to_numpy(float)))
    return out


def beyond_mpi(data, out):
    """Beyond the paper: ranks and threads (sphnl run under mpirun): speed-up
    over one core, VL_X's improvement against the particles per rank N/P, and
    the communication share of the step."""
    med = _med(data, family="mpi")
    if "ranks" not in med.point:
        raise NoData("no ranks axis (the mpi kind)")
    speed = med.curves(_mpi_speedups) if _mpi_speedups(med.point) else []
    gain = med.curves(_mpi_gain_per_rank) if _mpi_gain_per_rank(med.point) else []
    comm = med.curves(_mpi_comm_share) if _mpi_comm_share(med.point) else []
    if not speed and not gain:
        raise NoData("needs runs on 1 x 1 and more cores, or CLL and VL_X pairs")
    fig, axes = plt.subplots(1, 3, figsize=(19.2, 4.4))
    for ax, (ylabel, xlabel, curves, zero) in zip(axes, (
            ("speed-up over 1 rank x 1 thread", N_LABEL, speed, False),
            ("VL$_X$ improvement over CLL (%)", "N / P (particles per rank)", gain, True),
            ("communication share of the step (%)", N_LABEL, comm, False))):
        for i, (label, xs, ys, lo, hi) in enumerate(curves):
            ax.errorbar(xs, ys, yerr=[np.clip(ys - lo, 0, None), np.clip(hi - ys, 0, None)],
                        marker=MARKERS[i % len(MARKERS)], capsize=3, label=label)
        ax.set_xscale("log")
        if zero:
            ax.axhline(0, color="0.3", lw=0.8)
        else:
            ax.set_ylim(bottom=0)
        ax.set(xlabel=xlabel, ylabel=ylabel)
        if curves:
            ax.legend()
    fig.suptitle("Beyond the paper: CLL and VL$_X$ ($n_s$ = 7) on ranks and threads "
                 "(windows from t = 0, slowest rank)")
    _footnote(fig, "bars")
    _save(fig, out, "beyond_mpi")
    parts = []
    if speed:
        n, text = _at_end(speed, "x", best="max")
        parts.append(f"At N = {format_n(n)}, speed-up over one core: {text}.")
    if gain:
        parts.append("VL_X improvement over CLL at the smallest N/P of each rank count: " + ", ".join(
            f"{_plain(lab)} {ys[0]:.3g} % [{lo[0]:.3g}, {hi[0]:.3g}] at N/P = {format_n(xs[0])}"
            for lab, xs, ys, lo, hi in gain) + ".")
    return " ".join(parts)


FIGURES = {f.__name__: f for f in (fig06, fig07, fig08, fig09, fig10, fig11, fig12, fig13,
                                   fig14, fig15, fig16, fig17, cellindex, beyond_threads, peers, peers_first_call,
                                   counters_lists, counters_reorder, counters_vl_force, beyond_mpi)}

PHASES = (("Neighbour List", "s_neighbour_list", "list"), ("Force Computation", "s_force", "force"),
          ("System Update", "s_update", "update"))


def table1(data, exp):
    """Table I: share of each phase in the runtime of a step, CLL and VL (n_s = 1).

    Returns (markdown, sentence). Shares are of the sum of the three timed
    phases; the paper values come from the experiment's claims."""
    med = _med(data, list_steps=1, kgc=0).point
    n = med["particles"].max()
    paper = {c["id"]: c["paper_value"] for c in exp.get("claims", [])}
    cols, shares = [], {}
    for lst, key in (("cll", "cll"), ("vlc", "vl")):
        row = pick(med, particles=n, list=lst)
        if row.empty:
            raise NoData(f"no {lst} run at N = {n}")
        row = row.iloc[0]
        total = sum(row[col] for _, col, _ in PHASES)
        shares[key] = {ph: 100 * row[col] / total for _, col, ph in PHASES}
        cols.append(f"{100 * total / row['t']:.1f} %")
    lines = ["| Phase | CLL, paper | CLL, measured | VL, paper | VL, measured |",
             "|---|---:|---:|---:|---:|"]
    for name, _, ph in PHASES:
        lines.append(f"| {name} | {paper.get(f'table1_cll_{ph}', '?')} % | {shares['cll'][ph]:.1f} % "
                     f"| {paper.get(f'table1_vl_{ph}', '?')} % | {shares['vl'][ph]:.1f} % |")
    reps = int(pick(med, particles=n)["reps"].min())
    md = "\n".join(lines) + (
        f"\n\nMeasured at N = {format_n(pick(med, particles=n)['N'].iloc[0])} (gridder B, SortX, reordered), "
        f"median of {reps} repetition(s); VL = VL_C with n_s = 1. Shares are of the sum of the "
        f"three timed phases, which covers {cols[0]} (CLL) and {cols[1]} (VL) of the wall time per step. "
        f"The intervals of these shares are in the claims table (`table1_*`).\n")
    sentence = (f"The neighbour list takes {shares['cll']['list']:.1f} % of a CLL step and "
                f"{shares['vl']['list']:.1f} % of a VL step (paper: "
                f"{paper.get('table1_cll_list', '?')} % and {paper.get('table1_vl_list', '?')} %).")
    return md, sentence
