#!/usr/bin/python3
"""Draw every figure, Table I, REPRODUCTION.md and claims.json from a results folder alone.

    /usr/bin/python3 -m plots.report results/<run-id> [--experiments-dir experiments]
                                     [--resamples 1000] [--publish FILE]

(from the repository root, or with PYTHONPATH set to it: harness/__init__.py)

Writes RESULTS_DIR/figures/<id>.png|svg, RESULTS_DIR/table1.md,
RESULTS_DIR/claims.json (one object per claim: value, 95 % interval, bands,
verdict; docs/CONTRACTS.md) and RESULTS_DIR/REPRODUCTION.md (machine,
rounds under load, one data-derived sentence per figure, claims table with
`value [low, high]`). A missing experiment file skips its figures with a
line in the report.
"""
import argparse
import collections
import json
import math
import os
import pathlib
import sys

import numpy as np

from harness import drift as D
from harness import machine as M
from harness import stats as S
from harness.fsio import write_atomic
from harness.results import NOT_RESULTS, ResultsError, errors, load_experiments, load_run
from plots import claims as C
from plots import explanations as X
from plots import figures as F

HERE = pathlib.Path(__file__).resolve().parent

TITLE = ("Reproduction of Domínguez, Crespo, Gómez-Gesteira and Marongiu (2011), "
         "\"Neighbour lists in smoothed particle hydrodynamics\"")
UNITS = {"%": " %", "pp": " pp", "x": "x", "MB": " MB", "fraction": "", "": ""}
VERDICTS = C.VERDICTS
# The targets a run is checked against, printed with it (docs/MEASUREMENT.md, "Targets").
TARGET_PP = 2.0        # improvement claims at N >= 31 000: half-width at most 2 pp
TARGET_RATIO = 5.0     # ratio claims: half-width at most 5 % of the value
TARGET_RESOLVED = 0.8  # share of claims not `unresolved`
TINY_RESAMPLES = 20  # a tiny run is a smoke test of the pipeline: its intervals mean nothing
CLAIM_KEYS = ("id", "figure", "paper_value", "value", "ci_low", "ci_high", "unit", "at_n", "at_n_wanted", "band",
              "verdict", "repetitions", "rounds", "resolve", "note", "per_flow_time",
              "per_experiment", "related", "explanation")


def _num(value, unit):
    digits = ".2f" if unit in ("fraction", "x") else ".1f" if unit in ("%", "pp") else ".3g"
    return f"{value:{digits}}"


def fmt(value, unit):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    if isinstance(value, str):
        return value + UNITS.get(unit, "")
    return _num(value, unit) + UNITS.get(unit, " " + unit)


