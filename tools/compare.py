#!/usr/bin/python3
"""Compare the performance of the working tree against another git ref.

    /usr/bin/python3 tools/compare.py [--base REF] [--threshold 2] [--reps 5] [--out DIR]

(`make compare BASE=<ref> THRESHOLD=<pct>`). The base is built in its own git
worktree and build folder under .compare/ (the user's working tree is never
touched); the new side is the working tree as it stands, uncommitted changes
included, built into .compare/build-current. Both are built with
-march=x86-64-v3 because valgrind 3.19 cannot execute AVX-512 instructions.

Two figures per benchmark of experiments/compare.json (the new side's file is
given to both binaries; a base built before the sweep axes became the run-config
keys rejects it, and gets a copy in the old names instead: old_names_experiment;
benchmark names are matched in today's vocabulary, harness.results.canonical_run_name):

* wall time per step (`s_per_step`), base and new runs alternated A B A B ...
  in this one invocation, compared with a two-sided Mann-Whitney U test and a
  95 % bootstrap interval of the change of medians; a change whose p >= 0.05
  or whose interval holds 0 is printed "n.s." (not significant). Informative
  only, never gated: each sample is one short window, and two runs of the
  same binary on these shared 2-core machines differ by tens of percent.
* instructions per step (callgrind `Ir` inside `sphnl::bench::timed_window`)
  of one window started from the cached snapshot: deterministic, so gated.

A commit between the base and HEAD that knowingly trades speed carries a
line `perf-regression-accepted: <reason>` in its message; a regression is
then reported with that reason and commit, and does not fail.

Exit status: 0 no gated regression (or every one accepted), 1 an Ir/step regression above the
threshold (benchmark, change and the valgrind commands to reproduce it are
printed), 2 the comparison could not be made (unknown ref, base does not
build, binary predates the benchmark interface, valgrind missing).
Writes OUT/compare.json and OUT/compare.md (a table for a CI job summary).
"""
import argparse
import concurrent.futures
import dataclasses
import hashlib
import json
import os
import pathlib
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # run as a script (tools/compare.py): the harness package is at the root
from harness import valgrind as V  # noqa: E402
from harness.results import OLD_AXES, canonical_run_name  # noqa: E402
from harness.valgrind import CMAKE_OPTIONS, TIMED_FUNCTION, gb_filter  # noqa: E402,F401

EXPERIMENT = "experiments/compare.json"
BENCH_TARGET = "sphnl_bench"
BENCH_RELPATH = pathlib.Path("benchmarks") / BENCH_TARGET
TIME_UNITS = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}
LOG_TAIL_LINES = 40


class CompareError(Exception):
    """The comparison cannot be made; the message says why and what to do."""

    def __init__(self, message, code=2):
        super().__init__(message)
        self.code = code


# ================================================================ parsing
def parse_gb_json(doc, source="benchmark JSON"):
    """{benchmark name: {'s_per_step', 'window_steps', 'iterations', 'real_time_s',
    'run_name'}} of the iteration entries of one Google Benchmark 1.7.1 JSON
    document, keyed by the name in today's vocabulary (an older bench's
    'step/n:6000/order:sort_x/...' as 'step/particles:6000/cell_order:sort_x/...');
    'run_name' is the name as the bench wrote it (what its filter matches).

    Aggregates (`_mean`, `_median`, ...) are skipped; an entry that reports an
    error raises, since its figures would be meaningless."""
    if not isinstance(doc, dict) or not isinstance(doc.get("benchmarks"), list):
        raise CompareError(f"{source}: not Google Benchmark JSON (no 'benchmarks' list)")
    out = {}
    for entry in doc["benchmarks"]:
        if entry.get("run_type", "iteration") != "iteration":
            continue
        name = entry.get("run_name") or entry["name"]
        if entry.get("error_occurred"):
            raise CompareError(f"{source}: benchmark {name} failed: "
                               f"{entry.get('error_message', 'no message')}")
        unit = TIME_UNITS.get(entry.get("time_unit", "ns"))
        if unit is None:
            raise CompareError(f"{source}: {name} has unknown time_unit {entry.get('time_unit')!r}")
        steps = entry.get("window_steps")
        if "s_per_step" not in entry or not steps:
            raise CompareError(f"{source}: {name} lacks the s_per_step / window_steps counters "
                               "of docs/CONTRACTS.md §2")
        out[canonical_run_name(name)] = {"s_per_step": float(entry["s_per_step"]),
                                         "window_steps": int(round(float(steps))),
                                         "iterations": int(entry.get("iterations", 1)),
                                         "real_time_s": float(entry.get("real_time", 0.0)) * unit,
                                         "run_name": name}
    if not out:
        raise CompareError(f"{source}: no benchmark ran (is the filter or the experiment empty?)")
    return out


