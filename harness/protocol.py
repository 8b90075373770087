"""The measurement protocol of an experiment (docs/MEASUREMENT.md): rounds,
repetitions per round, the adaptive stop, and the window rule for Verlet-list
comparisons. Pure functions of the experiment definition and the samples, so
that experiments/run.py stays a driver and the rules are unit-tested.
"""
import collections
import math

SIZES = ("tiny", "default", "full")
PROTOCOL_FIELDS = ("min_rounds", "max_rounds", "reps_per_round", "budget_s")
# Rounds (separate bench processes) every experiment gets at these sizes at
# least: between-process drift is the scatter a single process hides.
MIN_ROUNDS = {"tiny": 1, "default": 3, "full": 3}
MIN_REPETITIONS = {"tiny": 1, "default": 9, "full": 9}
STOP_TARGET, STOP_BUDGET, STOP_MAX = "target met", "budget", "max rounds"
LIST_LIFETIMES = 3  # a window covers at least this many lifetimes of the largest n_s


class ProtocolError(Exception):
    """An experiment's protocol or window cannot be used; the message names
    the file, the field and the fix."""


def protocol_of(exp, size):
    """{min_rounds, max_rounds, reps_per_round, target_halfwidth_pct, budget_s}
    of `exp` at `size`, checked (ProtocolError names the field). The block is
    one set of fields for every size, or {size: fields} (docs/CONTRACTS.md)."""
    where = f"experiments/{exp['id']}.json"
    block = exp.get("protocol")
    example = ('"protocol": {"tiny": {"min_rounds": 1, ...}, "default": {"min_rounds": 3, '
               '"max_rounds": 5, "reps_per_round": 3, "target_halfwidth_pct": 1.0, "budget_s": 300}, '
               '"full": {...}}')
    if not isinstance(block, dict) or not block:
        raise ProtocolError(f"{where}: no 'protocol' block; add e.g. {example} (docs/CONTRACTS.md)")
    name = "protocol"
    if all(k in SIZES for k in block):
        if not isinstance(block.get(size), dict):
            raise ProtocolError(f"{where}: protocol has no size '{size}'; give every size "
                                f"({', '.join(SIZES)}) its fields, e.g. {example}")
        block, name = block[size], f"protocol.{size}"
    out = {}
    for field in PROTOCOL_FIELDS + ("target_halfwidth_pct",):
        value = block.get(field)
        if not isinstance(value, (int, float)) or isinstance(value, bool) or value <= 0:
            raise ProtocolError(f"{where}: {name}.{field} is {value!r}; it must be a positive number")
        out[field] = value
    for field in ("min_rounds", "max_rounds", "reps_per_round"):
        if out[field] != int(out[field]):
            raise ProtocolError(f"{where}: {name}.{field} must be a whole number")
        out[field] = int(out[field])
    if out["min_rounds"] < MIN_ROUNDS[size]:
        raise ProtocolError(f"{where}: {name}.min_rounds is {out['min_rounds']}; at size '{size}' "
                            f"at least {MIN_ROUNDS[size]} separate processes are required")
    if out["max_rounds"] < out["min_rounds"]:
        raise ProtocolError(f"{where}: {name}.max_rounds ({out['max_rounds']}) is below "
                            f"min_rounds ({out['min_rounds']})")
    if out["min_rounds"] * out["reps_per_round"] < MIN_REPETITIONS[size]:
        raise ProtocolError(f"{where}: {name}: min_rounds x reps_per_round is "
                            f"{out['min_rounds'] * out['reps_per_round']}; at least "
                            f"{MIN_REPETITIONS[size]} repetitions per point are required")
    return out


# ---------------------------------------------------------------- window rule
def compared_ns(exp, size):
    """The n_s of the Verlet-list configurations of the sweep (CLL ignores n_s)."""
    sweep = exp.get("sweep", {}).get(size, {})
    if not any(lst != "cll" for lst in sweep.get("list", [])):
        return []
    return sorted(set(sweep.get("list_steps", [])))


