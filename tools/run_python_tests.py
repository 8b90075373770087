"""The Python test suite, one test class per process, `--jobs` at a time.

`make test` runs it after ctest. The tests are those `python -m unittest
discover -s tests/python` finds; each TestCase class runs in a process of
its own (`python -m unittest -v <module>.<class>`, tests/python on the
path as discover puts it), so a class that draws reports or waits on the
real binaries no longer leaves the other core idle. Classes run longest
first: by the seconds each took last time (kept in
$SPHNL_BUILD_DIR/python_test_seconds.json), else by those in
tests/python/class_seconds.json (committed, so that a fresh build starts
the long classes first too; refresh it with `--save-seconds`), else those
of modules that start the real binaries first. Each class's output is printed whole when
it ends; the last line is the total:

    N passed, N failed, N skipped

    /usr/bin/python3 tools/run_python_tests.py [--jobs 2] [-k pattern]
"""
import argparse
import ast
import concurrent.futures as cf
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from harness.fsio import write_atomic  # noqa: E402

TESTS = ROOT / "tests" / "python"
TIMES_NAME = "python_test_seconds.json"
SEED_TIMES = TESTS / "class_seconds.json"


def test_classes(pattern):
    """["module.Class"] of every TestCase class with tests in the modules
    whose file name matches `pattern`, read from the source (no import: a
    module that does not import is one unit, `module`, and fails as such).
    A class counts when it derives, directly or through classes of its
    module, from a *TestCase and has test_ methods, its own or inherited."""
    units = []
    for path in sorted(TESTS.glob("test_*.py")):
        if pattern and not re.search(pattern, path.name):
            continue
        try:
            tree = ast.parse(path.read_text(encoding="utf-8"))
        except SyntaxError:
            units.append(path.stem)
            continue
        classes = {c.name: c for c in tree.body if isinstance(c, ast.ClassDef)}

        def base_names(c):
            return [b.attr if isinstance(b, ast.Attribute) else getattr(b, "id", "") for b in c.bases]

        def is_case(c, seen=()):
            return any(n.endswith("TestCase") or (n in classes and n not in seen and is_case(classes[n], seen + (n,)))
                       for n in base_names(c))

        def has_tests(c, seen=()):
            own = any(isinstance(f, ast.FunctionDef) and f.name.startswith("test") for f in c.body)
            return own or any(n in classes and n not in seen and has_tests(classes[n], seen + (n,))
                              for n in base_names(c))

        found = [f"{path.stem}.{name}" for name, c in classes.items() if is_case(c) and has_tests(c)]
        units += sorted(found) or [path.stem]
    return units


def starts_binaries(unit):
    return "SPHNL_BUILD_DIR" in (TESTS / (unit.split(".")[0] + ".py")).read_text(encoding="utf-8")


def longest_first(units, times):
    def key(u):
        if u in times:
            return (0, -times[u])
        return (1, not starts_binaries(u), u)
    return sorted(units, key=key)


def read_times(path):
    """{unit: seconds} from `path`; {} when it is missing or unreadable (the
    times only order the classes)."""
    try:
        return json.loads(path.read_text(encoding="utf-8")) if path.exists() else {}
    except (OSError, ValueError):
        return {}


def write_times(path, times):
    write_atomic(path, json.dumps(times, indent=1, sort_keys=True) + "\n")


def counts(output):
    """(run, failed, skipped) from unittest's closing lines."""
    ran = re.search(r"^Ran (\d+) tests?", output, re.M)
    run = int(ran.group(1)) if ran else 0
    failed = sum(int(n) for n in re.findall(r"(?:failures|errors|unexpected successes)=(\d+)", output))
    skipped = sum(int(n) for n in re.findall(r"skipped=(\d+)", output))
    return run, failed, skipped


def run_unit(unit):
    t0 = time.monotonic()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(TESTS), os.environ.get("PYTHONPATH")]))}
    # Several classes run at once, some starting 2-thread binaries: spinning
    # OpenMP waits on shared cores stall them (the CMake tests do the same).
    env.setdefault("OMP_WAIT_POLICY", "passive")
    p = subprocess.run([sys.executable, "-m", "unittest", "-v", unit],
                       cwd=ROOT, env=env, capture_output=True, text=True, stdin=subprocess.DEVNULL)
    return unit, p.returncode, p.stdout + p.stderr, time.monotonic() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="classes at a time (default: the cores)")
    ap.add_argument("-k", dest="pattern", default="", help="only the modules whose file name matches this regex")
    ap.add_argument("--save-seconds", action="store_true",
                    help=f"also write this run's seconds per class to {SEED_TIMES.relative_to(ROOT)}")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error(f"--jobs {args.jobs}: at least 1")
    names = test_classes(args.pattern)
    if not names:
        print(f"run_python_tests: no module of {TESTS} matches {args.pattern!r}", file=sys.stderr)
        return 2
    build = os.environ.get("SPHNL_BUILD_DIR")
    times_path = Path(build) / TIMES_NAME if build and Path(build).is_dir() else None
    times = {**read_times(SEED_TIMES), **(read_times(times_path) if times_path else {})}
    t0 = time.monotonic()
    total = failed = skipped = 0
    bad = []
    with cf.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for fut in cf.as_completed([pool.submit(run_unit, u) for u in longest_first(names, times)]):
            unit, rc, output, seconds = fut.result()
            run, fail, skip = counts(output)
            if rc != 0 and fail == 0:
                fail = 1  # an import error or a crash: the unit did not report
            total, failed, skipped = total + run, failed + fail, skipped + skip
            times[unit] = round(seconds, 1)
            if rc != 0:
                bad.append(unit)
            print(f"===== {unit}: {run} tests, {fail} failed, {skip} skipped, {seconds:.1f} s =====")
            print(output.rstrip(), flush=True)
    if times_path:
        write_times(times_path, times)
    if args.save_seconds:  # every class that still exists, this run's seconds where it ran
        known = set(test_classes(""))
        write_times(SEED_TIMES, {u: t for u, t in times.items() if u in known})
    print(f"\nPython tests: {len(names)} test classes, {args.jobs} at a time, {time.monotonic() - t0:.1f} s"
          + (f"; failed: {', '.join(bad)}" if bad else ""))
    print(f"{total - failed - skipped} passed, {failed} failed, {skipped} skipped")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