def parse_callgrind_ir(text, source="callgrind output"):
    """Total instructions executed (event `Ir`) from a callgrind output file
    (harness/valgrind.py reads it; a file without an `events:` line counts Ir only)."""
    if not any(line.startswith("events:") for line in text.splitlines()):
        text = "events: Ir\n" + text
    try:
        return V.parse_callgrind(text, source).total("Ir")
    except V.ValgrindError as e:
        raise CompareError(str(e)) from None


# ============================================================= statistics
def mann_whitney_p(a, b):
    """Two-sided Mann-Whitney U p-value (as Google Benchmark's compare.py
    computes it), or None when it cannot be computed (too few samples, scipy
    missing)."""
    if len(a) < 2 or len(b) < 2:
        return None
    try:
        from scipy.stats import mannwhitneyu
    except ImportError:
        return None
    if len(set(a) | set(b)) == 1:  # all samples equal: no evidence of a difference
        return 1.0
    return float(mannwhitneyu(a, b, alternative="two-sided").pvalue)


def bootstrap_change_interval(a, b, level=0.95, resamples=2000, seed=12345):
    """Percentile bootstrap interval of (median(b) - median(a)) / median(a),
    resampling each side with replacement; None with fewer than 2 samples a
    side. Seeded: the same samples give the same interval."""
    if len(a) < 2 or len(b) < 2:
        return None
    import random
    rng = random.Random(seed)
    changes = []
    for _ in range(resamples):
        ma = statistics.median(rng.choices(a, k=len(a)))
        mb = statistics.median(rng.choices(b, k=len(b)))
        if ma:
            changes.append((mb - ma) / ma)
    if not changes:
        return None
    changes.sort()
    lo = changes[int((1 - level) / 2 * (len(changes) - 1))]
    hi = changes[int((1 + level) / 2 * (len(changes) - 1))]
    return [lo, hi]


def time_significant(p_value, interval, alpha=0.05):
    """A timing change counts only when the U test rejects equality and the
    bootstrap interval excludes zero."""
    return p_value is not None and p_value < alpha and interval is not None and \
        (interval[0] > 0 or interval[1] < 0)


def relative_change(base, new):
    """(new - base) / base, or None when base is zero."""
    return None if not base else (new - base) / base


def time_figures(base_samples, new_samples):
    """Medians of s_per_step, their relative change and the U-test p-value."""
    base_med, new_med = statistics.median(base_samples), statistics.median(new_samples)
    p = mann_whitney_p(base_samples, new_samples)
    interval = bootstrap_change_interval(list(base_samples), list(new_samples))
    return {"base_median_s": base_med, "new_median_s": new_med,
            "change": relative_change(base_med, new_med),
            "p_value": p, "change_interval_95": interval,
            "significant": time_significant(p, interval),
            "base_samples": list(base_samples), "new_samples": list(new_samples)}


def ir_figures(base_ir, base_steps, new_ir, new_steps, threshold_pct):
    """Instructions per step of both sides and the gate decision."""
    base_ps, new_ps = base_ir / base_steps, new_ir / new_steps
    change = relative_change(base_ps, new_ps)
    return {"base_total": base_ir, "new_total": new_ir,
            "base_steps": base_steps, "new_steps": new_steps,
            "base_per_step": base_ps, "new_per_step": new_ps, "change": change,
            "regression": change is not None and change * 100.0 > threshold_pct}


def compare(times, irs, threshold_pct, reproduce=None):
    """The whole comparison from measured figures; pure, so tests can feed it.

    times: {name: (base s_per_step samples, new samples)}
    irs:   {name: ((base Ir, base counted steps), (new Ir, new counted steps))}
           (a name may be absent: instruction counts not measured)
    reproduce: {name: [base command, new command]}
    Returns the report dict written as compare.json."""
    reproduce = reproduce or {}
    rows = []
    for name in sorted(set(times) | set(irs)):
        row = {"name": name, "time": None, "ir": None, "reproduce": reproduce.get(name, [])}
        if name in times:
            row["time"] = time_figures(*times[name])
        if name in irs:
            (b_ir, b_steps), (n_ir, n_steps) = irs[name]
            row["ir"] = ir_figures(b_ir, b_steps, n_ir, n_steps, threshold_pct)
        rows.append(row)
    regressions = [r["name"] for r in rows if r["ir"] and r["ir"]["regression"]]
    return {"threshold_pct": threshold_pct, "benchmarks": rows,
            "regressions": regressions, "verdict": "regression" if regressions else "pass"}