def fmt_ci(value, lo, hi, unit):
    """'5.6 % [2.1, 6.6]': the value with its 95 % interval, in the value's unit."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return fmt(value, unit)
    return f"{fmt(value, unit)} [{_num(lo, unit)}, {_num(hi, unit)}]"


def fmt_interval(bounds, unit):
    lo, hi = bounds
    return f"= {fmt(lo, unit)}" if lo == hi else f"{fmt(lo, unit)} to {fmt(hi, unit)}"


def memory_pages(m):
    """'; transparent huge pages madvise, free memory reported to the host':
    what decides a first call's page cost (machine.json; '' where older
    files lack it)."""
    parts = []
    if m.get("transparent_huge_pages"):
        parts.append(f"transparent huge pages {m['transparent_huge_pages']}")
    if m.get("free_memory_reported_to_host") is not None:
        parts.append("free memory reported to the host (the search defaults to base pages)"
                     if m["free_memory_reported_to_host"] else "free memory not reported to a host")
    return "; " + ", ".join(parts) if parts else ""


def machine_section(run_dir):
    path = run_dir / "machine.json"
    if not path.exists():
        return ["No machine.json in this run folder."], {}
    try:
        m = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ResultsError(f"{path}: not valid JSON ({e})") from None
    caches = m.get("caches") or m.get("caches_sysfs") or {}
    caches = ", ".join(f"{k} {v}" for k, v in caches.items())
    if caches and m.get("caches_source"):
        caches += f" (from {m['caches_source']})"
    mem = f"{m['memory_bytes'] / 2**30:.1f} GiB" if m.get("memory_bytes") else "not reported"
    dirty = " (uncommitted changes)" if m.get("git_dirty") else ""
    cpu = m.get("cpu_model") or "not reported"
    ident = [f"{k} {m[v]}" for k, v in (("family", "cpu_family"), ("model", "cpu_model_number"),
                                          ("stepping", "cpu_stepping")) if m.get(v) is not None]
    clock = [f"{m[k]:.0f} MHz {w}" for k, w in (("cpu_mhz", "current"), ("cpu_max_mhz", "max"))
             if isinstance(m.get(k), (int, float))]
    rows = [("CPU", f"{cpu}{' (' + ', '.join(ident) + ')' if ident else ''}, {m.get('cores') or '?'} cores, "
                    f"{m.get('logical_cpus') or '?'} logical CPUs"),
            ("Clock", ", ".join(clock) or "not reported"),
            ("Caches", caches or "not reported"), ("Memory", mem + memory_pages(m)),
            ("Compiler", m.get("compiler") or "not reported"),
            ("Git revision", f"{m.get('git_revision') or '?'}{dirty}"),
            ("Date (UTC)", m.get("date") or "?"), ("Size", m.get("size") or "?"),
            ("OS", m.get("os") or "not reported")]
    if m.get("pinning"):
        rows.append(("Pinning", json.dumps(m["pinning"]) if not isinstance(m["pinning"], str) else m["pinning"]))
    if m.get("loadavg_start") is not None:
        rows.append(("Load average", f"{m.get('loadavg_start')} at start, {m.get('loadavg_end')} at end"))
    if m.get("max_n"):
        rows.append(("N cap", f"sweep points above N = {m['max_n']:,} left out (--max-n)"))
    for part in m.get("earlier") or []:  # a run made in parts: each earlier invocation
        cap = f", N ≤ {part['max_n']:,}" if part.get("max_n") else ""
        forced = f", **merged by force**: {part.get('forced_merge_reason') or 'no reason given'}" \
            if part.get("forced_merge") else ""
        where = f", on {M.describe_identity(part['machine'])}" if part.get("machine") else ""
        rows.append(("Earlier part", f"{part.get('date', '?')}, revision "
                                     f"{(part.get('git_revision') or '?')[:12]}{cap}{where}{forced}"))
    for part in (m.get("parts") or [m]):
        reason = (part.get("builds") or {}).get("other_build_reason")
        if reason:
            rows.append(("Other build", f"**yes** ({part.get('date', '?')}): measured with a binary built from "
                                        f"other code than the checkout, --allow-other-build: {reason}"))
    if m.get("forced_merge"):
        rows.append(("Forced merge", "**yes**: parts from a dirty tree or different code were merged "
                                     f"with --force-merge ({m.get('forced_merge_reason') or 'no reason given'})"))
    return ["| | |", "|---|---|"] + [f"| {k} | {v} |" for k, v in rows], m


def rounds_section(run_dir):
    """Lines on the protocol and on the rounds measured under load, per experiment."""
    lines, flagged, old = [], 0, []
    for path in sorted(run_dir.glob("*.json")):
        if path.name in NOT_RESULTS or path.name.startswith("."):
            continue
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError):
            continue
        rounds = doc.get("sphnl_rounds")
        if not isinstance(rounds, list):
            old.append(path.stem)
            continue
        proto = doc.get("sphnl_protocol") or {}
        # the rule of today's harness, also on files measured under an older one
        loaded = [r for r in rounds if M.under_load(r)]
        flagged += len(loaded)
        desc = (f"- `{path.stem}`: {len(rounds)} rounds × {proto.get('reps_per_round', '?')} repetitions, "
                f"stopped: {proto.get('stop_reason', '?')}")
        if proto.get("target_halfwidth_pct") is not None:
            desc += f" (target half-width {proto['target_halfwidth_pct']} %)"
        if loaded:
            def most(key, pick=max):
                vals = [v for r in loaded for v in np.ravel([r.get(key)]) if isinstance(v, (int, float))]
                return f"{pick(vals):.2g}" if vals else "?"
            desc += (f"; **under load**: {len(loaded)} of {len(rounds)} rounds ("
                     + ", ".join(str(r.get("round", "?")) for r in loaded)
                     + f"; load average up to {most('loadavg_before')}/{most('loadavg_after')} before/after, "
                     f"other processes up to {most('other_busy_cores')} cores, steal up to {most('steal_pct')} %)")
        lines.append(desc)
        witness = witness_line(doc)
        if witness:
            lines.append("  " + witness)
    if old:
        lines.append(f"- {', '.join(f'`{o}`' for o in old)}: written before rounds were recorded "
                     "(no noise records); each repetition is resampled as its own round")
    return lines, flagged


# A repetition was measured on a slow machine when either witness fell below
# this share of its results file's median (the spread of an idle machine's
# witness is a few per cent).
SLOW_WITNESS = 0.85


def slow_witness(cores, mems):
    """Mask of the repetitions whose core or memory witness is below
    SLOW_WITNESS times its median (NaN, no witness: never slow)."""
    slow = np.zeros(len(cores), dtype=bool)
    for v in (np.asarray(cores, float), np.asarray(mems, float)):
        if np.isfinite(v).any():
            slow |= v < SLOW_WITNESS * np.nanmedian(v)
    return slow


def witness_line(doc):
    """One line on the machine witness of a results file (the core's and the
    memory path's speed recorded before every repetition): its range, and the
    rank correlation of a repetition's time, over its configuration's median,
    with each witness. None when the file has no witness counters."""
    by_config = collections.defaultdict(list)
    for b in doc.get("benchmarks", []):
        if b.get("run_type", "iteration") != "iteration":
            continue
        core, mem, t = b.get("witness_core_gflops"), b.get("witness_mem_gbps"), b.get("real_time")
        if not all(isinstance(v, (int, float)) and v > 0 for v in (core, mem, t)):
            continue
        by_config[b.get("run_name", b.get("name"))].append((t, core, mem))
    rel, cores, mems = [], [], []
    for reps in by_config.values():
        if len(reps) < 3:
            continue
        median = float(np.median([r[0] for r in reps]))
        for t, core, mem in reps:
            rel.append(t / median)
            cores.append(core)
            mems.append(mem)
    if len(rel) < 6:
        return None
    from scipy.stats import spearmanr  # only where witnesses were recorded
    rho_core = float(spearmanr(rel, cores)[0])
    rho_mem = float(spearmanr(rel, mems)[0])
    slow = [r for r, s in zip(rel, slow_witness(cores, mems)) if s]
    def fmt(v):
        return "n/a" if math.isnan(v) else f"{v:+.2f}"
    line = (f"witness over {len(rel)} repetitions: core {min(cores):.0f}-{max(cores):.0f} GFlop/s, "
            f"memory {min(mems):.1f}-{max(mems):.1f} GB/s; rank correlation of a repetition's time "
            f"(over its configuration's median) with them: {fmt(rho_core)} (core), {fmt(rho_mem)} (memory); "
            "negative: slower repetitions came with a slower witness")
    if slow:
        line += (f"; {len(slow)} repetition(s) with a witness below {SLOW_WITNESS * 100:g} % of the median, their "
                 f"times {min(slow):.2f}-{max(slow):.2f}x their configuration's median (kept in every estimate)")
    return line


def quiet_rows(df):
    """The rows of `df` without the repetitions measured on a slow machine
    (slow_witness within each experiment; rows without a witness are kept).
    Returns (rows, {experiment: repetitions left out})."""
    cols = ["witness_core_gflops", "witness_mem_gbps"]
    if not len(df) or not all(c in df.columns for c in cols):
        return df, {}
    slow = np.zeros(len(df), dtype=bool)
    for _, rows in df.groupby("experiment"):
        slow[df.index.get_indexer(rows.index)] = slow_witness(rows[cols[0]], rows[cols[1]])
    left_out = collections.Counter(df.loc[slow, "experiment"])
    return df[~slow], dict(left_out)


def targets(results):
    """Lines that check the targets of docs/MEASUREMENT.md on this run: share resolved,
    interval half-widths of improvement (pp) and ratio (x) claims."""
    measured = [r for r in results if r["verdict"] != "not measured"]
    resolved = [r for r in measured if r["verdict"] != "unresolved"]
    out = []
    share = len(resolved) / len(measured) if measured else math.nan
    out.append(f"- Resolved (not `unresolved`): {len(resolved)} of {len(measured)} measured claims "
               f"({100 * share:.0f} %; target ≥ {100 * TARGET_RESOLVED:.0f} %)" if measured else
               "- Resolved: no claim measured")

    def half(r):
        return max(r["value"] - r["ci_low"], r["ci_high"] - r["value"])
    imp = [r for r in measured if r["unit"] in ("%", "pp") and not r["id"].startswith("table1")
           and (r.get("at_n") or 0) >= 31000]
    if imp:
        worst = max(imp, key=half)
        ok = sum(half(r) <= TARGET_PP for r in imp)
        out.append(f"- Improvement claims at N ≥ 31 000: {ok} of {len(imp)} within ±{TARGET_PP:g} pp; widest "
                   f"`{worst['id']}` ±{half(worst):.1f} pp")
    ratios = [r for r in measured if r["unit"] == "x" and r["value"]]
    if ratios:
        rel = {r["id"]: 100 * half(r) / abs(r["value"]) for r in ratios}
        worst = max(rel, key=rel.get)
        ok = sum(v <= TARGET_RATIO for v in rel.values())
        out.append(f"- Ratio claims: {ok} of {len(ratios)} within ±{TARGET_RATIO:g} %; widest `{worst}` "
                   f"±{rel[worst]:.1f} %")
    return out


def add_quiet(found, quiet_evaluator, exp, left_out):
    """Puts each claim's value without the slow-witness repetitions into
    r["quiet"], where the claim's experiments lost any and it can still be
    measured. An experiment none of whose claims lost a repetition is not
    evaluated again."""
    lost_by_claim = [sum(left_out.get(e, 0) for e in r.get("experiments", [])) for r in found]
    if not any(lost_by_claim):
        return
    try:
        quiet = quiet_evaluator.experiment(exp, exp["claims"])
    except Exception:  # noqa: BLE001 - too few repetitions left: no sensitivity line
        return
    for r, q, lost in zip(found, quiet, lost_by_claim):
        if lost and q.get("value") is not None and r["verdict"] != "not measured":
            r["quiet"] = {"value": q["value"], "ci_low": q["ci_low"], "ci_high": q["ci_high"],
                          "verdict": q["verdict"], "left_out": lost}


def claim_record(exp, r):
    """The claims.json object of one evaluated claim."""
    rec = {k: r.get(k) for k in CLAIM_KEYS if k not in ("figure", "band")}
    rec["figure"] = figure_of(exp)
    rec["band"] = {"reproduced": r["tolerance"]["reproduced"], "partly": r["tolerance"]["partly"]}
    rec["band_reason"] = r.get("band_reason", "")
    rec["experiments"] = r.get("experiments", [])
    for key in ("value", "ci_low", "ci_high"):
        if isinstance(rec[key], float) and not math.isfinite(rec[key]):
            rec[key] = None
    return rec


def claim_note(r):
    parts = [r["note"]] if r["note"] else []
    for name, v in r.get("related", {}).items():
        parts.append(f"{name} {v['value']:.3g} [{v['ci_low']:.3g}, {v['ci_high']:.3g}]")
    if r.get("per_flow_time"):
        parts.append("per flow state: " + ", ".join(
            f"t = {p['flow_time']:g} s: {fmt_ci(p['value'], p['ci_low'], p['ci_high'], r['unit'])}"
            for p in r["per_flow_time"]))
    if r.get("per_experiment"):
        parts.append("each experiment alone: " + ", ".join(
            f"{p['experiment']} {fmt_ci(p['value'], p['ci_low'], p['ci_high'], r['unit'])}"
            for p in r["per_experiment"]))
    if r.get("quiet"):
        q = r["quiet"]
        parts.append(f"without the experiment's {q['left_out']} repetition(s) whose machine witness was below "
                     f"{SLOW_WITNESS * 100:g} % of its median: {fmt_ci(q['value'], q['ci_low'], q['ci_high'], r['unit'])} "
                     f"({q['verdict']})")
    if r.get("resolve"):
        parts.append("to resolve: " + r["resolve"])
    if r["verdict"] != "not measured":
        parts.append(f"at least {r['repetitions']} repetitions in {r['rounds']} resampled rounds per configuration")
    tol = r["tolerance"]
    parts.append(f"reproduced if {fmt_interval(tol['reproduced'], r['unit'])}, partly if "
                 f"{fmt_interval(tol['partly'], r['unit'])} ({r.get('band_reason', '')})")
    return "; ".join(parts).replace("|", "/")


def figure_of(exp):
    """What a claim belongs to: the paper's figure, or for a study that draws
    none (the ablations, run by `make ablations`) its experiment id."""
    return exp["figure"] or exp["id"]


def drift_section(summary):
    """Lines on the drift correction of each experiment (harness/drift.py)."""
    lines = []
    for exp, d in summary.items():
        pct = d.get("level_pct")
        level = ("" if pct is None else  # shares no configuration with another experiment
                 f"; level {'±0.0' if abs(pct) < 0.05 else f'{pct:+.1f}'} % against the experiments "
                 "it shares configurations with")
        if not d["repetitions"]:
            lines.append(f"- `{exp}`: no run order recorded; times as measured")
        elif d["window"] is None:
            lines.append((f"- `{exp}`: no window reduced the scatter of {d['scatter_pct_before']:.1f} %"
                          if math.isfinite(d["scatter_pct_before"])
                          else f"- `{exp}`: too few repetitions per round for a window") + level)
        else:
            lines.append(f"- `{exp}`: {d['window']} neighbour(s) on each side; scatter of the "
                         f"residuals {d['scatter_pct_before']:.1f} % → {d['scatter_pct_after']:.1f} % "
                         f"({d['repetitions']} repetitions)" + level)
    return lines


def build(run_dir, exp_dir, resamples=None, drift=True):
    """Draw everything; return (markdown of REPRODUCTION.md, claims.json records, verdict counts, drawn, skipped).
    drift: divide the machine's drift inside each round out of the times
    (harness/drift.py) before any median, interval or verdict."""
    experiments = load_experiments(exp_dir)
    for exp in experiments.values():
        for c in exp["claims"]:
            C.validate_claim(c, f"{exp_dir}/{exp['id']}.json")
    entries = X.load(exp_dir)
    problems = X.check_references(entries, exp_dir)
    if problems:
        raise ResultsError("explanations that name what does not exist:\n  " + "\n  ".join(problems))
    df = load_run(run_dir)
    drift_summary = None
    if drift:
        df, drift_summary = D.corrected(df)
    F.DRIFT_NOTE = " of drift-corrected times" if drift else ""
    machine_lines, machine = machine_section(run_dir)
    round_lines, flagged = rounds_section(run_dir)
    figs_dir = run_dir / "figures"
    figures, skipped, table_md, results = [], [], None, []
    tiny = machine.get("size") == "tiny"
    if resamples is None:  # a tiny run's numbers say nothing: few replicates keep make test fast
        resamples = TINY_RESAMPLES if tiny else S.RESAMPLES
    evaluator = C.Evaluator(df, resamples=resamples, per_experiment_resamples=min(100, resamples))
    # The same claims without the repetitions the machine witness flags as
    # measured on a slow machine: a sensitivity line beside each claim whose
    # experiments had any; the verdict stays the one from every repetition.
    quiet, left_out = quiet_rows(df)
    quiet_evaluator = (C.Evaluator(quiet, resamples=resamples, per_experiment_resamples=10)
                       if left_out else None)  # its per-experiment values are not shown
    F.RESAMPLES = min(resamples, TINY_RESAMPLES) if tiny else max(50, resamples // 4)
    for exp_id, exp in experiments.items():
        drawn = exp_id == "table1" or exp_id in F.FIGURES
        if not drawn and not exp["claims"]:
            continue  # not a figure (e.g. the CI benchmark set `compare`)
        src = exp.get("uses") or exp_id
        data = df[df["experiment"] == src]
        found = evaluator.experiment(exp, exp["claims"])
        if quiet_evaluator is not None and exp["claims"]:
            add_quiet(found, quiet_evaluator, exp, left_out)
        results += [(exp, r) for r in found]
        if data.empty or not drawn:
            if drawn:
                skipped.append(f"{exp_id} ({exp['figure']}): `{src}.json` is missing from {run_dir}")
            continue
        try:
            if exp_id == "table1":
                table_md, sentence = F.table1(data, exp)
                write_atomic(run_dir / "table1.md", f"# Table I, measured\n\n{table_md}")
            else:
                sentence = F.FIGURES[exp_id](data, figs_dir)
            figures.append((exp, sentence))
        except F.NoData as e:
            skipped.append(f"{exp_id} ({exp['figure']}): {e}")

    explained = X.by_claim(entries)
    for _, r in results:
        r["explanation"] = explained.get(r["id"])
    records = [claim_record(exp, r) for exp, r in results]
    why = X.section(X.evaluate_all(entries, df, resamples), {r["id"]: r["verdict"] for _, r in results})
    counts = collections.Counter(r["verdict"] for _, r in results)
    size = machine.get("size") or "?"
    out = [f"# {TITLE}", "",
           f"Drawn by `plots/report.py` from the JSON in `{run_dir}` alone (size `{size}`); "
           "the claims as data: `claims.json`.", ""]
    if size == "tiny":
        out += ["**This is a tiny run (a smoke test of the pipeline): its numbers say nothing "
                "about the paper, and no claim is measured on it.**", ""]
    out += ["## Machine", ""] + machine_lines + ["", "## Rounds", ""]
    out += round_lines or ["No results files."]
    out += ["", f"{flagged} round(s) measured under load." if flagged else "No round flagged under load.",
            "", "## How to read this", "",
            "- *t* is the median over repetitions of the wall seconds per step (`s_per_step`); every "
            "repetition times the same window of steps from the same snapshot of the developed flow.",
            "- Every value reads `value [low, high]`: the median-based estimate and its 95 % bootstrap "
            f"interval ({resamples} replicates; rounds drawn with replacement, then the repetitions inside "
            "each, with the same draw of rounds for every configuration, so that A and B of one round form "
            "one ratio). Figures draw the same intervals as error bars and bands.",
            ("- Drift correction: each repetition's times are divided by the machine's drift at that "
             "moment, estimated from the residuals of the repetitions that ran next to it in the same "
             "round (its own left out; the configurations are interleaved at random, so its neighbours "
             "are other configurations); see \"Drift correction\" below and `harness/drift.py`. The "
             "raw times stay in the results files."
             if drift else "- Times as measured: drift correction was turned off (`--no-drift-correction`)."),
            "- A configuration measured in several experiments with the same window length is pooled: every "
            "claim that uses it reads the mean of the experiments' medians, and the note lists the value "
            "each experiment gives alone.",
            "- Where an experiment measures several flow states (`flow_time`), the claim is the mean over "
            "the states; the note gives each state's value.",
            "- *Improvement* is the paper's (t_ref − t) / t_ref in percent: positive means faster "
            "than the reference.",
            "- *Memory* is `nl_bytes`, the bytes of the neighbour structures (max over the window); "
            "MB = 10⁶ bytes.",
            "- Verdicts: *reproduced* when the whole interval lies in the `reproduced` band, *partly* when "
            "it lies in the `partly` band but not wholly in the reproduced one, *not reproduced* when it lies "
            "wholly outside the partly band, *unresolved* otherwise (the note says what would resolve it), "
            "*not measured* when the run cannot support the claim (missing results, N < 5 000, too few "
            "points for a trend). Claims that count points (fractions) count a point only when the "
            "interval of its margin lies above 0 (above the claim's `tie_within` where it has one); a "
            "margin within ±tie_within is a tie, not a ranking, and does not count; a point whose "
            "interval straddles is undecided and widens the fraction's interval.",
            "", "## Summary", "",
            ", ".join(f"{counts.get(v, 0)} {v}" for v in VERDICTS) + f" (of {len(results)} claims); "
            f"{len(figures)} figures and tables drawn, {len(skipped)} skipped.", ""]
    out += ["Targets:", ""] + targets([r for _, r in results]) + [""]
    if drift_summary is not None:
        out += ["## Drift correction", "",
                "Scatter: standard deviation of the repetitions' log-time residuals (about their "
                "configuration's mean) before and after dividing out the drift estimated from their "
                "neighbours in run order; the window is the one that leaves the least. Level: the factor "
                "each experiment's times were then divided by so that the configurations it shares with "
                "other experiments agree (the median over them; ratios inside it do not change).", ""]
        out += drift_section(drift_summary) + [""]
    out += ["## Figures", ""]
    for exp, sentence in figures:
        out += [f"### {figure_of(exp)}: {exp['title']}", ""]
        if exp["id"] == "table1":
            out += [table_md.rstrip(), ""]
        else:
            out += [f"![{figure_of(exp)}](figures/{exp['id']}.png)", ""]
        out += [sentence, ""]
    if skipped:
        out += ["Skipped:", ""] + [f"- {s}" for s in skipped] + [""]
    out += ["## Claims", "", "| Figure | Claim | Paper | Measured [95 % interval] | Verdict | Note |",
            "|---|---|---|---|---|---|"]
    for exp, r in results:
        out.append(f"| {figure_of(exp)} | {r['text']} (`{r['id']}`) | {fmt(r['paper_value'], r['unit'])} "
                   f"| {fmt_ci(r['value'], r['ci_low'], r['ci_high'], r['unit'])} | {r['verdict']} "
                   f"| {claim_note(r)} |")
    out += [""] + why
    failed = errors(df)
    if failed:
        out += ["", "## Benchmarks that reported an error", ""] + \
            [f"- `{name}`: {msg}" for name, msg in failed]
    out += ["", "## Sources of the claims", ""] + \
        [f"- `{r['id']}`: \"{r['source']}\"" for _, r in results]
    return "\n".join(out) + "\n", records, counts, len(figures), len(skipped)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("results_dir", type=pathlib.Path, help="results/<run-id>")
    p.add_argument("--experiments-dir", type=pathlib.Path, default=HERE.parent / "experiments")
    p.add_argument("--resamples", type=int, default=None,
                   help=f"bootstrap replicates per claim (default {S.RESAMPLES}, {TINY_RESAMPLES} for a tiny "
                        "run; figures use a quarter, at least 50; a tiny run's figures {TINY_RESAMPLES})")
    p.add_argument("--publish", type=pathlib.Path, metavar="FILE",
                   help="also write the report to FILE (e.g. results/REPRODUCTION.md, the "
                        "reference copy), its figure links rewritten to point into the run folder")
    p.add_argument("--no-drift-correction", action="store_true",
                   help="use the times as measured, without dividing out the machine's drift inside "
                        "a round (harness/drift.py)")
    args = p.parse_args(argv)
    if args.resamples is not None and args.resamples < 50:
        p.error(f"--resamples {args.resamples}: a 95 % percentile interval needs at least 50 replicates")
    try:
        text, records, counts, drawn, skipped = build(args.results_dir, args.experiments_dir, args.resamples,
                                                       drift=not args.no_drift_correction)
    except ResultsError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    write_atomic(args.results_dir / "claims.json", json.dumps(records, indent=1, ensure_ascii=False) + "\n")
    write_atomic(args.results_dir / "REPRODUCTION.md", text)
    if args.publish:
        prefix = os.path.relpath(args.results_dir.resolve(), args.publish.resolve().parent)
        write_atomic(args.publish, text.replace("](figures/", f"]({prefix}/figures/")
                     .replace("](table1.md)", f"]({prefix}/table1.md)"))
        print(f"wrote {args.publish} (links into {prefix}/)")
    print(f"wrote {args.results_dir / 'REPRODUCTION.md'} and claims.json: "
          + ", ".join(f"{counts.get(v, 0)} {v}" for v in VERDICTS)
          + f"; {drawn} figures/tables drawn, {skipped} skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
