"""Provenance and noise records of a run (docs/CONTRACTS.md, machine.json and
`sphnl_rounds`): what machine and code measured, and how quiet it was.

Every reader is best effort: a field that cannot be read here is None, never
a guess. Nothing recorded is an absolute path (results are committed and
compared between machines).
"""
import datetime
import hashlib
import json
import os
import pathlib
import platform
import re
import subprocess

REPO = pathlib.Path(__file__).resolve().parent.parent
CPU_SYS = pathlib.Path("/sys/devices/system/cpu")
# A round is flagged `under_load` when other processes used more than this
# many cores while it ran, or steal exceeded STEAL_PCT (see under_load()).
LOAD_MARGIN, STEAL_PCT = 0.5, 1.0


def under_load(record, bench_threads=None):
    """Whether a round's noise record says it ran under load. Where /proc/stat
    was read (`other_busy_cores`, `steal_pct`), those decide: they measure the
    round itself. The load average is a one-minute mean that still holds the
    run's own work just before (a snapshot developed on every core inside the
    round, the previous round's threads), so it decides only where /proc/stat
    could not be read: with the bench's threads known, it must exceed them by
    LOAD_MARGIN; without them, the flag the record carries."""
    others, steal = record.get("other_busy_cores"), record.get("steal_pct")
    if others is not None or steal is not None:
        return bool((others or 0) > LOAD_MARGIN or (steal or 0) > STEAL_PCT)
    if bench_threads is None:
        return bool(record.get("under_load"))
    allowance = bench_threads + LOAD_MARGIN
    return any(v is not None and v[0] > allowance
               for v in (record.get("loadavg_before"), record.get("loadavg_after")))


def _run(args, cwd=REPO, env=None, timeout=30):
    """A command's CompletedProcess (text, C locale), or None where it could
    not be run or did not finish in `timeout` seconds."""
    try:
        return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=timeout,
                              cwd=cwd, env={**(os.environ if env is None else env), "LC_ALL": "C"})
    except (OSError, subprocess.TimeoutExpired):
        return None


def _cmd(*args):
    """A command's stripped output, or "" where it failed."""
    out = _run(args)
    return out.stdout.strip() if out is not None and out.returncode == 0 else ""


def _read(path):
    try:
        return pathlib.Path(path).read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        return None


def now():
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


# ------------------------------------------------------------------ the code
# The tests of the merge refusal set these to play a given checkout, whatever
# the state of the tree they run in.
TEST_REVISION, TEST_DIRTY = "SPHNL_TEST_GIT_REVISION", "SPHNL_TEST_GIT_DIRTY"


def git_revision():
    return os.environ.get(TEST_REVISION) or _cmd("git", "rev-parse", "HEAD") or None


def git_dirty():
    """Uncommitted changes to the code (results/ written by earlier parts of a
    run do not count); None outside a git checkout."""
    if os.environ.get(TEST_DIRTY) in ("0", "1"):
        return os.environ[TEST_DIRTY] == "1"
    if not git_revision():
        return None
    return bool(_cmd("git", "status", "--porcelain", "--", ".", ":!results"))


# What a sphnl binary is built from (cmake/revision.cmake marks a build
# "-dirty" by the same paths): a change elsewhere (docs, plots, results) does
# not change what is measured.
CODE_PATHS = ("core", "benchmarks", "cmake", "CMakeLists.txt")


def binary_revision(cmd, env=None):
    """The revision a sphnl binary reports (cmd: `sphnl_bench --revision`,
    `sphnl --version`): the first word of its output that looks like one, or
    None where it cannot say."""
    out = _run(cmd, env=env, timeout=60)
    words = out.stdout.split() if out is not None and out.returncode == 0 else []
    revs = [w for w in words if re.fullmatch(r"[0-9a-f]{7,40}(-dirty)?|unknown", w)]
    return revs[0] if revs else None