ACCEPT_RE = re.compile(r"^\s*perf-regression-accepted:\s*(\S.*?)\s*$", re.M)


def acceptances(commits):
    """[{'sha', 'reason'}] of the `perf-regression-accepted: <reason>` lines in
    the messages of `commits` ([(sha, message)], as git log gives them)."""
    return [{"sha": sha, "reason": m.group(1)} for sha, msg in commits for m in ACCEPT_RE.finditer(msg)]


def apply_acceptances(report, accepted):
    """Marks the report's regressions as accepted when a commit between base
    and HEAD says so; the regressions stay listed."""
    report["accepted"] = accepted
    if report["regressions"] and accepted:
        report["verdict"] = "accepted"
    return report


def exit_code(report):
    return 1 if report["regressions"] and not report.get("accepted") else 0


# ============================================================= formatting
def fmt_seconds(s):
    if s is None:
        return "–"
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6)):
        if abs(s) >= scale:
            return f"{s / scale:.3g} {unit}"
    return f"{s / 1e-9:.3g} ns"


def fmt_count(x):
    if x is None:
        return "–"
    for unit, scale in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if abs(x) >= scale:
            return f"{x / scale:.2f} {unit}"
    return f"{x:.2f}"


def fmt_change(c):
    if c is None:
        return "–"
    pct = c * 100
    # a gate set below 0.01 % must not print its regressions as "+0.00 %"
    return f"{pct:+.1e} %" if 0 < abs(pct) < 0.005 else f"{pct:+.2f} %"


def fmt_time_change(t):
    """'-18.0 % [-35, +4] n.s.': the change of medians, its 95 % bootstrap
    interval, and n.s. unless it is significant."""
    if not t or t.get("change") is None:
        return "–"
    text = fmt_change(t["change"])
    iv = t.get("change_interval_95")
    if iv:
        text += f" [{iv[0] * 100:+.0f}, {iv[1] * 100:+.0f}]"
    return text + ("" if t.get("significant") else " n.s.")


def fmt_p(p):
    return "–" if p is None else f"{p:.3f}"


TABLE_HEADER = ["benchmark", "time/step base", "time/step new", "Δ time [95 % CI] (informative)", "p (U test)",
                "Ir/step base", "Ir/step new", "Δ Ir", "verdict"]


def table_rows(report):
    rows = []
    for r in report["benchmarks"]:
        t, i = r["time"] or {}, r["ir"] or {}
        verdict = ("REGRESSION" if i.get("regression") else "ok") if i else "not gated"
        if verdict == "REGRESSION" and report.get("accepted"):
            verdict = "accepted"
        rows.append([r["name"], fmt_seconds(t.get("base_median_s")),
                     fmt_seconds(t.get("new_median_s")), fmt_time_change(t),
                     fmt_p(t.get("p_value")), fmt_count(i.get("base_per_step")),
                     fmt_count(i.get("new_per_step")), fmt_change(i.get("change")), verdict])
    return rows


def side_label(side):
    if not side:
        return "?"
    text = side.get("ref") or "working tree"
    if side.get("sha"):
        text += f" ({side['sha'][:12]})"
    if side.get("dirty"):
        text += " + uncommitted changes"
    return text


def format_text(report):
    """The console table (plain, fixed width) and the regression details."""
    rows = [TABLE_HEADER] + table_rows(report)
    widths = [max(len(row[c]) for row in rows) for c in range(len(TABLE_HEADER))]
    lines = [f"base: {side_label(report.get('base'))}",
             f"new:  {side_label(report.get('new'))}",
             f"time: median of {report.get('reps', '?')} alternated runs per side, 95 % bootstrap "
             "interval, n.s. = not significant (informative, never gated); Ir: callgrind, "
             f"one window (the gate, at +{report['threshold_pct']:g} %)", ""]
    for k, row in enumerate(rows):
        lines.append("  ".join(cell.ljust(w) if c == 0 else cell.rjust(w)
                               for c, (cell, w) in enumerate(zip(row, widths))))
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    lines.append("")
    lines += regression_lines(report)
    return "\n".join(lines) + "\n"


