#!/usr/bin/python3
"""Compare two independent runs claim by claim: do their verdicts survive a rerun?

    /usr/bin/python3 -m plots.replicate results/<run A> results/<run B> [--out DIR]
    make replicate A=results/<run A> B=results/<run B>

Reads each run's claims.json (written by plots/report.py; drawn here first
when a run folder lacks it) and writes replication.md and replication.json
into B's folder, or into --out: for every claim both values with their 95 %
intervals, whether the intervals overlap, whether the verdicts agree, and
the share of the claims resolved in both runs (neither `unresolved` nor
`not measured`) that got the same verdict in both (target: at least 90 %,
docs/MEASUREMENT.md, "Targets").
"""
import argparse
import json
import math
import pathlib
import sys

from harness.fsio import write_atomic
from harness.results import ResultsError, format_n

HERE = pathlib.Path(__file__).resolve().parent
UNRESOLVED = ("unresolved", "not measured")
TARGET_AGREEMENT = 0.9


def load_claims(run_dir, exp_dir, resamples):
    """The claims.json of `run_dir`, drawing the report first if it is missing."""
    path = run_dir / "claims.json"
    if not path.exists():
        if not run_dir.is_dir():
            raise ResultsError(f"{run_dir}: no such results folder")
        from plots import report
        rc = report.main([str(run_dir), "--experiments-dir", str(exp_dir), "--resamples", str(resamples)])
        if rc != 0 or not path.exists():
            raise ResultsError(f"{run_dir}: could not draw its report (plots/report.py exited {rc})")
    try:
        claims = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as e:
        raise ResultsError(f"{path}: cannot read claims ({e}); redraw it with "
                           f"`make figures RESULTS={run_dir}`") from None
    if not isinstance(claims, list) or not all(isinstance(c, dict) and "id" in c for c in claims):
        raise ResultsError(f"{path}: not a list of claim objects; redraw it with `make figures RESULTS={run_dir}`")
    return claims


def _finite(*values):
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def overlap(a, b):
    """True/False when both intervals exist, None otherwise."""
    if not (_finite(a.get("ci_low"), a.get("ci_high")) and _finite(b.get("ci_low"), b.get("ci_high"))):
        return None
    return a["ci_low"] <= b["ci_high"] and b["ci_low"] <= a["ci_high"]


def compare(claims_a, claims_b):
    """(rows, summary): one row per claim id present in either run."""
    by_a = {c["id"]: c for c in claims_a}
    by_b = {c["id"]: c for c in claims_b}
    rows = []
    for cid in list(by_a) + [i for i in by_b if i not in by_a]:
        a, b = by_a.get(cid, {}), by_b.get(cid, {})
        va, vb = a.get("verdict", "not measured"), b.get("verdict", "not measured")
        resolved = va not in UNRESOLVED and vb not in UNRESOLVED
        rows.append({"id": cid, "figure": a.get("figure") or b.get("figure"),
                     "unit": a.get("unit") or b.get("unit"),
                     "a": {k: a.get(k) for k in ("value", "ci_low", "ci_high", "verdict", "at_n")},
                     "b": {k: b.get(k) for k in ("value", "ci_low", "ci_high", "verdict", "at_n")},
                     "same_n": a.get("at_n") == b.get("at_n") or not (a.get("at_n") and b.get("at_n")),
                     "overlap": overlap(a, b), "same_verdict": va == vb,
                     "resolved_in_both": resolved})
    both = [r for r in rows if r["resolved_in_both"]]
    agree = [r for r in both if r["same_verdict"]]
    with_ci = [r for r in rows if r["overlap"] is not None]
    summary = {"claims": len(rows), "same_verdict": sum(r["same_verdict"] for r in rows),
               "resolved_in_both": len(both), "same_verdict_when_resolved_in_both": len(agree),
               "agreement_when_resolved": (len(agree) / len(both)) if both else None,
               "target_agreement": TARGET_AGREEMENT,
               "intervals_compared": len(with_ci), "intervals_overlap": sum(r["overlap"] for r in with_ci),
               "different_n": sum(not r["same_n"] for r in rows)}
    return rows, summary


