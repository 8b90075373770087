"""Deterministic counts of sphnl_bench's timed window under valgrind: shared
by tools/compare.py (instructions, the regression gate) and
experiments/counters.py (instructions and simulated cache misses per phase,
the `counters` benchmark kind of docs/CONTRACTS.md).

* the build flavour valgrind 3.19 can run (`make counters-build`): AVX2 at
  most, since it dies on AVX-512 instructions; `python3 -m harness.valgrind
  --cmake-options` prints its CMake options for the Makefile;
* the cache models valgrind simulates (two levels only: D1 and LL);
* the callgrind command that counts inside `sphnl::bench::timed_window`;
* the parser of callgrind output files: totals and inclusive cost per function.

Counts repeat exactly: callgrind simulates caches from the program's own
access stream, so the machine's load does not enter them.
"""
import dataclasses
import pathlib
import re
import sys

# The function sphnl_bench marks noinline and runs exactly one timed window
# in (benchmarks/bench_common.hpp); callgrind counts only inside it.
TIMED_FUNCTION = "sphnl::bench::timed_window*"
# --dump-after takes no wildcard (valgrind 3.19): the full signature, as
# callgrind names it (`fn=` lines of its output).
TIMED_SIGNATURE = "sphnl::bench::timed_window(sphnl::Simulation&, int, unsigned long&)"
# The phases of Table I (core/src/simulation.cpp, Simulation::step) and the
# noinline functions whose inclusive costs make them up.
PHASE_FUNCTIONS = {
    "neighbour_list": ("sphnl::Simulation::build_neighbours()",),
    "force": ("sphnl::Simulation::compute_forces()",),
    "update": ("sphnl::Simulation::time_step() const", "sphnl::Simulation::update(double)"),
}
# Release code for x86-64-v3 (AVX2 + FMA: valgrind 3.19 has no AVX-512), with
# debug information (-g changes no generated code) so that callgrind names
# every function and callgrind_annotate can show source lines.
CMAKE_OPTIONS = ["-DCMAKE_BUILD_TYPE=Release", "-DSPHNL_MARCH=x86-64-v3", "-DCMAKE_CXX_FLAGS=-g",
                 "-DSPHNL_BUILD_TESTS=OFF", "-DSPHNL_BUILD_BENCHMARKS=ON",
                 "-DPython3_EXECUTABLE=/usr/bin/python3"]
COUNTERS_BUILD = "build-counters"
CPU_SYS = pathlib.Path("/sys/devices/system/cpu")


class ValgrindError(Exception):
    """A count that cannot be made or read; the message says why and the fix."""


# ------------------------------------------------------------- cache models
@dataclasses.dataclass(frozen=True)
class Cache:
    size: int     # bytes
    assoc: int    # ways
    line: int     # bytes

    def option(self):
        return f"{self.size},{self.assoc},{self.line}"


@dataclasses.dataclass(frozen=True)
class CacheModel:
    name: str
    i1: Cache
    d1: Cache
    ll: Cache
    note: str

    def options(self):
        return [f"--I1={self.i1.option()}", f"--D1={self.d1.option()}", f"--LL={self.ll.option()}"]

    def fields(self):
        """The geometry as numeric result fields (docs/CONTRACTS.md §2a)."""
        return {"d1_bytes": self.d1.size, "d1_assoc": self.d1.assoc, "ll_bytes": self.ll.size,
                "ll_assoc": self.ll.assoc, "line_bytes": self.d1.line}


KIB, MIB = 1024, 1024 * 1024
# A 2010 server core (Nehalem / Westmere class): 32 KiB 8-way L1d and L1i,
# 256 KiB L2 per core, 8 MiB 16-way shared L3, 64-byte lines. valgrind models
# two levels, so its LL is the L3 (the L2 is not simulated). The paper names
# no hardware: this is an assumption about the machines of its time.
NEHALEM_2010 = CacheModel(
    "nehalem_2010", Cache(32 * KIB, 8, 64), Cache(32 * KIB, 8, 64), Cache(8 * MIB, 16, 64),
    "assumed 2010 server (Nehalem/Westmere class): L1d 32 KiB 8-way, L2 256 KiB (not simulated), "
    "LL = L3 8 MiB 16-way, 64 B lines; the paper names no hardware")
CACHE_MODELS = ("this_machine", "nehalem_2010")


