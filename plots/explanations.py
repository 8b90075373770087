"""Why our results differ from the paper: hypotheses, each tested by an experiment.

An experiment file may carry `explanations` (docs/CONTRACTS.md §1): entries

    {"id": "...", "explains": [claim ids], "hypothesis": "one sentence",
     "measure": SPEC, "unit": "x", "supported_if": [lo, hi], "band_reason": "..."}

tested by that file's own experiment. A file under experiments/pending/
holds an experiment whose sweep axes this build does not have yet
(`pending_axes`); its entries are listed and not evaluated.

SPEC is declarative (a number is never typed in): a tree of

    {"op": "ratio" | "difference" | "improvement", "of": [SPEC, SPEC]}
    {"select": {axis: value, ...}}        a leaf: one configuration's metric

where `metric` (a results column, e.g. ll_misses_per_particle_step) and
`where` (axis values) given at any level hold for every leaf below it, a
nearer one overriding. `"particles": "max"` / `"particles": "min"` pick the largest or
smallest N among the configurations matching the other values. ratio is
a / b, difference a - b, improvement 100 (a - b) / a (the paper's, a the
reference). A leaf must match exactly one configuration.

The measured value carries the 95 % bootstrap interval of
harness.stats.RoundBootstrap (rounds resampled, as for the claims), and the
verdict follows the claims' rule (plots/claims.py: verdict) with a single
band, `supported_if`: `supported` when the whole interval lies in it,
`refuted` when wholly outside, `unresolved` otherwise; `not measured` when
the run folder lacks the experiment's results. Counts of the `counters`
kind repeat exactly: their interval has zero width.
"""
import json
import math
import pathlib

from harness import stats as S
from harness.results import ResultsError, load_experiments, pick
from plots import claims as C

OPS = {"ratio": lambda a, b: a / b,
       "difference": lambda a, b: a - b,
       "improvement": lambda a, b: 100.0 * (a - b) / a}
VERDICTS = ("supported", "refuted", "unresolved", "not measured", "pending")
ENTRY_KEYS = {"id", "explains", "hypothesis", "measure", "unit", "supported_if", "band_reason", "note"}
PENDING_DIR = "pending"


class SpecError(ResultsError):
    """An explanation entry that cannot be evaluated as written."""


# ------------------------------------------------------------------ loading
def load(exp_dir):
    """[entry] of every experiment file of `exp_dir` and of its pending/
    folder, each entry with `experiment` (the file's id) and `pending_axes`
    (empty for an experiment this build can run)."""
    exp_dir = pathlib.Path(exp_dir)
    out = []
    for path in sorted(exp_dir.glob("*.json")) + sorted((exp_dir / PENDING_DIR).glob("*.json")):
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as e:
            raise ResultsError(f"{path}: not valid JSON ({e})") from None
        for k, e in enumerate(doc.get("explanations") or []):
            where = f"{path}: explanations[{k}]"
            validate(e, where)
            out.append({**e, "experiment": doc.get("id", path.stem), "source": str(path.relative_to(exp_dir)),
                        "pending_axes": list(doc.get("pending_axes") or [])})
    ids = [e["id"] for e in out]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise ResultsError(f"{exp_dir}: explanation ids used twice: {', '.join(dup)}")
    return out


def validate(e, where):
    """The shape of one entry, with the problem and the fix named."""
    if not isinstance(e, dict):
        raise SpecError(f"{where}: an entry must be an object")
    missing = sorted({"id", "explains", "hypothesis", "measure", "unit", "supported_if", "band_reason"} - set(e))
    if missing:
        raise SpecError(f"{where}: missing {', '.join(missing)}")
    unknown = sorted(set(e) - ENTRY_KEYS)
    if unknown:
        raise SpecError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(ENTRY_KEYS))}")
    if not (isinstance(e["explains"], list) and e["explains"] and all(isinstance(c, str) for c in e["explains"])):
        raise SpecError(f"{where} ({e['id']}): explains must list claim ids")
    band = e["supported_if"]
    if not (isinstance(band, list) and len(band) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in band)
            and band[0] <= band[1]):
        raise SpecError(f"{where} ({e['id']}): supported_if is {band}; it must be two finite numbers "
                        "[lo, hi], lo <= hi (bound an open side by the quantity's physical range)")
    _check_spec(e["measure"], f"{where} ({e['id']}): measure", {})


