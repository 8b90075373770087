#!/usr/bin/python3
"""Check a portable build of `sphnl` (`make test-portable`).

    /usr/bin/python3 tools/check_portable.py --native build/sphnl --portable build-portable/sphnl

The portable build is configured with -DCMAKE_CXX_FLAGS=-march=x86-64-v2, so
this also checks that the user's -march is not overridden by SPHNL_MARCH:

1. no AVX-512 instruction in the portable binary (no zmm register in
   `objdump -d`; the native build on an AVX-512 machine has hundreds);
2. the same short dam-break run in both builds gives the same results:
   counts and step sequence exactly, floating-point figures and the final
   particle state within 1e-9 relative (the builds differ in FMA contraction
   and vector width, so the last bits of sums may differ).
Exit 0 when both hold, 1 otherwise, with what differs.
"""
import argparse
import csv
import json
import pathlib
import subprocess
import sys
import tempfile

RUN_ARGS = ["run", "--set", "particles=3000", "--set", "steps=30", "--set", "output_interval=0", "--quiet"]
REL_TOL = 1e-9


def zmm_instructions(binary):
    out = subprocess.run(["objdump", "-d", "--no-show-raw-insn", str(binary)], capture_output=True,
                         text=True, check=True).stdout
    return [line.strip() for line in out.splitlines() if "%zmm" in line]


def run_case(binary, out_dir):
    subprocess.run([str(binary), *RUN_ARGS, "--out", str(out_dir)], check=True)
    summary = json.loads((out_dir / "summary.json").read_text())
    final = sorted((out_dir / "snapshots").glob("step_*.csv"))[-1]
    with open(final, newline="") as f:
        rows = list(csv.DictReader(f))
    return summary, rows


def close(a, b, scale):
    return abs(a - b) <= REL_TOL * max(abs(a), abs(b), scale)


def differences(native, portable):
    (sa, ra), (sb, rb) = native, portable
    diffs = []
    for key in ("n_fluid", "n_boundary", "n_total", "steps", "particles_lost"):
        if sa[key] != sb[key]:
            diffs.append(f"{key}: native {sa[key]}, portable {sb[key]}")
    for key in ("simulated_time", "max_speed", "dx", "h"):
        if not close(sa[key], sb[key], 0.0):
            diffs.append(f"{key}: native {sa[key]!r}, portable {sb[key]!r}")
    scale = max(abs(v) for v in sa["momentum"])  # a component near 0 is round-off
    for k, (a, b) in enumerate(zip(sa["momentum"], sb["momentum"])):
        if not close(a, b, scale):
            diffs.append(f"momentum[{k}]: native {a!r}, portable {b!r}")
    if len(ra) != len(rb):
        return diffs + [f"final snapshot: {len(ra)} rows native, {len(rb)} portable"]
    for col in ("x", "y", "z", "vx", "vy", "vz", "rho", "p"):
        va, vb = [float(r[col]) for r in ra], [float(r[col]) for r in rb]
        col_scale = max(abs(v) for v in va)
        bad = [i for i, (a, b) in enumerate(zip(va, vb)) if not close(a, b, col_scale)]
        if bad:
            i = bad[0]
            diffs.append(f"final snapshot column {col}: {len(bad)} particles differ, e.g. id {ra[i]['id']}: "
                         f"native {va[i]!r}, portable {vb[i]!r}")
    return diffs


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--native", type=pathlib.Path, required=True)
    p.add_argument("--portable", type=pathlib.Path, required=True)
    args = p.parse_args(argv)
    ok = True
    zmm = zmm_instructions(args.portable)
    if zmm:
        ok = False
        print(f"check_portable: {args.portable} holds {len(zmm)} AVX-512 instructions, e.g. {zmm[0]}", file=sys.stderr)
    else:
        print(f"check_portable: {args.portable}: no AVX-512 instruction "
              f"(native build: {len(zmm_instructions(args.native))} with zmm registers)")
    with tempfile.TemporaryDirectory(prefix="sphnl_portable_") as tmp:
        native = run_case(args.native, pathlib.Path(tmp) / "native")
        portable = run_case(args.portable, pathlib.Path(tmp) / "portable")
    diffs = differences(native, portable)
    if diffs:
        ok = False
        print("check_portable: the portable build gives other results:\n  " + "\n  ".join(diffs), file=sys.stderr)
    else:
        print(f"check_portable: same results ({native[0]['steps']} steps of {native[0]['n_total']} particles; "
              f"counts exact, floating point within {REL_TOL:g} relative)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
