#!/usr/bin/python3
"""Draw every figure, Table I and REPRODUCTION.md from a results folder alone.

    /usr/bin/python3 -m plots.report results/<run-id> [--experiments-dir experiments]

(from the repository root, or with PYTHONPATH set to it: harness/__init__.py)

Writes RESULTS_DIR/figures/<id>.png|svg, RESULTS_DIR/table1.md and
RESULTS_DIR/REPRODUCTION.md (machine, one data-derived sentence per figure,
claims table: claim, paper value, measured value, verdict, note).
A missing experiment file skips its figures with a line in the report.
"""
import argparse
import collections
import json
import os
import pathlib
import sys

from harness.fsio import write_atomic
from harness.results import ResultsError, errors, load_experiments, load_run
from plots import claims as C
from plots import figures as F

HERE = pathlib.Path(__file__).resolve().parent

TITLE = ("Reproduction of Domínguez, Crespo, Gómez-Gesteira and Marongiu (2011), "
         "\"Neighbour lists in smoothed particle hydrodynamics\"")
UNITS = {"%": " %", "pp": " pp", "x": "x", "MB": " MB", "fraction": "", "": ""}
VERDICTS = ("reproduced", "partly", "not reproduced", "not measured")


def fmt(value, unit):
    if value is None:
        return "–"
    if isinstance(value, str):
        return value + UNITS.get(unit, "")
    digits = ".2f" if unit in ("fraction", "x") else ".1f" if unit in ("%", "pp") else ".3g"
    return f"{value:{digits}}{UNITS.get(unit, ' ' + unit)}"


def fmt_interval(bounds, unit):
    lo, hi = bounds
    if lo is not None and hi is not None:
        return f"= {fmt(lo, unit)}" if lo == hi else f"{fmt(lo, unit)} to {fmt(hi, unit)}"
    return f"≥ {fmt(lo, unit)}" if lo is not None else f"≤ {fmt(hi, unit)}"


def machine_section(run_dir, df):
    path = run_dir / "machine.json"
    if not path.exists():
        return ["No machine.json in this run folder."], {}
    try:
        m = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ResultsError(f"{path}: not valid JSON ({e})") from None
    caches = ", ".join(f"{k} {v}" for k, v in (m.get("caches") or {}).items())
    mem = f"{m['memory_bytes'] / 2**30:.1f} GiB" if m.get("memory_bytes") else "?"
    dirty = " (uncommitted changes)" if m.get("git_dirty") else ""
    rows = [("CPU", f"{m.get('cpu_model', '?')}, {m.get('cores', '?')} cores, "
                    f"{m.get('logical_cpus', '?')} logical CPUs"),
            ("Caches", caches or "?"), ("Memory", mem), ("Compiler", m.get("compiler", "?")),
            ("Git revision", f"{m.get('git_revision', '?')}{dirty}"),
            ("Date (UTC)", m.get("date", "?")), ("Size", m.get("size", "?")),
            ("OS", m.get("os", "?"))]
    if m.get("max_n"):
        rows.append(("N cap", f"sweep points above N = {m['max_n']:,} left out (--max-n)"))
    for part in m.get("earlier") or []:  # a run made in parts: each earlier invocation
        cap = f", N ≤ {part['max_n']:,}" if part.get("max_n") else ""
        rows.append(("Earlier part", f"{part.get('date', '?')}, revision "
                                     f"{(part.get('git_revision') or '?')[:12]}{cap}"))
    return ["| | |", "|---|---|"] + [f"| {k} | {v} |" for k, v in rows], m