def _check_spec(spec, where, inherited):
    if not isinstance(spec, dict):
        raise SpecError(f"{where}: a spec is an object ({{'op': ..., 'of': [...]}} or {{'select': {{...}}}})")
    scope = {**inherited, **({"metric": spec["metric"]} if "metric" in spec else {})}
    if "op" in spec:
        if spec["op"] not in OPS:
            raise SpecError(f"{where}: unknown op {spec['op']!r}; allowed: {', '.join(OPS)}")
        if not (isinstance(spec.get("of"), list) and len(spec["of"]) == 2):
            raise SpecError(f"{where}: op {spec['op']} needs 'of': [two specs]")
        for k, sub in enumerate(spec["of"]):
            _check_spec(sub, f"{where}.of[{k}]", scope)
    elif "select" in spec:
        if not isinstance(spec["select"], dict):
            raise SpecError(f"{where}: select must be an object of axis values")
        if "metric" not in scope:
            raise SpecError(f"{where}: no metric for this leaf (give 'metric' on it or above it)")
    else:
        raise SpecError(f"{where}: neither 'op' nor 'select'")


# --------------------------------------------------------------- evaluation
def _leaf(med, select, metric):
    want = dict(select)
    extreme = {k: v for k, v in want.items() if v in ("max", "min")}
    for k in extreme:
        del want[k]
    rows = pick(med, **want)
    if any(k not in med for k in want):
        raise C.NotMeasured(f"the results have no column {[k for k in want if k not in med]}")
    for k, how in extreme.items():
        if rows.empty:
            break
        rows = rows[rows[k] == (rows[k].max() if how == "max" else rows[k].min())]
    if len(rows) != 1:
        raise C.NotMeasured(f"{len(rows)} configurations match {select} (one is needed)")
    if metric not in rows:
        raise C.NotMeasured(f"the results have no metric {metric}")
    return float(rows[metric].iloc[0])


def evaluate_spec(spec, med, inherited=None):
    """The value of `spec` on one table of per-configuration medians."""
    inherited = inherited or {}
    scope = {"metric": spec.get("metric", inherited.get("metric")),
             "where": {**inherited.get("where", {}), **spec.get("where", {})}}
    if "op" in spec:
        a, b = (evaluate_spec(s, med, scope) for s in spec["of"])
        return OPS[spec["op"]](a, b)
    return _leaf(med, {**scope["where"], **spec["select"]}, scope["metric"])


def measure(entry, rows, resamples=S.RESAMPLES, seed=0):
    """{value, ci_low, ci_high, verdict, note} of one entry on the rows of its experiment."""
    band = {"reproduced": entry["supported_if"], "partly": entry["supported_if"]}
    out = {"value": None, "ci_low": None, "ci_high": None, "verdict": "not measured", "note": ""}
    if entry.get("pending_axes"):
        out.update(verdict="pending", note=(f"experiment {entry['experiment']} sweeps "
                                            f"{', '.join(entry['pending_axes'])}, which this build lacks"))
        return out
    if rows is None or not len(rows):
        out["note"] = (f"no results of {entry['experiment']} in this run folder (python3 -m experiments.run "
                       f"--only {entry['experiment']})")
        return out
    try:
        boot = S.RoundBootstrap(rows, resamples=resamples, seed=seed)
        value = evaluate_spec(entry["measure"], boot.point)
        reps = []
        for tab in boot.tables():
            try:
                reps.append(evaluate_spec(entry["measure"], tab))
            except (C.NotMeasured, ZeroDivisionError):
                pass
        lo, hi = S.percentile_interval(reps, boot.level)
    except C.NotMeasured as e:
        out["note"] = str(e)
        return out
    except ZeroDivisionError:
        out["note"] = "a ratio or improvement divides by zero"
        return out
    verdict, resolve = C.verdict(value, lo, hi, band)
    out.update(value=value, ci_low=lo, ci_high=hi, note=resolve,
               verdict={"reproduced": "supported", "not reproduced": "refuted"}.get(verdict, verdict))
    return out