def build_mismatch(built, repo=REPO):
    """Why a binary built from revision `built` (as it reports it) does not
    measure this checkout's code, or None when it does or cannot be told
    ("unknown": built outside git). The code of two revisions is the same
    when CODE_PATHS do not differ between them; a "-dirty" build holds
    uncommitted changes, which match only a checkout with uncommitted code
    changes on the same revision (that much can be checked; the changes
    themselves cannot, and git_dirty records them)."""
    if built in (None, "unknown"):
        return None
    base, built_dirty = built.removesuffix("-dirty"), built.endswith("-dirty")

    def git(*a):
        return _run(("git", *a), cwd=repo, timeout=60)
    head = git("rev-parse", "--short=12", "HEAD")
    if head is None or head.returncode != 0:
        return None  # not a git checkout: nothing to compare with
    head = head.stdout.strip()
    known = git("cat-file", "-e", f"{base}^{{commit}}")
    if known is None or known.returncode != 0:
        return f"it was built from revision {built}, which this repository does not hold"
    changed = git("diff", "--name-only", base, "HEAD", "--", *CODE_PATHS)
    if changed is not None and changed.stdout.strip():
        files = changed.stdout.split()
        more = f" and {len(files) - 3} more" if len(files) > 3 else ""
        return (f"it was built from revision {built}, and the code changed since then "
                f"(HEAD {head}: {', '.join(files[:3])}{more})")
    local = git("status", "--porcelain", "--", *CODE_PATHS)
    tree_dirty = bool(local is not None and local.stdout.strip())
    if built_dirty and not tree_dirty:
        return (f"it was built from uncommitted changes on {base} ({built}), which this checkout "
                f"(HEAD {head}, clean code) does not hold")
    if tree_dirty and not built_dirty:
        return (f"it was built from the committed code of {base}, and this checkout has uncommitted "
                "changes to the code since")
    return None


def sha256(path):
    try:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        return h.hexdigest()
    except OSError:
        return None


def relative_to_repo(path):
    """`path` relative to the repository, or its bare name when outside it
    (machine.json carries no absolute path)."""
    path = pathlib.Path(path).resolve()
    try:
        return str(path.relative_to(REPO))
    except ValueError:
        return f"(outside the repository)/{path.name}"


# ------------------------------------------------------------------- the CPU
def lscpu():
    rows = (line.split(":", 1) for line in _cmd("lscpu").splitlines() if ":" in line)
    return {k.strip(): v.strip() for k, v in rows}


def proc_cpuinfo():
    """Fields of the first processor of /proc/cpuinfo, and every `cpu MHz`."""
    first, mhz = {}, []
    for block in (_read("/proc/cpuinfo") or "").split("\n\n"):
        fields = dict((k.strip(), v.strip()) for k, _, v in
                      (line.partition(":") for line in block.splitlines()) if k.strip())
        if "cpu MHz" in fields:
            try:
                mhz.append(float(fields["cpu MHz"]))
            except ValueError:
                pass
        first = first or fields
    return first, mhz


def sysfs_caches(cpu=0):
    """{'L1d': '48K', 'L1i': '32K', 'L2': '1024K', 'L3': '32768K'} of one CPU
    from /sys/devices/system/cpu/cpuN/cache/index*/{level,type,size}."""
    out = {}
    for index in sorted((CPU_SYS / f"cpu{cpu}" / "cache").glob("index*")):
        level, kind, size = (_read(index / f) for f in ("level", "type", "size"))
        if level and size:
            suffix = {"Data": "d", "Instruction": "i"}.get(kind, "")
            out[f"L{level}{suffix}"] = size
    return out


def cpu_mhz(cpus=None):
    """Current clock of each CPU in `cpus` (MHz): sysfs scaling_cur_freq where
    readable, else /proc/cpuinfo's `cpu MHz`; [] when neither is."""
    cpus = sorted(cpus if cpus is not None else affinity() or [])
    sysfs = [_read(CPU_SYS / f"cpu{c}" / "cpufreq" / "scaling_cur_freq") for c in cpus]
    if sysfs and all(v and v.isdigit() for v in sysfs):
        return [int(v) / 1000.0 for v in sysfs]
    _, mhz = proc_cpuinfo()
    return [mhz[c] for c in cpus if c < len(mhz)] if mhz else []


def max_mhz(cpu_fields):
    value = _read(CPU_SYS / "cpu0" / "cpufreq" / "cpuinfo_max_freq")
    if value and value.isdigit():
        return int(value) / 1000.0
    try:
        return float(cpu_fields.get("CPU max MHz", ""))
    except ValueError:
        return None