def _size_bytes(text):
    """'32K' -> 32768, '32768K' -> 33554432, '8M' -> 8388608."""
    m = re.fullmatch(r"\s*(\d+)\s*([KMG]?)i?B?\s*", text or "")
    if not m:
        raise ValgrindError(f"cache size {text!r} not understood")
    return int(m.group(1)) * {"": 1, "K": KIB, "M": MIB, "G": 1024 * MIB}[m.group(2)]


def valgrind_cache(size, assoc, line):
    """A Cache valgrind accepts: it needs a power-of-two number of sets, so a
    size that gives another (e.g. 12 MiB 12-way) is cut to the largest
    power-of-two set count below it, keeping ways and line."""
    sets = size // (assoc * line)
    if sets < 1:
        raise ValgrindError(f"cache of {size} B, {assoc}-way, {line} B lines has no set")
    sets = 1 << (sets.bit_length() - 1)
    return Cache(sets * assoc * line, assoc, line)


def sysfs_levels(cpu_dir=None):
    """[(level, type, Cache as sysfs describes it)] of one CPU's caches."""
    base = pathlib.Path(cpu_dir) if cpu_dir else CPU_SYS / "cpu0" / "cache"
    out = []
    for index in sorted(base.glob("index*")):
        def read(name):
            try:
                return (index / name).read_text().strip()
            except OSError:
                return None
        level, kind, size = read("level"), read("type"), read("size")
        ways, line = read("ways_of_associativity"), read("coherency_line_size")
        if not (level and kind and size and ways and line):
            continue
        out.append((int(level), kind, Cache(_size_bytes(size), int(ways), int(line))))
    return out


def this_machine(cpu_dir=None):
    """The cache model of the CPU running this: its L1d and L1i, and its last
    level (the largest level sysfs lists) as valgrind's LL."""
    levels = sysfs_levels(cpu_dir)
    d1 = next((c for lv, k, c in levels if lv == 1 and k == "Data"), None)
    i1 = next((c for lv, k, c in levels if lv == 1 and k == "Instruction"), None)
    last = max((lv for lv, k, _ in levels if k == "Unified"), default=None)
    if not (d1 and i1 and last):
        raise ValgrindError(f"cannot read this machine's caches from {cpu_dir or CPU_SYS / 'cpu0/cache'} "
                            "(index*/level, type, size, ways_of_associativity, coherency_line_size); "
                            "use cache_model nehalem_2010")
    ll_raw = next(c for lv, k, c in levels if lv == last and k == "Unified")
    ll = valgrind_cache(ll_raw.size, ll_raw.assoc, ll_raw.line)
    note = (f"this machine: L1d {d1.size // KIB} KiB {d1.assoc}-way, LL = L{last} "
            f"{ll_raw.size // KIB} KiB {ll_raw.assoc}-way, {d1.line} B lines")
    if ll != ll_raw:
        note += f" (simulated as {ll.size // KIB} KiB: valgrind needs a power-of-two number of sets)"
    return CacheModel("this_machine", valgrind_cache(i1.size, i1.assoc, i1.line),
                      valgrind_cache(d1.size, d1.assoc, d1.line), ll, note)


def cache_model(name):
    if name == "nehalem_2010":
        return NEHALEM_2010
    if name == "this_machine":
        return this_machine()
    raise ValgrindError(f"unknown cache_model {name!r}; known: {', '.join(CACHE_MODELS)}")


# ---------------------------------------------------------------- commands
def gb_filter(name):
    """An anchored Google Benchmark filter matching exactly the benchmark `name`."""
    return "^" + re.sub(r"([\\^$.|?*+()\[\]{}])", r"\\\1", name) + "$"


def callgrind_command(valgrind, out_file, command, cache=None, dump_per_window=False):
    """callgrind counting only inside the timed window; with a CacheModel it
    also simulates the caches. dump_per_window writes one file per window
    (OUT.1, OUT.2, ...: callgrind's --dump-after), so that a warm-up window
    can be told from the measured one."""
    args = [valgrind, "--tool=callgrind", f"--callgrind-out-file={out_file}",
            f"--toggle-collect={TIMED_FUNCTION}"]
    if cache is not None:
        args += ["--cache-sim=yes", *cache.options()]
    if dump_per_window:
        args.append(f"--dump-after={TIMED_SIGNATURE}")
    return args + list(command)


