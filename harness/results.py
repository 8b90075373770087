"""The results format of sphnl (docs/CONTRACTS.md): experiment definitions,
benchmark names and the Google Benchmark JSON written by sphnl_bench.

Shared by experiments/run.py (which runs the sweeps and checks they are
complete), the plotting scripts and tests/python/fake_bench.py. pandas is
imported only where the DataFrame is built (load_run), so that run.py and
the fake bench start quickly.
"""
import itertools
import json
import pathlib
import re

from harness import protocol as P

SIZES = ("tiny", "default", "full")
# Name segments of each benchmark family, in the order of docs/CONTRACTS.md §2. Sweep
# axes, name segment keys and DataFrame columns are one vocabulary: the run-config
# keys of README "Configuration" (plus flow_time, which picks the snapshot).
FAMILY_KEYS = {
    "step": ["particles", "gridder", "cell_order", "reorder", "list", "list_steps", "kgc",
             "threads", "lattice", "h_coefficient", "flow_time", "window_start",
             # optional ablation axes (README.md, "Ablations")
             "pair_loop", "simd", "skip_boundary_pairs", "gridder_a_variant", "initial_order",
             "extra_loops", "thread_updates", "thread_split", "precision", "inner_order"],
    "cellindex": ["cell_order", "particles"],
    "search": ["particles", "gridder", "cell_order", "reorder", "threads",
               "impl", "cloud", "memory_order", "call", "pages", "freed_memory"],
    # the step window under callgrind (the counters kind): the caches simulated
    "counters": ["particles", "gridder", "cell_order", "reorder", "list", "list_steps", "kgc",
                 "threads", "lattice", "h_coefficient", "flow_time", "window_start",
                 "pair_loop", "simd", "skip_boundary_pairs", "gridder_a_variant", "initial_order",
                 "extra_loops", "thread_updates", "thread_split", "precision", "inner_order", "cache_model"],
    # `sphnl run` under mpirun (the mpi kind, experiments/mpi_runs.py): ranks x threads
    "mpi": ["particles", "list", "list_steps", "ranks", "threads",
            # optional: what the ranks' cell ranges balance (ranks > 1 only)
            "balance_by"],
}
# The flow time (s) a step window starts from when the sweep has no flow_time axis.
DEFAULT_FLOW_TIME = 0.35
# The vocabulary before the run-config keys were used everywhere, kept in this
# one table so that names and JSON written by older benches still read: stored
# results (results/full, results/reference, ...) and the base side of `make
# compare`. Every reader of names and counters goes through it (parse_run_name,
# canonical_run_name, entry_rows, validate_experiment); nothing writes it.
OLD_AXES = {"n": "particles", "order": "cell_order", "ns": "list_steps"}  # old sweep axis -> now
OLD_NAME_KEYS = {**OLD_AXES, "hcoef": "h_coefficient"}  # old name segment key -> now
OLD_COUNTERS = {"n": "n_particles"}            # old counter -> now (particles simulated)
# The value an optional axis has where a sweep (and so a benchmark name) lacks
# it: the one table of defaults, read by validation and by the loader, so
# results written before an axis existed still read (docs/CONTRACTS.md §2).
# window_start: benches since the axis prime every window; the results of
# older ones (no `primed_steps` counter) were timed cold.
_STEP_DEFAULTS = {"lattice": "bcc", "h_coefficient": 0.866025, "flow_time": DEFAULT_FLOW_TIME, "window_start": "primed",
                  "pair_loop": "gather", "simd": "on", "skip_boundary_pairs": 0,
                  "gridder_a_variant": "occupied", "initial_order": "generated", "extra_loops": 0,
                  "thread_updates": "private", "thread_split": "fluid", "precision": "double",
                  "inner_order": "index"}
AXIS_DEFAULTS = {
    "step": _STEP_DEFAULTS,
    "counters": _STEP_DEFAULTS,  # cache_model has none: a counters sweep names it
    "cellindex": {},
    "search": {"impl": "sphnl", "cloud": "lattice", "memory_order": "generated", "call": "warm", "pages": "base",
               "freed_memory": "as_found"},
    "mpi": {"balance_by": "interactions"},  # not filled in on load: older runs cut by particles
}