def window_ok(exp, size):
    """(ok, message): for list comparisons the timed window must be a multiple
    of every n_s compared (whole list lifetimes, so no configuration pays for
    a build whose list it does not use) and cover at least LIST_LIFETIMES
    lifetimes of the largest n_s (paper section 2.5: a list lives n_s steps)."""
    if exp.get("uses") or exp.get("benchmark") not in ("step", "counters", "mpi"):
        return True, ""
    ns = compared_ns(exp, size)
    window = exp["window_steps"].get(size)
    if not ns:
        return True, ""
    lcm = math.lcm(*ns)
    need = max(ns) * LIST_LIFETIMES
    if window % lcm == 0 and window >= need:
        return True, ""
    fix = lcm * math.ceil(need / lcm)
    return False, (f"experiments/{exp['id']}.json: window_steps.{size} = {window} must be a multiple "
                   f"of every n_s compared ({', '.join(map(str, ns))}: lcm {lcm}) and at least "
                   f"{LIST_LIFETIMES} x {max(ns)} = {need} steps; use {fix} or change the n_s sweep")


# ------------------------------------------------------------------ the stop
def metric_samples(entries, exp):
    """{run name: [[values of one round], ...]} of the experiment's metric (`metric`
    of the file, else s_per_step, else real time): what the adaptive stop
    must know precisely."""
    key = exp.get("metric", "s_per_step")
    out = collections.defaultdict(lambda: collections.defaultdict(list))
    for e in entries:
        if not e.get("error_occurred"):
            out[e["run_name"]][e["sphnl_round"]].append(e.get(key, e.get("real_time")))
    return {name: list(by_round.values()) for name, by_round in out.items()}


def median_halfwidth_pct(rounds, confidence=0.95, resamples=2000, seed=0):
    """Half-width, in percent of the median, of a percentile-bootstrap
    interval of the median of one configuration's repetitions, given as one
    list per round. With several rounds each replicate draws the rounds with
    replacement, then the repetitions inside each drawn round, so drift
    between processes widens the interval as it should; with one round the
    repetitions are resampled. A deliberately small copy of the round-level
    resampling in harness/stats.py (the report's statistics), kept here so
    the stop rule does not depend on the report's code."""
    import numpy as np
    groups = [np.asarray([v for v in r if v == v], dtype=float) for r in rounds]
    groups = [g for g in groups if g.size]
    pooled = np.concatenate(groups) if groups else np.array([])
    if pooled.size < 2 or not np.median(pooled):
        return math.inf
    rng = np.random.default_rng(seed)
    if len(groups) == 1:
        meds = np.median(rng.choice(pooled, size=(resamples, pooled.size)), axis=1)
    elif len({g.size for g in groups}) == 1:  # the usual case, vectorised: (B, rounds, reps)
        table, (k, m) = np.stack(groups), (len(groups), groups[0].size)
        drawn = rng.integers(0, k, size=(resamples, k, 1))
        meds = np.median(table[drawn, rng.integers(0, m, size=(resamples, k, m))].reshape(resamples, -1),
                         axis=1)
    else:
        meds = np.empty(resamples)
        for b in range(resamples):
            drawn = rng.integers(0, len(groups), size=len(groups))
            meds[b] = np.median(np.concatenate([rng.choice(groups[k], size=groups[k].size)
                                                for k in drawn]))
    lo, hi = np.quantile(meds, [(1 - confidence) / 2, (1 + confidence) / 2])
    return 100.0 * (hi - lo) / 2 / abs(np.median(pooled))


def stop_reason(samples, proto, rounds_done, elapsed_s, round_s):
    """Why to stop after `rounds_done` rounds, or None to run another.
    samples: {configuration: [[values of round 0], [round 1], ...]}; round_s: the expected length of one
    more round (the mean of those done). The target is checked first: a
    finished measurement is 'target met' even when the budget is also spent."""
    if rounds_done < proto["min_rounds"]:
        return None
    widths = [median_halfwidth_pct(v) for v in samples.values()]
    if widths and max(widths) <= proto["target_halfwidth_pct"]:
        return STOP_TARGET
    if rounds_done >= proto["max_rounds"]:
        return STOP_MAX
    if elapsed_s + round_s > proto["budget_s"]:
        return STOP_BUDGET
    return None


def executed_order(entries):
    """Run names of one round's iteration entries in the order they ran (by
    the bench's `run_sequence` counter), and how many calls were discarded
    warm-ups (sequence numbers with no entry)."""
    seq = sorted((e["run_sequence"], e["run_name"]) for e in entries if "run_sequence" in e)
    if len(seq) != len(entries):
        return [e["run_name"] for e in entries], None  # an old bench: no order recorded
    numbers = [int(s) for s, _ in seq]
    warmups = (max(numbers) + 1 - len(numbers)) if numbers else 0
    return [name for _, name in seq], warmups