def regression_lines(report):
    lines = []
    for r in report["benchmarks"]:
        if not (r["ir"] and r["ir"]["regression"]):
            continue
        lines.append(f"REGRESSION: {r['name']}: instructions per step "
                     f"{fmt_change(r['ir']['change'])} ({fmt_count(r['ir']['base_per_step'])} -> "
                     f"{fmt_count(r['ir']['new_per_step'])}), threshold +{report['threshold_pct']:g} %")
        if r["reproduce"]:
            lines.append("  reproduce (base, then new; compare with callgrind_annotate):")
            lines += [f"    {cmd}" for cmd in r["reproduce"]]
    if report["regressions"] and report.get("accepted"):
        for a in report["accepted"]:
            lines.append(f"ACCEPTED by commit {a['sha'][:12]}: perf-regression-accepted: {a['reason']}")
        lines.append(f"{len(report['regressions'])} gated regression(s), accepted by the commit message(s) "
                     "above: exit 0")
    elif report["regressions"]:
        lines.append(f"{len(report['regressions'])} gated regression(s): exit 1 (a commit that trades "
                     "speed on purpose says so with a line 'perf-regression-accepted: <reason>')")
    else:
        lines.append(f"no instruction-count regression above +{report['threshold_pct']:g} %: pass")
    return lines


def format_markdown(report):
    """A Markdown section for a CI job summary ($GITHUB_STEP_SUMMARY)."""
    icon = ("⚠️ regression accepted" if report.get("accepted") else "❌ regression") \
        if report["regressions"] else "✅ pass"
    out = [f"### Performance comparison: {icon}", "",
           f"* base: `{side_label(report.get('base'))}`",
           f"* new: `{side_label(report.get('new'))}`",
           f"* time: median of {report.get('reps', '?')} alternated runs per side, 95 % bootstrap "
           "interval, two-sided Mann–Whitney U p-value; n.s. = not significant; informative, "
           "never gated (shared machines drift)",
           f"* Ir: callgrind instructions per step of one window from a fixed snapshot; "
           f"gated at +{report['threshold_pct']:g} %", "",
           "| " + " | ".join(TABLE_HEADER) + " |",
           "|" + "|".join(["---"] + ["---:"] * (len(TABLE_HEADER) - 1)) + "|"]
    for row in table_rows(report):
        row = [f"`{row[0]}`"] + row[1:-1] + [f"**{row[-1]}**" if row[-1] == "REGRESSION" else row[-1]]
        out.append("| " + " | ".join(row) + " |")
    out.append("")
    details = regression_lines(report)
    if report["regressions"]:
        out += ["```", *details, "```"]
    else:
        out.append(details[-1])
    return "\n".join(out) + "\n"


def write_atomic(path, text):
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        pathlib.Path(tmp).unlink(missing_ok=True)
        raise


def write_outputs(report, out_dir):
    out_dir = pathlib.Path(out_dir)
    write_atomic(out_dir / "compare.json", json.dumps(report, indent=2, ensure_ascii=False) + "\n")
    write_atomic(out_dir / "compare.md", format_markdown(report))
    return out_dir / "compare.json", out_dir / "compare.md"


# ==================================================================== git
def git(repo, *args, check=True):
    proc = subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True)
    if check and proc.returncode != 0:
        raise CompareError(f"git {' '.join(args)} failed: {proc.stderr.strip()}")
    return proc


def resolve_ref(repo, ref):
    """Full commit sha of `ref`; a clear error when git does not know it."""
    proc = git(repo, "rev-parse", "--verify", "--quiet", f"{ref}^{{commit}}", check=False)
    if proc.returncode != 0 or not proc.stdout.strip():
        hint = "(run `git fetch` if it is a remote branch, e.g. BASE=origin/main)"
        if re.search(r"[~^]", ref):
            hint = ("(the history does not reach that far: a single-commit or shallow clone "
                    "has no parent commit; fetch more history with `git fetch --deepen=1`)")
        raise CompareError(f"unknown git ref '{ref}': not a branch, tag or commit of {repo} {hint}")
    return proc.stdout.strip()