def idle_seconds(freed_memory):
    """Seconds of idle a value of the search family's `freed_memory` axis asks
    for: s for idle_<s>s, 0 for as_found and just_freed, None for any other
    value (the bench's freed_memory_idle_seconds validates experiment files)."""
    m = re.fullmatch(r"idle_(\d+)s", str(freed_memory))
    if m:
        return int(m.group(1))
    return 0 if freed_memory in ("as_found", "just_freed") else None


def pages_used(rows):
    """The pages sphnl's lists used in search rows, from the bench's
    huge_pages counter (the `pages` axis resolved, `default` included):
    'base', 'huge', 'base and huge', or None where no row carries it (rows
    of nanoflann, or older than the counter)."""
    if "huge_pages" not in rows:
        return None
    kinds = sorted({"huge" if v >= 0.5 else "base" for v in rows["huge_pages"].dropna()})
    return " and ".join(kinds) or None


# Axes filled in from AXIS_DEFAULTS when a name lacks them (lattice and h
# coefficient stay absent in step rows, as the figures and claims expect).
DEFAULTED_ON_LOAD = {"step": ("flow_time",), "counters": ("flow_time",), "search": ("impl", "cloud", "memory_order", "call", "pages", "freed_memory")}
# Axes a sweep must list: every axis of the family without a default.
REQUIRED_AXES = {family: [k for k in keys if k not in AXIS_DEFAULTS[family]]
                 for family, keys in FAMILY_KEYS.items()}
# Segments Google Benchmark itself may append to a name (->Iterations() etc.).
GB_SEGMENT_KEYS = {"iterations", "repetitions", "min_time", "min_warmup_time"}
# Top-level fields of a Google Benchmark 1.7.1 entry that are not user counters.
GB_FIELDS = {"name", "family_index", "per_family_instance_index", "run_name",
             "run_type", "repetitions", "repetition_index", "threads",
             "iterations", "real_time", "cpu_time", "time_unit",
             "error_occurred", "error_message", "aggregate_name",
             "aggregate_unit", "label", "big_o", "rms", "sphnl_round"}
# Counters that identify a repetition, not a measurement: never medianed.
BOOKKEEPING = {"repetition_index", "round", "run_sequence"}
TIME_UNITS = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}
_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


class ResultsError(Exception):
    """A results or experiment file that cannot be used; the message names it."""


def parse_value(text):
    """'31239' -> 31239, '0.87' -> 0.87, 'sort_x' -> 'sort_x'."""
    if re.fullmatch(r"[-+]?\d+", text):
        return int(text)
    if _NUMBER.fullmatch(text):
        return float(text)
    return text


def format_n(n):
    """A particle count as the paper prints it: a space every three digits
    (150 000)."""
    return f"{n:,.0f}".replace(",", " ")


def format_value(value):
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return f"{value:g}" if isinstance(value, float) else str(value)


def parse_run_name(run_name):
    """Split 'step/particles:31239/gridder:B/...' into
    ('step', {'particles': 31239, 'gridder': 'B', ...}).

    Segments Google Benchmark adds ('real_time', 'iterations:1', ...) are
    dropped; keys of the old vocabulary ('n', 'order', 'ns', 'hcoef') are
    returned under their names now (OLD_NAME_KEYS).
    """
    family, *segments = run_name.split("/")
    params = {}
    for seg in segments:
        key, sep, value = seg.partition(":")
        if sep and key not in GB_SEGMENT_KEYS:
            params[OLD_NAME_KEYS.get(key, key)] = parse_value(value)
    return family, params


def canonical_run_name(run_name):
    """The name in today's vocabulary: segment keys of the old one renamed
    (OLD_NAME_KEYS), values and order kept as written, so that a name of an
    older bench matches the one the bench writes now."""
    family, *segments = run_name.split("/")
    out = [family]
    for seg in segments:
        key, sep, value = seg.partition(":")
        out.append(f"{OLD_NAME_KEYS.get(key, key)}{sep}{value}" if sep else seg)
    return "/".join(out)