def build(run_dir, exp_dir):
    """Draw everything; return (markdown of REPRODUCTION.md, verdict counts)."""
    experiments = load_experiments(exp_dir)
    df = load_run(run_dir)
    machine_lines, machine = machine_section(run_dir, df)
    figs_dir = run_dir / "figures"
    figures, skipped, table_md, results = [], [], None, []
    for exp_id, exp in experiments.items():
        drawn = exp_id == "table1" or exp_id in F.FIGURES
        if not drawn and not exp["claims"]:
            continue  # not a figure (e.g. the CI benchmark set `compare`)
        src = exp.get("uses") or exp_id
        data = df[df["experiment"] == src]
        for c in exp["claims"]:
            results.append((exp, C.evaluate(c, data)))
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

    counts = collections.Counter(r["verdict"] for _, r in results)
    size = machine.get("size") or "?"
    out = [f"# {TITLE}", "",
           f"Drawn by `plots/report.py` from the JSON in `{run_dir}` alone (size `{size}`).", ""]
    if size == "tiny":
        out += ["**This is a tiny run (a smoke test of the pipeline): its numbers say nothing "
                "about the paper, and no claim is measured on it.**", ""]
    out += ["## Machine", ""] + machine_lines + [
        "", "## How to read this", "",
        "- *t* is the median over repetitions of the wall seconds per step (`s_per_step`); every "
        "repetition times the same window of steps from the same snapshot of the developed flow.",
        "- *Improvement* is the paper's (t_ref − t) / t_ref in percent: positive means faster "
        "than the reference.",
        "- *Memory* is `nl_bytes`, the bytes of the neighbour structures (max over the window); "
        "MB = 10⁶ bytes.",
        "- A claim is *reproduced* when the measured value lies in its `reproduced` interval, "
        "*partly* in its `partly` interval, otherwise *not reproduced*; *not measured* when the run "
        "cannot support it (missing results, N < 5 000, too few points for a trend).",
        "", "## Summary", "",
        ", ".join(f"{counts.get(v, 0)} {v}" for v in VERDICTS) + f" (of {len(results)} claims); "
        f"{len(figures)} figures and tables drawn, {len(skipped)} skipped.", ""]
    out += ["## Figures", ""]
    for exp, sentence in figures:
        out += [f"### {exp['figure']}: {exp['title']}", ""]
        if exp["id"] == "table1":
            out += [table_md.rstrip(), ""]
        else:
            out += [f"![{exp['figure']}](figures/{exp['id']}.png)", ""]
        out += [sentence, ""]
    if skipped:
        out += ["Skipped:", ""] + [f"- {s}" for s in skipped] + [""]
    out += ["## Claims", "", "| Figure | Claim | Paper | Measured | Verdict | Note |",
            "|---|---|---|---|---|---|"]
    for exp, r in results:
        tol = r["tolerance"]
        rule = (f"reproduced if {fmt_interval(tol['reproduced'], r['unit'])}, "
                f"partly if {fmt_interval(tol['partly'], r['unit'])}")
        note = f"{r['note']}. {rule}" if r["note"] else rule
        out.append(f"| {exp['figure']} | {r['text']} (`{r['id']}`) | {fmt(r['paper_value'], r['unit'])} "
                   f"| {fmt(r['measured'], r['unit'])} | {r['verdict']} | {note} |")
    failed = errors(df)
    if failed:
        out += ["", "## Benchmarks that reported an error", ""] + \
            [f"- `{name}`: {msg}" for name, msg in failed]
    out += ["", "## Sources of the claims", ""] + \
        [f"- `{r['id']}`: \"{r['source']}\"" for _, r in results]
    return "\n".join(out) + "\n", counts, len(figures), len(skipped)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("results_dir", type=pathlib.Path, help="results/<run-id>")
    p.add_argument("--experiments-dir", type=pathlib.Path, default=HERE.parent / "experiments")
    p.add_argument("--publish", type=pathlib.Path, metavar="FILE",
                   help="also write the report to FILE (e.g. results/REPRODUCTION.md, the "
                        "reference copy), its figure links rewritten to point into the run folder")
    args = p.parse_args(argv)
    try:
        text, counts, drawn, skipped = build(args.results_dir, args.experiments_dir)
    except ResultsError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    write_atomic(args.results_dir / "REPRODUCTION.md", text)
    if args.publish:
        prefix = os.path.relpath(args.results_dir.resolve(), args.publish.resolve().parent)
        write_atomic(args.publish, text.replace("](figures/", f"]({prefix}/figures/")
                     .replace("](table1.md)", f"]({prefix}/table1.md)"))
        print(f"wrote {args.publish} (links into {prefix}/)")
    print(f"wrote {args.results_dir / 'REPRODUCTION.md'}: "
          + ", ".join(f"{counts.get(v, 0)} {v}" for v in VERDICTS)
          + f"; {drawn} figures/tables drawn, {skipped} skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