def evaluate_all(entries, df, resamples=S.RESAMPLES):
    """[entry + its measurement] for every entry, each on its experiment's rows of `df`."""
    out = []
    for e in entries:
        rows = df[df["experiment"] == e["experiment"]] if len(df) and "experiment" in df else None
        if rows is not None and "error_occurred" in rows:
            rows = rows[~rows["error_occurred"].astype(bool)]
        out.append({**e, **measure(e, rows, resamples)})
    return out


def by_claim(entries):
    """{claim id: [entry ids that explain it]}."""
    out = {}
    for e in entries:
        for c in e["explains"]:
            out.setdefault(c, []).append(e["id"])
    return out


def check_references(entries, exp_dir):
    """Problems (list of strings): entries naming a claim no experiment
    states, or an experiment that does not exist."""
    exps = load_experiments(exp_dir)
    claims = {c["id"] for e in exps.values() for c in e.get("claims", [])}
    pending = {p.stem for p in (pathlib.Path(exp_dir) / PENDING_DIR).glob("*.json")}
    problems = []
    for e in entries:
        if e["experiment"] not in exps and e["experiment"] not in pending:
            problems.append(f"{e['id']}: experiment {e['experiment']} does not exist")
        for c in e["explains"]:
            if c not in claims:
                problems.append(f"{e['id']}: explains unknown claim {c}")
    return problems


# ------------------------------------------------------------------- report
def _fmt(v, unit):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return f"{v:.3g}" + ("x" if unit == "x" else f" {unit}" if unit else "")


def section(results, claim_verdicts):
    """The lines of REPRODUCTION.md's "Why the results differ"."""
    differing = {c for c, v in claim_verdicts.items() if v in ("not reproduced", "partly")}
    covered = {c for r in results for c in r["explains"]}
    lines = ["## Why the results differ", "",
             "Hypotheses for the claims that are not reproduced or only partly, each tested by an "
             "experiment (its file's `explanations`; docs/CONTRACTS.md). The measured value is computed "
             "from that experiment's results by the entry's declarative spec, with its 95 % bootstrap "
             "interval; the hypothesis is *supported* when the whole interval lies in its `supported_if` "
             "band, *refuted* when it lies wholly outside, *unresolved* otherwise; *pending* when the "
             "experiment needs sweep axes this build lacks, *not measured* when this run folder lacks "
             "its results. Counts (`counters` experiments) repeat exactly: their interval has no width.", "",
             "| Hypothesis | Explains (verdict here) | Experiment | Measured [95 % interval] | Supported if | "
             "Verdict | Note |", "|---|---|---|---|---|---|---|"]
    for r in results:
        claims = ", ".join(f"`{c}` ({claim_verdicts.get(c, '?')})" for c in r["explains"])
        measured = "–" if r["value"] is None else \
            f"{_fmt(r['value'], r['unit'])} [{r['ci_low']:.3g}, {r['ci_high']:.3g}]"
        lo, hi = r["supported_if"]
        note = "; ".join(x for x in (r.get("measure", {}).get("text", ""), r["note"], r["band_reason"]) if x)
        lines.append(f"| {r['hypothesis']} (`{r['id']}`) | {claims} | `{r['experiment']}` | {measured} "
                     f"| {_fmt(lo, r['unit'])} to {_fmt(hi, r['unit'])} | {r['verdict']} | "
                     f"{note.replace('|', '/')} |")
    missing = sorted(differing - covered)
    lines += ["", (f"Claims not reproduced or partly without an entry: {', '.join(f'`{c}`' for c in missing)}."
                   if missing else "Every claim not reproduced or partly here has at least one entry.")]
    return lines