def axes_in_order(family, axes):
    known = [k for k in FAMILY_KEYS.get(family, []) if k in axes]
    return known + [k for k in axes if k not in known]


def format_run_name(family, point):
    """Inverse of parse_run_name, segments in the contract's order."""
    segs = [f"{k}:{format_value(point[k])}"
            for k in axes_in_order(family, point)]
    return "/".join([family] + segs)


def sweep_points(exp, size):
    """Every point of the cross product exp['sweep'][size], as dicts."""
    sweep = exp["sweep"][size]
    axes = axes_in_order(exp["benchmark"], list(sweep))
    points = [dict(zip(axes, combo)) for combo in itertools.product(*(sweep[a] for a in axes))]
    # the mpi kind: `max_cores` leaves out the layouts that would need more cores
    cores = exp.get("max_cores")
    points = [p for p in points if not cores or p.get("ranks", 1) * p.get("threads", 1) <= cores]
    # balance_by only matters on several ranks: one rank runs once, with the axis's first value
    if "balance_by" in sweep:
        first = sweep["balance_by"][0]
        points = [p for p in points if p.get("ranks", 1) > 1 or p["balance_by"] == first]
    return points


def point_key(params, axes):
    """Comparable identity of a sweep point restricted to `axes`."""
    def norm(v):
        return round(float(v), 9) if isinstance(v, (int, float)) else v
    return tuple((a, norm(params.get(a))) for a in sorted(axes))


# ---------------------------------------------------------------- experiments
def validate_experiment(exp, path):
    where = str(path)
    for key in ("id", "benchmark", "sweep", "window_steps", "protocol", "claims"):
        if exp.get("uses") and key in ("window_steps", "protocol"):
            continue
        if key == "protocol" and exp.get("benchmark") == "counters":
            continue  # deterministic counts: one round, no protocol
        if key not in exp:
            raise ResultsError(f"{where}: missing key '{key}'")
    if exp["id"] != pathlib.Path(path).stem:
        raise ResultsError(f"{where}: id '{exp['id']}' differs from the file name")
    if exp.get("uses"):
        return exp
    if exp["benchmark"] not in FAMILY_KEYS:
        raise ResultsError(f"{where}: unknown benchmark '{exp['benchmark']}', "
                           f"expected one of {sorted(FAMILY_KEYS)}")
    for size in SIZES:
        sweep = exp["sweep"].get(size)
        if sweep is None:
            raise ResultsError(f"{where}: sweep has no size '{size}'")
        old = [f"'{a}' was renamed to '{OLD_NAME_KEYS[a]}'" for a in sweep if a in OLD_NAME_KEYS]
        if old:
            raise ResultsError(f"{where}: sweep.{size}: sweep axis {', '.join(old)} (sweep "
                               "axes are the run-config keys of README \"Configuration\")")
        need = REQUIRED_AXES[exp["benchmark"]]
        missing = [a for a in need if a not in sweep]
        if missing:
            raise ResultsError(f"{where}: sweep.{size} lacks axes {missing}")
        if size not in exp["window_steps"]:
            raise ResultsError(f"{where}: window_steps has no size '{size}'")
        times = sweep.get("flow_time", [DEFAULT_FLOW_TIME])
        if not all(isinstance(t, (int, float)) and not isinstance(t, bool) and t > 0 for t in times):
            raise ResultsError(f"{where}: sweep.{size}.flow_time must list positive times in "
                               f"seconds, not {times}")
        try:
            if exp["benchmark"] != "counters":
                P.protocol_of(exp, size)
        except P.ProtocolError as e:
            raise ResultsError(str(e).replace(f"experiments/{exp['id']}.json", where)) from None
        ok, message = P.window_ok(exp, size)
        if not ok:
            raise ResultsError(message.replace(f"experiments/{exp['id']}.json", where))
    return exp


def experiment_order(exp_id):
    """Sort key: Table I, the figures in paper order, other studies, beyond_* last."""
    group = 0 if exp_id.startswith("table") else 1 if exp_id.startswith("fig") else \
        3 if exp_id.startswith("beyond") else 2
    return group, exp_id