def _v(side, unit):
    if not _finite(side.get("value")):
        return "–"
    digits = ".2f" if unit in ("fraction", "x") else ".1f" if unit in ("%", "pp") else ".3g"
    text = f"{side['value']:{digits}}"
    if _finite(side.get("ci_low"), side.get("ci_high")):
        text += f" [{side['ci_low']:{digits}}, {side['ci_high']:{digits}}]"
    return text + ("" if unit in ("fraction", "") else f" {unit}")


def _side(r, key):
    """A run's value, with the N it was read at where the two runs read the
    claim at different N (a run that left out the largest N reads it lower)."""
    side = r[key]
    text = _v(side, r["unit"])
    if not r.get("same_n", True) and side.get("at_n"):
        text += f" (N = {format_n(side['at_n'])})"
    return text


def markdown(rows, summary, name_a, name_b):
    s = summary
    share = s["agreement_when_resolved"]
    lines = [f"# Replication: `{name_a}` (A) against `{name_b}` (B)", "",
             "Drawn by `plots/replicate.py` from the two runs' `claims.json`. Values read "
             "`value [low, high]` (95 % bootstrap intervals).", "",
             "## Summary", "",
             f"- Claims: {s['claims']}; same verdict in both runs: {s['same_verdict']}.",
             f"- Resolved in both runs (neither `unresolved` nor `not measured`): {s['resolved_in_both']}; "
             f"of these, same verdict: {s['same_verdict_when_resolved_in_both']}"
             + (f" ({100 * share:.0f} %; target ≥ {100 * TARGET_AGREEMENT:.0f} %)." if share is not None else "."),
             f"- Intervals that overlap: {s['intervals_overlap']} of the {s['intervals_compared']} claims "
             "with an interval in both runs.",
             f"- Read at different N in the two runs (the N beside the value; not a replication of "
             f"one measurement): {s['different_n']}.", "",
             "## Claims", "",
             "| Figure | Claim | A | verdict A | B | verdict B | overlap | same verdict |",
             "|---|---|---|---|---|---|---|---|"]
    yes = {True: "yes", False: "**no**", None: "–"}
    for r in rows:
        lines.append(f"| {r['figure'] or '?'} | `{r['id']}` | {_side(r, 'a')} | {r['a']['verdict'] or '–'} "
                     f"| {_side(r, 'b')} | {r['b']['verdict'] or '–'} | {yes[r['overlap']]} "
                     f"| {yes[r['same_verdict']]} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_a", type=pathlib.Path, help="results/<run A>")
    p.add_argument("run_b", type=pathlib.Path, help="results/<run B>")
    p.add_argument("--out", type=pathlib.Path, help="folder for replication.md/.json (default: run B's)")
    p.add_argument("--experiments-dir", type=pathlib.Path, default=HERE.parent / "experiments")
    p.add_argument("--resamples", type=int, default=1000,
                   help="bootstrap replicates when a run's report must be drawn first")
    args = p.parse_args(argv)
    try:
        if args.run_a.resolve() == args.run_b.resolve():
            raise ResultsError(f"A and B are the same folder ({args.run_a}): a replication needs two runs")
        claims_a = load_claims(args.run_a, args.experiments_dir, args.resamples)
        claims_b = load_claims(args.run_b, args.experiments_dir, args.resamples)
    except ResultsError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    rows, summary = compare(claims_a, claims_b)
    out = args.out or args.run_b
    doc = {"a": str(args.run_a), "b": str(args.run_b), "summary": summary, "claims": rows}
    write_atomic(out / "replication.json", json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    write_atomic(out / "replication.md", markdown(rows, summary, args.run_a, args.run_b))
    share = summary["agreement_when_resolved"]
    print(f"wrote {out / 'replication.md'} and replication.json: {summary['same_verdict']} of "
          f"{summary['claims']} verdicts agree; resolved in both: {summary['resolved_in_both']}, of which "
          f"{summary['same_verdict_when_resolved_in_both']} agree"
          + (f" ({100 * share:.0f} %)" if share is not None else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