# ----------------------------------------------------------------- parsing
@dataclasses.dataclass
class Profile:
    """One callgrind output file: the event names, the total of each event,
    and the inclusive cost of each function ({name: [costs in event order]})."""
    events: list
    totals: list
    inclusive: dict

    def total(self, event):
        return self.totals[self.index(event)]

    def index(self, event):
        if event not in self.events:
            raise ValgrindError(f"no {event} event in the callgrind output (events: {' '.join(self.events)}); "
                                "cache events need --cache-sim=yes")
        return self.events.index(event)

    def of(self, functions, event):
        """Inclusive `event` summed over `functions` (0 for one never called
        while counting)."""
        i = self.index(event)
        return sum(self.inclusive[f][i] for f in functions if f in self.inclusive)


_COMPRESSED = re.compile(r"\((\d+)\)(?:\s(.*))?$")


def _costs(tokens, n_positions, n_events):
    vals = [int(t) for t in tokens[n_positions:n_positions + n_events]]
    return vals + [0] * (n_events - len(vals))


def parse_callgrind(text, source="callgrind output"):
    """A Profile from the text of a callgrind output file (format version 1:
    name compression, subposition compression, `calls=` lines whose next
    line holds the inclusive cost of the call). A function's inclusive cost
    is its own cost lines plus the costs of the calls it makes."""
    events, positions, totals, summary = None, 1, None, None
    names, fn = {}, None
    self_cost, call_cost = {}, {}
    pending_call = False
    for line in text.splitlines():
        if not line or line[0] == "#":
            continue
        c = line[0]
        if c.isdigit() or c in "+-*":
            if events is None:
                raise ValgrindError(f"{source}: cost line before the 'events:' line")
            costs = _costs(line.split(), positions, len(events))
            target = call_cost if pending_call else self_cost
            acc = target.setdefault(fn, [0] * len(events))
            for i, v in enumerate(costs):
                acc[i] += v
            pending_call = False
            continue
        key, sep, rest = line.partition("=")
        if sep and key in ("fn", "cfn", "cfi", "cfl", "fl", "fi", "fe", "ob", "cob"):
            if key in ("fn", "cfn"):
                m = _COMPRESSED.match(rest)
                if m:
                    name = m.group(2) if m.group(2) is not None else names.get(m.group(1))
                    if m.group(2) is not None:
                        names[m.group(1)] = m.group(2)
                else:
                    name = rest
                if key == "fn":
                    fn = name
            continue
        if sep and key == "calls":
            pending_call = True
            continue
        key, sep, rest = line.partition(":")
        if not sep:
            continue
        if key == "events":
            events = rest.split()
        elif key == "positions":
            positions = len(rest.split())
        elif key == "totals":
            totals = [int(v) for v in rest.split()]
        elif key == "summary":
            summary = [int(v) for v in rest.split()]
    if events is None:
        raise ValgrindError(f"{source}: no 'events:' line; not a callgrind output file")
    totals = totals or summary
    if totals is None:
        raise ValgrindError(f"{source}: no 'totals:' or 'summary:' line; did valgrind finish?")
    totals = totals + [0] * (len(events) - len(totals))
    inclusive = {}
    for f in set(self_cost) | set(call_cost):
        s = self_cost.get(f, [0] * len(events))
        k = call_cost.get(f, [0] * len(events))
        inclusive[f] = [a + b for a, b in zip(s, k)]
    return Profile(events, totals, inclusive)


def dump_files(out_file):
    """The per-window dumps of a run with dump_per_window, in order
    (OUT.1, OUT.2, ...; callgrind writes OUT itself at exit with what was
    counted after the last dump)."""
    out = pathlib.Path(out_file)
    found = []
    for p in out.parent.glob(out.name + ".*"):
        suffix = p.name[len(out.name) + 1:]
        if suffix.isdigit():
            found.append((int(suffix), p))
    return [p for _, p in sorted(found)]


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--cmake-options"]:
        print(" ".join(CMAKE_OPTIONS))
        return 0
    if argv == ["--cache-models"]:
        for name in CACHE_MODELS:
            m = cache_model(name)
            print(f"{name}: {' '.join(m.options())}  ({m.note})")
        return 0
    print("usage: python3 -m harness.valgrind --cmake-options | --cache-models", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