def load_experiments(exp_dir):
    """{id: definition} of every experiments/*.json, validated, in report order."""
    out = {}
    paths = sorted(pathlib.Path(exp_dir).glob("*.json"), key=lambda p: experiment_order(p.stem))
    for path in paths:
        try:
            exp = json.loads(path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as e:
            raise ResultsError(f"{path}: not valid JSON ({e})") from None
        out[exp.get("id", path.stem)] = validate_experiment(exp, path)
    for exp in out.values():
        if exp.get("uses") and exp["uses"] not in out:
            raise ResultsError(f"{exp['id']}: uses unknown experiment '{exp['uses']}'")
    return out


# ------------------------------------------------------------------- results
def read_benchmark_json(path):
    """The parsed Google Benchmark JSON of one experiment; clear error otherwise."""
    try:
        doc = json.loads(pathlib.Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ResultsError(f"{path}: cannot read benchmark JSON ({e})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("benchmarks"), list):
        raise ResultsError(f"{path}: not a Google Benchmark JSON (no 'benchmarks' list)")
    return doc


def missing_points(path, exp, size):
    """Names of the sweep points of `exp` that `path` does not list (raises on a bad file)."""
    return missing_in(read_benchmark_json(path), exp, size)


def missing_in(doc, exp, size):
    """Names of the sweep points of `exp` that the parsed benchmark JSON `doc` does not list."""
    axes = list(exp["sweep"][size])
    have = set()
    for entry in doc["benchmarks"]:
        if entry.get("run_type", "iteration") == "iteration":
            family, params = parse_run_name(entry.get("run_name", entry.get("name", "")))
            if family == exp["benchmark"]:
                have.add(point_key(params, axes))
    return [format_run_name(exp["benchmark"], p) for p in sweep_points(exp, size)
            if point_key(p, axes) not in have]


def entry_rows(doc, experiment):
    """One dict per iteration entry: parameters, GB fields and counters."""
    rows = []
    for entry in doc["benchmarks"]:
        if entry.get("run_type", "iteration") != "iteration":
            continue
        run_name = canonical_run_name(entry.get("run_name", entry["name"]))
        family, params = parse_run_name(run_name)
        # a name without the segment has the axis' default (a step window
        # without flow_time starts from t = 0.35 s; a search without impl is sphnl's)
        for axis in DEFAULTED_ON_LOAD.get(family, ()):
            params.setdefault(axis, AXIS_DEFAULTS[family][axis])
        row = {"experiment": experiment, "family": family, "run_name": run_name}
        row.update(params)
        for key, value in entry.items():
            if key in GB_FIELDS:
                continue
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                col = OLD_COUNTERS.get(key, key)
                row[col + "_counter" if col in params else col] = value
        scale = TIME_UNITS.get(entry.get("time_unit", "ns"), 1e-9)
        row.update(repetition_index=entry.get("repetition_index", 0),
                   round=entry.get("sphnl_round", 0),
                   iterations=entry.get("iterations", 1),
                   real_time_s=entry.get("real_time", float("nan")) * scale,
                   cpu_time_s=entry.get("cpu_time", float("nan")) * scale,
                   error_occurred=bool(entry.get("error_occurred", False)),
                   error_message=entry.get("error_message", ""))
        rows.append(row)
    return rows


# JSON files of a run folder that are not benchmark results (docs/CONTRACTS.md).
NOT_RESULTS = {"machine.json", "claims.json", "replication.json"}


def load_run(run_dir):
    """Every <experiment>.json of a run folder as one DataFrame, one row per
    benchmark iteration entry (the report's own JSON, NOT_RESULTS, and hidden
    temp files ignored)."""
    import pandas as pd
    run_dir = pathlib.Path(run_dir)
    if not run_dir.is_dir():
        raise ResultsError(f"{run_dir}: no such results folder")
    rows = []
    for path in sorted(run_dir.glob("*.json")):  # glob matches dot files too
        if path.name not in NOT_RESULTS and not path.name.startswith("."):
            rows += entry_rows(read_benchmark_json(path), path.stem)
    df = pd.DataFrame(rows)
    if df.empty:
        df = pd.DataFrame(columns=["experiment", "family", "run_name",
                                   "repetition_index", "error_occurred"])
    return df


_NON_PARAM = {"experiment", "family", "run_name", "error_message", "error_occurred"}
_ALL_KEYS = list(dict.fromkeys(sum(FAMILY_KEYS.values(), [])))


def param_columns(df):
    """Columns that identify a configuration: the name segments of the
    contract, plus any other text-valued segment found in the names."""
    return ["experiment", "family"] + [k for k in _ALL_KEYS if k in df.columns] + \
        [c for c in df.columns if c not in _ALL_KEYS and c not in _NON_PARAM
         and df[c].dtype == object]


def medians(df):
    """One row per configuration: the median over repetitions of every numeric
    column, plus `reps` (repetitions kept) and the convenience columns
    `t` (s per step), `mem_mb` (nl_bytes / 1e6) and `N` (particles simulated).
    Entries that reported an error are dropped."""
    if df.empty:
        return df
    ok = df[~df["error_occurred"]]
    keys = param_columns(ok)
    numeric = [c for c in ok.columns if c not in keys and c not in _NON_PARAM
               and c not in BOOKKEEPING and ok[c].dtype.kind in "iuf"]
    grouped = ok.groupby(keys, dropna=False, sort=True)
    med = grouped[numeric].median().reset_index()
    for col in keys:  # integer axes read as float where other families lack them
        if med[col].dtype == float and med[col].notna().all() and (med[col] % 1 == 0).all():
            med[col] = med[col].astype(int)
    med["reps"] = grouped.size().values
    return derive_columns(med)


def derive_columns(med):
    """The convenience columns every reader of medians uses: t (seconds per
    step), mem_mb (neighbour-structure MB), N (particles simulated, as a
    float: the counter n_particles, else the requested `particles`),
    nl_bytes_per_particle and, for Verlet lists, list_bytes_per_pair (list
    bytes over the pairs the list stores; NaN for a cell-linked list)."""
    if "s_per_step" in med:
        med["t"] = med["s_per_step"]
    elif "window_steps" in med:
        med["t"] = med["real_time_s"] / med["window_steps"]
    if "nl_bytes" in med:
        med["mem_mb"] = med["nl_bytes"] / 1e6
    if "particles" in med:
        med["N"] = med["n_particles"] if "n_particles" in med else med["particles"]
        med["N"] = med["N"].fillna(med["particles"]).astype(float)
        if "nl_bytes" in med:
            med["nl_bytes_per_particle"] = med["nl_bytes"] / med["N"]
        if "list_bytes" in med and "candidates_per_particle" in med:
            # A Verlet list's pass tests each stored pair once a step, so the
            # candidates per particle (each pair counted for both particles)
            # times N / 2 are the pairs stored; a cell-linked list stores none.
            stored_pairs = med["candidates_per_particle"] * med["N"] / 2.0
            med["list_bytes_per_pair"] = (med["list_bytes"] / stored_pairs).where(med["list_bytes"] > 0)
    return med


def pick(med, **equal):
    """Rows of `med` whose columns equal the given values (absent columns ignored)."""
    for key, value in equal.items():
        if key in med:
            med = med[med[key] == value]
    return med


def improvement(med, ref, var, on=("particles",), x="N"):
    """The paper's improvement, 100 * (t_ref - t) / t_ref, of configurations
    `var` over `ref` (dicts of column values), matched on the columns `on`.
    Returns a DataFrame with columns `x`, `imp`, `t`, `t_ref`, sorted by `x`."""
    on = list(on)
    a = pick(med, **ref)[on + ["t"]]
    b = pick(med, **var)[list(dict.fromkeys(on + [x, "t"]))]
    m = b.merge(a, on=on, suffixes=("", "_ref"))
    m["imp"] = 100.0 * (m["t_ref"] - m["t"]) / m["t_ref"]
    return m.sort_values(x).reset_index(drop=True)


def errors(df):
    """(run_name, message) of every entry that reported an error."""
    if df.empty:
        return []
    bad = df[df["error_occurred"]]
    return sorted(set(zip(bad["run_name"], bad["error_message"])))