def commits_between(repo, base_sha, head="HEAD"):
    """[(sha, message)] of the commits in base..head."""
    proc = git(repo, "log", "--format=%H%x00%B%x01", f"{base_sha}..{head}", check=False)
    if proc.returncode != 0:
        return []
    out = []
    for record in proc.stdout.split("\x01"):
        if "\x00" in record:
            sha, msg = record.split("\x00", 1)
            out.append((sha.strip(), msg))
    return out


def default_base(repo):
    """The merge base of HEAD with `main` (or `origin/main`)."""
    for branch in ("main", "origin/main"):
        if git(repo, "rev-parse", "--verify", "--quiet", f"{branch}^{{commit}}", check=False).returncode == 0:
            proc = git(repo, "merge-base", "HEAD", branch, check=False)
            if proc.returncode == 0 and proc.stdout.strip():
                return branch, proc.stdout.strip()
            raise CompareError(f"HEAD has no merge base with '{branch}'; name the base: "
                               "make compare BASE=<ref>")
    raise CompareError("no BASE given and no 'main' or 'origin/main' branch to take the merge base "
                       "with; name the base: make compare BASE=<ref> (e.g. BASE=HEAD~1)")


def is_dirty(repo):
    proc = git(repo, "status", "--porcelain", "--untracked-files=no", check=False)
    return bool(proc.stdout.strip())


def ensure_worktree(repo, sha, work_dir):
    """A detached worktree of `sha` at WORK/worktree-<sha12>, reused when it is
    already there and intact; stale registrations are pruned first."""
    path = pathlib.Path(work_dir) / f"worktree-{sha[:12]}"
    git(repo, "worktree", "prune")
    if path.exists():
        head = git(path, "rev-parse", "HEAD", check=False)
        if head.returncode == 0 and head.stdout.strip() == sha and \
                pathlib.Path(path, ".git").is_file():
            return path
        git(repo, "worktree", "remove", "--force", str(path), check=False)
        shutil.rmtree(path, ignore_errors=True)
        git(repo, "worktree", "prune")
    path.parent.mkdir(parents=True, exist_ok=True)
    git(repo, "worktree", "add", "--detach", str(path), sha)
    return path


# ================================================================== build
def log_tail(path, lines=LOG_TAIL_LINES):
    text = pathlib.Path(path).read_text(errors="replace").splitlines()
    return "\n".join(text[-lines:])


def build_side(source, build_dir, log_path, what, jobs=2, cmake="cmake"):
    """Configure and build sphnl_bench of `source` into `build_dir`; returns the
    binary. The cmake output goes to `log_path`; its tail is shown on failure."""
    build_dir, log_path = pathlib.Path(build_dir), pathlib.Path(log_path)
    build_dir.mkdir(parents=True, exist_ok=True)
    steps = [[cmake, "-S", str(source), "-B", str(build_dir), *CMAKE_OPTIONS],
             [cmake, "--build", str(build_dir), "--target", BENCH_TARGET, "-j", str(jobs)]]
    with open(log_path, "w") as log:
        for cmd in steps:
            log.write(f"$ {shlex.join(cmd)}\n")
            log.flush()
            if subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode != 0:
                raise CompareError(f"{what} does not build (log: {log_path}); last lines:\n"
                                   f"{log_tail(log_path)}")
    bench = build_dir / BENCH_RELPATH
    if not (bench.is_file() and os.access(bench, os.X_OK)):
        raise CompareError(f"{what} built, but {bench} is missing")
    return bench


def has_benchmark_sources(source):
    return any(pathlib.Path(source, "benchmarks").glob("*.cpp")) or \
        pathlib.Path(source, "benchmarks", "CMakeLists.txt").exists()


# ============================================================== benchmark
@dataclasses.dataclass
class Side:
    label: str            # "base" or "new"
    bench: pathlib.Path
    cache_dir: pathlib.Path
    info: dict            # ref, sha, dirty: for the report
    experiment: pathlib.Path = None   # the file this bench reads (experiment_for)
    names: dict = dataclasses.field(default_factory=dict)  # today's name -> the name this bench writes


def bench_args(side, experiment, size, out_file, name=None):
    experiment = side.experiment or experiment
    args = [str(side.bench), f"--experiment={experiment}", f"--size={size}",
            f"--cache-dir={side.cache_dir}", f"--benchmark_out={out_file}",
            "--benchmark_out_format=json", "--benchmark_repetitions=1",
            "--benchmark_min_time=0"]
    if name is not None:
        args.insert(4, f"--benchmark_filter={gb_filter(side.names.get(name, name))}")
    return args