def affinity():
    try:
        return sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return None


def loadavg():
    text = _read("/proc/loadavg")
    try:
        return [float(v) for v in text.split()[:3]] if text else None
    except ValueError:
        return None


def cpu_jiffies():
    """(busy, steal, total) jiffies of all CPUs from the first line of /proc/stat."""
    text = _read("/proc/stat")
    if not text or not text.startswith("cpu "):
        return None
    v = [int(x) for x in text.splitlines()[0].split()[1:]]
    v += [0] * (8 - len(v))
    idle = v[3] + v[4]                 # idle + iowait
    steal = v[7]
    total = sum(v[:8])                 # guest time is already inside user/nice
    return total - idle - steal, steal, total


def free_memory_reported_to_host(sysfs_root="/sys"):
    """Whether a virtio balloon offers free page reporting (device id 0x0005,
    feature bit 5): the kernel then hands free memory that lies idle to its
    host, and the library's Search::Options default to base pages
    (huge_pages_by_default, the same test in C++)."""
    devices = pathlib.Path(sysfs_root) / "bus" / "virtio" / "devices"
    try:
        entries = sorted(devices.iterdir())
    except OSError:
        return False
    for dev in entries:
        features = _read(dev / "features") or ""
        if _read(dev / "device") == "0x0005" and len(features) > 5 and features[5] == "1":
            return True
    return False


def transparent_huge_pages():
    """The selected mode of /sys/kernel/mm/transparent_hugepage/enabled
    ('always', 'madvise', 'never'), or None where unreadable."""
    m = re.search(r"\[(\w+)\]", _read("/sys/kernel/mm/transparent_hugepage/enabled") or "")
    return m.group(1) if m else None


def machine_info():
    """CPU, clock, caches, memory, compiler and OS of this machine."""
    cpu = lscpu()
    first, mhz = proc_cpuinfo()

    def number(key, fallback=None):
        value = cpu.get(key) or first.get(fallback or "", "")
        return int(value) if str(value).isdigit() else None
    mem = re.search(r"MemTotal:\s+(\d+)", _read("/proc/meminfo") or "")
    sockets, per_socket = number("Socket(s)"), number("Core(s) per socket")
    lscpu_caches = {k.replace(" cache", ""): cpu[k] for k in
                    ("L1d cache", "L1i cache", "L2 cache", "L3 cache") if k in cpu}
    from_sysfs = sysfs_caches()
    return {
        "cpu_model": cpu.get("Model name") or first.get("model name") or platform.processor() or None,
        "cpu_vendor": cpu.get("Vendor ID") or first.get("vendor_id"),
        "cpu_family": number("CPU family", "cpu family"),
        "cpu_model_number": number("Model", "model"),
        "cpu_stepping": number("Stepping", "stepping"),
        "cpu_mhz": round(sum(mhz) / len(mhz), 1) if mhz else None,
        "cpu_max_mhz": max_mhz(cpu),
        "logical_cpus": number("CPU(s)") or os.cpu_count(),
        "cores": sockets * per_socket if sockets and per_socket else None,
        "threads_per_core": number("Thread(s) per core"),
        "caches": lscpu_caches or from_sysfs,
        "caches_source": "lscpu" if lscpu_caches else "sysfs" if from_sysfs else None,
        "caches_sysfs": from_sysfs,
        "memory_bytes": int(mem.group(1)) * 1024 if mem else None,
        # what a first call's pages cost depends on both (docs/FINDINGS.md,
        # "Huge pages on idle memory"); the search's page default follows the first
        "free_memory_reported_to_host": free_memory_reported_to_host(),
        "transparent_huge_pages": transparent_huge_pages(),
        "compiler": (_cmd("c++", "--version").splitlines() or [None])[0],
        "os": platform.platform(),
        "python": platform.python_version(),
    }


# ---------------------------------------------------------------- the rounds
class NoiseProbe:
    """The noise record of one round: taken just before the bench starts and
    just after it ends (docs/CONTRACTS.md `sphnl_rounds`)."""

    def __init__(self, bench_threads):
        self.bench_threads = bench_threads
        self.started, self.load_before = now(), loadavg()
        self.jiffies_before = cpu_jiffies()
        self.children_before = os.times()

    def finish(self, env):
        after, children = cpu_jiffies(), os.times()
        steal_pct = other_cores = None
        if self.jiffies_before and after:
            d_busy, d_steal, d_total = (a - b for a, b in zip(after, self.jiffies_before))
            steal_pct = round(100.0 * d_steal / d_total, 2) if d_total > 0 else 0.0
            ticks = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
            wall_ticks = d_total / max(1, os.cpu_count() or 1)  # jiffies per CPU = wall time
            own = ((children.children_user - self.children_before.children_user) +
                   (children.children_system - self.children_before.children_system)) * ticks
            other_cores = round(max(0.0, d_busy - own) / wall_ticks, 2) if wall_ticks > 0 else None
        record = {"started": self.started, "ended": now(),
                  "loadavg_before": self.load_before, "loadavg_after": loadavg(),
                  "steal_pct": steal_pct, "other_busy_cores": other_cores,
                  "cpu_affinity": affinity(),
                  "omp_proc_bind": env.get("OMP_PROC_BIND"), "omp_places": env.get("OMP_PLACES"),
                  "cpu_mhz": cpu_mhz()}
        record["under_load"] = under_load(record, self.bench_threads)
        return record


# ----------------------------------------------------------------- the parts
# What a part records of the machine it ran on: a run assembled in parts over
# several sessions may otherwise land on another VM (another CPU, another
# core count) between parts, and its pooled figures would mix two machines.
IDENTITY_KEYS = ("cpu_vendor", "cpu_model", "cpu_family", "cpu_model_number", "logical_cpus")
TEST_IDENTITY = "SPHNL_TEST_MACHINE"  # tests: a JSON object that replaces this machine's identity


def machine_identity(info=None):
    """The keys of IDENTITY_KEYS from machine_info() (or from `info`)."""
    if info is None and os.environ.get(TEST_IDENTITY):
        return json.loads(os.environ[TEST_IDENTITY])
    info = machine_info() if info is None else info
    return {k: info.get(k) for k in IDENTITY_KEYS}


def describe_identity(identity):
    """'AMD EPYC (family 26, model 2), 2 logical CPUs' from machine_identity()."""
    ident = ", ".join(f"{k} {identity[key]}" for k, key in (("family", "cpu_family"), ("model", "cpu_model_number"))
                      if identity.get(key) is not None)
    return (f"{identity.get('cpu_model') or 'unknown CPU'}{' (' + ident + ')' if ident else ''}, "
            f"{identity.get('logical_cpus') or '?'} logical CPUs")


def merge_refusal(earlier_parts, part):
    """Why the results of `part` (this invocation) must not be merged into a
    run folder whose earlier parts are `earlier_parts`, or None when they may:
    a dirty tree, or a revision or bench binary that differs from an earlier
    part's, would mix measurements of different code; another machine's
    (machine_identity) would mix measurements of different hardware."""
    if part.get("git_dirty"):
        return ("the working tree has uncommitted changes to the code (git status, results/ "
                "aside); commit them, or measure into a new run folder")
    for old in earlier_parts:
        if old.get("git_dirty"):
            return (f"an earlier part ({old.get('date')}) was measured from a dirty tree; "
                    "measure into a new run folder")
        for key, what in (("git_revision", "git revision"), ("bench_sha256", "bench binary")):
            if old.get(key) and part.get(key) and old[key] != part[key]:
                return (f"the {what} differs from an earlier part's ({old.get('date')}: "
                        f"{old[key][:12]} here {part[key][:12]}); measure into a new run folder "
                        "or rebuild the earlier revision")
        mine, theirs = part.get("machine"), old.get("machine")
        if mine and theirs and any(mine.get(k) != theirs.get(k) for k in IDENTITY_KEYS):
            return (f"the machine differs from an earlier part's ({old.get('date')}: "
                    f"{describe_identity(theirs)}; here {describe_identity(mine)}); measure into a new "
                    "run folder on this machine, or finish the run on the earlier one")
    return None