def old_names_experiment(doc):
    """The experiment `doc` with its sweep axes in the vocabulary before the
    run-config keys were used everywhere ('particles' -> 'n', 'cell_order' ->
    'order', 'list_steps' -> 'ns'), for a base bench built before that change."""
    to_old = {new: old for old, new in OLD_AXES.items()}
    out = json.loads(json.dumps(doc))
    for size, sweep in out.get("sweep", {}).items():
        out["sweep"][size] = {to_old.get(axis, axis): values for axis, values in sweep.items()}
    return out


def experiment_for(side, experiment, size, work_dir):
    """The experiment file `side`'s bench reads: `experiment` when its schema
    accepts it (--validate), else a copy in the old sweep-axis names when that
    one is accepted, or the bench predates --validate (and so the renaming)."""
    def validate(path):
        cmd = [str(side.bench), f"--experiment={path}", f"--size={size}",
               f"--cache-dir={side.cache_dir}", "--validate"]
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              errors="replace")
        return proc.returncode, proc.stdout
    code, out = validate(experiment)
    if code == 0:
        return experiment
    old = pathlib.Path(work_dir) / f"{side.label}-{experiment.stem}-old-names.json"
    write_atomic(old, json.dumps(old_names_experiment(read_json(experiment, "benchmark set")),
                                 indent=1) + "\n")
    old_code, old_out = validate(old)
    if old_code == 0 or re.search(r"unrecognized (command-line )?(flag|argument).*--validate", old_out):
        return old
    tail = "\n".join(out.splitlines()[-10:])
    raise CompareError(f"the {side.label} bench rejects {experiment}, in today's sweep-axis names "
                       f"and in the old ones; its message:\n{tail}")


def run_checked(cmd, side, log_path, what):
    """Run one benchmark process, appending its output to `log_path`. A base
    binary that rejects the flags of docs/CONTRACTS.md §2 is reported as
    predating the benchmark interface."""
    with open(log_path, "a") as log:
        log.write(f"$ {shlex.join(cmd)}\n")
        log.flush()
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True, errors="replace")
        log.write(proc.stdout)
    if proc.returncode != 0:
        tail = "\n".join(proc.stdout.splitlines()[-20:])
        hint = ""
        if side.label == "base" and re.search(
                r"unrecognized (command-line )?(flag|argument|option)|unknown (flag|option)|"
                r"--experiment=.* is required", proc.stdout, re.I):
            hint = ("\nthe base binary predates the benchmark interface of docs/CONTRACTS.md §2 "
                    "(--experiment/--size/--cache-dir); compare against a newer base")
        raise CompareError(f"{what} failed (exit {proc.returncode}; log: {log_path}); "
                           f"last lines:\n{tail}{hint}")


def read_json(path, what):
    try:
        return json.loads(pathlib.Path(path).read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise CompareError(f"{what}: cannot read {path} ({e})") from None


def timing_runs(sides, experiment, size, reps, work_dir, log_path, progress):
    """s_per_step samples {name: {side label: [..]}}, runs alternated A B A B."""
    samples = {}
    for rep in range(reps):
        for side in sides:
            out = pathlib.Path(work_dir) / f"time-{side.label}-{rep}.json"
            progress(f"timing run {rep + 1}/{reps}: {side.label}")
            run_checked(bench_args(side, experiment, size, out), side, log_path,
                        f"{side.label} benchmark run {rep + 1}")
            for name, fig in parse_gb_json(read_json(out, f"{side.label} run"), str(out)).items():
                side.names[name] = fig["run_name"]
                samples.setdefault(name, {}).setdefault(side.label, []).append(fig["s_per_step"])
    return samples


def callgrind_run(side, name, experiment, size, work_dir, valgrind):
    """(Ir inside the timed window, steps counted, reproduce command) of one
    benchmark under callgrind; output and log files are named for the run."""
    stem = f"callgrind-{side.label}-" + re.sub(r"[^A-Za-z0-9_.-]+", "_", name)
    cg_out, gb_out = (pathlib.Path(work_dir) / f"{stem}{ext}" for ext in (".out", ".json"))
    cmd = V.callgrind_command(valgrind, cg_out, bench_args(side, experiment, size, gb_out, name))
    cg_out.unlink(missing_ok=True)
    run_checked(cmd, side, pathlib.Path(work_dir) / f"{stem}.log",
                f"callgrind run of {side.label} {name}")
    ir = parse_callgrind_ir(pathlib.Path(cg_out).read_text(errors="replace"), str(cg_out))
    figs = parse_gb_json(read_json(gb_out, "callgrind run"), str(gb_out))
    if name not in figs:
        raise CompareError(f"callgrind run of {side.label}: {name} did not run "
                           f"(filter {gb_filter(side.names.get(name, name))})")
    if ir == 0:
        raise CompareError(f"callgrind counted 0 instructions in {TIMED_FUNCTION} for the "
                           f"{side.label} binary: it lacks the noinline function "
                           "sphnl::bench::timed_window (predates the benchmark interface?)")
    steps = figs[name]["window_steps"] * figs[name]["iterations"]
    return ir, steps, shlex.join(cmd)


def callgrind_all(sides, names, experiment, size, work_dir, valgrind, jobs, progress):
    """Ir of every (benchmark, side), `jobs` valgrind processes at a time:
    instruction counts do not depend on what else runs on the machine."""
    tasks = [(name, side) for name in names for side in sides]
    results = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        futures = {pool.submit(callgrind_run, side, name, experiment, size, work_dir, valgrind):
                   (name, side.label) for name, side in tasks}
        for done, future in enumerate(concurrent.futures.as_completed(futures), 1):
            name, label = futures[future]
            results[(name, label)] = future.result()
            progress(f"callgrind {done}/{len(tasks)} done: {label} {name}")
    irs, reproduce = {}, {}
    for name in names:
        per_side = [results[(name, side.label)] for side in sides]
        irs[name] = tuple((ir, steps) for ir, steps, _ in per_side)
        reproduce[name] = [cmd for _, _, cmd in per_side]
    return irs, reproduce


def binary_digest(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:12]


# =================================================================== main
def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("--base", default="",
                   help="git ref of the base (default: merge base of HEAD with main)")
    p.add_argument("--threshold", type=float, default=2.0,
                   help="gate: fail when Ir/step grows by more than this percentage (default 2)")
    p.add_argument("--reps", type=int, default=5,
                   help="timing runs per side, alternated A B A B (default 5)")
    p.add_argument("--out", type=pathlib.Path, default=None,
                   help="folder for compare.json and compare.md (default .compare/out)")
    p.add_argument("--experiment", type=pathlib.Path, default=None,
                   help=f"benchmark set (default: the working tree's {EXPERIMENT})")
    p.add_argument("--size", default="default", help="sweep size of the experiment (default: default)")
    p.add_argument("--repo", type=pathlib.Path, default=REPO, help=argparse.SUPPRESS)
    p.add_argument("--work-dir", type=pathlib.Path, default=None,
                   help="worktrees, builds, caches and logs (default REPO/.compare)")
    p.add_argument("--jobs", type=int, default=2, help="parallel build jobs and callgrind runs (default 2)")
    p.add_argument("--valgrind", default="valgrind", help="valgrind executable")
    p.add_argument("--no-callgrind", action="store_true",
                   help="time only: nothing is gated, exit 0 unless an error occurs")
    p.add_argument("--base-bench", type=pathlib.Path,
                   help="use this base sphnl_bench instead of building --base")
    p.add_argument("--new-bench", type=pathlib.Path,
                   help="use this new sphnl_bench instead of building the working tree")
    args = p.parse_args(argv)
    if args.threshold < 0:
        p.error("--threshold must be >= 0 (a percentage)")
    if args.reps < 1:
        p.error("--reps must be >= 1")
    args.repo = args.repo.resolve()
    args.work_dir = (args.work_dir or args.repo / ".compare").resolve()
    args.out = (args.out or args.work_dir / "out").resolve()
    args.experiment = (args.experiment or args.repo / EXPERIMENT).resolve()
    return args


def prepare_sides(args, progress):
    """Resolve the base, build both binaries, and pick their snapshot caches."""
    repo, work = args.repo, args.work_dir
    work.mkdir(parents=True, exist_ok=True)
    if args.base:
        ref, sha = args.base, resolve_ref(repo, args.base)
    else:
        branch, sha = default_base(repo)
        ref = f"merge-base(HEAD, {branch})"
    head = git(repo, "rev-parse", "HEAD", check=False).stdout.strip()
    base_info = {"ref": ref, "sha": sha, "dirty": False}
    new_info = {"ref": "working tree", "sha": head, "dirty": is_dirty(repo)}

    if args.base_bench:
        base_bench = args.base_bench.resolve()
    else:
        progress(f"base {ref} ({sha[:12]}): worktree and build under {work}")
        tree = ensure_worktree(repo, sha, work)
        if not has_benchmark_sources(tree):
            raise CompareError(f"base {ref} ({sha[:12]}) predates the benchmark interface: it has "
                               "no benchmarks/*.cpp (sphnl_bench); compare against a newer base")
        base_bench = build_side(tree, work / f"build-{sha[:12]}", work / f"build-{sha[:12]}.log",
                                f"base {ref} ({sha[:12]})", args.jobs)
    if args.new_bench:
        new_bench = args.new_bench.resolve()
    else:
        progress(f"new: working tree {repo} -> {work / 'build-current'}")
        new_bench = build_side(repo, work / "build-current", work / "build-current.log",
                               "the working tree", args.jobs)
    # Snapshot caches keyed by the binary: a rebuilt working tree whose physics
    # changed must not reuse the other side's (or its own stale) snapshots.
    sides = []
    for label, bench, info in (("base", base_bench, base_info), ("new", new_bench, new_info)):
        cache = work / f"cache-{binary_digest(bench)}"
        cache.mkdir(parents=True, exist_ok=True)
        info = dict(info, bench=str(bench), cache_dir=str(cache))
        sides.append(Side(label, bench, cache, info))
    return sides


def run(args, progress):
    if not args.experiment.is_file():
        raise CompareError(f"benchmark set {args.experiment} not found")
    if not args.no_callgrind and shutil.which(args.valgrind) is None:
        raise CompareError(f"valgrind not found ('{args.valgrind}'): install it "
                           "(apt-get install valgrind) or pass --no-callgrind to time only")
    sides = prepare_sides(args, progress)
    run_dir = args.work_dir / "runs"
    shutil.rmtree(run_dir, ignore_errors=True)
    run_dir.mkdir(parents=True)
    log_path = run_dir / "bench.log"
    for side in sides:
        side.experiment = experiment_for(side, args.experiment, args.size, run_dir)
        if side.experiment != args.experiment:
            progress(f"the {side.label} bench predates today's sweep-axis names: it reads "
                     f"{side.experiment.name}, and its benchmark names are matched in today's")
    samples = timing_runs(sides, args.experiment, args.size, args.reps, run_dir, log_path, progress)
    both = sorted(n for n, s in samples.items() if len(s) == 2)
    if not both:
        raise CompareError("base and new binaries ran no benchmark of the same name; "
                           "the base probably predates the naming of docs/CONTRACTS.md §2")
    for name in sorted(set(samples) - set(both)):
        progress(f"note: {name} ran only on the {next(iter(samples[name]))} side; not compared")
    times = {n: (samples[n]["base"], samples[n]["new"]) for n in both}
    irs, reproduce = {}, {}
    if not args.no_callgrind:
        progress(f"callgrind: {len(both)} benchmarks x 2 sides, {args.jobs} at a time")
        irs, reproduce = callgrind_all(sides, both, args.experiment, args.size, run_dir,
                                       args.valgrind, args.jobs, progress)
    report = compare(times, irs, args.threshold, reproduce)
    apply_acceptances(report, acceptances(commits_between(args.repo, sides[0].info["sha"])))
    report.update(base=sides[0].info, new=sides[1].info, reps=args.reps,
                  experiment=str(args.experiment), size=args.size,
                  gated=not args.no_callgrind)
    return report


def main(argv=None):
    args = parse_args(argv)

    start = time.monotonic()

    def progress(msg):
        print(f"compare: [{time.monotonic() - start:5.0f} s] {msg}", file=sys.stderr, flush=True)

    try:
        report = run(args, progress)
    except CompareError as e:
        print(f"compare: error: {e}", file=sys.stderr)
        return e.code
    json_path, md_path = write_outputs(report, args.out)
    sys.stdout.write(format_text(report))
    print(f"wrote {json_path} and {md_path} ({time.monotonic() - start:.0f} s in all)")
    return exit_code(report)


if __name__ == "__main__":
    sys.exit(main())
