#!/usr/bin/env python3
"""`sphnl run` under mpirun with P ranks against the serial run (ctest cases mpi.*).

Each case runs the small dam break serially (no mpirun) and with P ranks, and
checks what a user sees: the same particles (ids and types) and total mass,
positions within 1e-8 m after 50 steps (20 with KGC, 10 for the gridders), the t = 0 snapshot files identical
byte for byte, and the distributed fields of summary.json. The `pieces` case
checks snapshot_pieces=per_rank (a .vtu piece per rank and a .pvtu) against
the gathered snapshots of the same run. Exit status 77
tells ctest the case was skipped (no MPI, no mpirun), with the reason printed.
"""
import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

SKIP = 77
TOL = 1e-8


def mpirun_command(mpirun, ranks):
    """The launch prefix: --oversubscribe for more ranks than cores, and
    --allow-run-as-root when running as root (OpenMPI refuses root otherwise)."""
    cmd = [mpirun, "-np", str(ranks), "--oversubscribe"]
    if os.getuid() == 0:
        cmd.append("--allow-run-as-root")
    return cmd


def find_mpirun(given):
    path = shutil.which(given) if given else None
    if not path:
        raise FileNotFoundError(
            f"mpirun not found (looked for {given or 'mpirun'!r}); install OpenMPI "
            "(Debian: apt-get install openmpi-bin libopenmpi-dev, or `make deps`) and re-run cmake")
    return path


def run(cmd, expect_rc=0):
    env = dict(os.environ)
    # Containers often forbid the cross-memory attach of OpenMPI's shared-memory
    # transport; copying through the shared segment works everywhere.
    env.setdefault("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
    env.setdefault("OMPI_MCA_rmaps_base_oversubscribe", "1")
    # More ranks than cores (P = 4, 8, 28 on a 2-core machine): a rank waiting in
    # a collective yields its core instead of spinning on it, so the rank it
    # waits for runs (the cases take about half the time on 2 cores).
    env.setdefault("OMPI_MCA_mpi_yield_when_idle", "1")
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=240)
    if expect_rc is not None and p.returncode != expect_rc:
        sys.stderr.write(f"$ {' '.join(cmd)}\nexit {p.returncode} (expected {expect_rc})\n{p.stdout}\n{p.stderr}\n")
        raise SystemExit(1)
    return p


def sphnl_run(args, out, sets, mpirun=None, ranks=1, expect_rc=0):
    cmd = (mpirun_command(mpirun, ranks) if mpirun else []) + [args.sphnl, "run", "--quiet", "--overwrite", "--out", str(out)]
    for s in sets:
        cmd += ["--set", s]
    return run(cmd, expect_rc)


def read_csv(path):
    with open(path, newline="") as f:
        return {int(r["id"]): r for r in csv.DictReader(f)}


def compare(serial_dir, dist_dir, ranks):
    a = json.loads((serial_dir / "summary.json").read_text())
    b = json.loads((dist_dir / "summary.json").read_text())
    problems = []
    for key in ("n_total", "n_fluid", "n_boundary", "steps", "particles_lost"):
        if a[key] != b[key]:
            problems.append(f"{key}: serial {a[key]}, {ranks} ranks {b[key]}")
    if a["total_mass"] != b["total_mass"]:
        problems.append(f"total_mass: serial {a['total_mass']}, {ranks} ranks {b['total_mass']}")
    if "ranks" in a:
        problems.append("the serial summary has distributed fields")
    if b.get("ranks") != ranks:
        problems.append(f"summary ranks = {b.get('ranks')}, expected {ranks}")
    for key in ("particles_per_rank", "ghosts_per_rank", "fluid_per_rank", "interactions_per_rank"):
        if not (isinstance(b.get(key), dict) and b[key]["min"] <= b[key]["max"]):
            problems.append(f"summary {key} missing or min > max: {b.get(key)}")
    if not b.get("bytes_sent_per_step", 0) > 0:
        problems.append(f"bytes_sent_per_step = {b.get('bytes_sent_per_step')}, expected > 0")
    if "communication" not in b["wall_time_s"]:
        problems.append("wall_time_s has no communication phase")
    if [s["csv"] for s in a["snapshots"]] != [s["csv"] for s in b["snapshots"]]:
        problems.append("different snapshot files")
    first = a["snapshots"][0]
    for kind in ("csv", "vtu"):
        if (serial_dir / first[kind]).read_bytes() != (dist_dir / first[kind]).read_bytes():
            problems.append(f"t = 0 snapshot {first[kind]} differs from the serial one")
    last = a["snapshots"][-1]["csv"]
    pa, pb = read_csv(serial_dir / last), read_csv(dist_dir / last)
    if sorted(pa) != sorted(pb):
        problems.append("different particle ids in the final snapshot")
    else:
        worst = max(abs(float(pa[i][c]) - float(pb[i][c])) for i in pa for c in ("x", "y", "z"))
        types = sum(pa[i]["type"] != pb[i]["type"] for i in pa)
        print(f"  {ranks} ranks: largest position difference {worst:.3g} m, "
              f"particles per rank {b['particles_per_rank']}, ghosts {b['ghosts_per_rank']}, "
              f"{b['bytes_sent_per_step']:.0f} bytes sent per step")
        if worst > TOL:
            problems.append(f"positions differ by up to {worst:.3g} m (> {TOL})")
        if types:
            problems.append(f"{types} particles of another type")
    return problems, b


def read_vtu_points(path):
    """{id: (x, y, z)} of a .vtu that write_vtu wrote (raw appended binary,
    UInt64 headers): the DataArray offsets point past the '_' of AppendedData."""
    import re
    import struct
    data = path.read_bytes()
    start = data.index(b'<AppendedData encoding="raw">')
    base = data.index(b"_", start) + 1
    arrays = {}
    for m in re.finditer(rb'<DataArray type="(\w+)" Name="(\w+)"[^>]*offset="(\d+)"', data[:start]):
        kind, name, offset = m.group(1).decode(), m.group(2).decode(), int(m.group(3))
        at = base + offset
        size = struct.unpack_from("<Q", data, at)[0]
        code = {"Float64": "d", "Int32": "i", "Int64": "q", "UInt8": "B"}[kind]
        arrays[name] = struct.unpack_from(f"<{size // struct.calcsize(code)}{code}", data, at + 8)
    pts, ids = arrays["Points"], arrays["id"]
    return {ids[k]: pts[3 * k:3 * k + 3] for k in range(len(ids))}


def pieces_against_gathered(args, ranks):
    """snapshot_pieces=per_rank on `ranks` ranks against the gathered
    snapshots of the same run: each final .pvtu names one existing piece per
    rank, the pieces hold every particle once, at the gathered positions."""
    import re
    work = Path(args.work) / "pieces"
    sets = BASE[:1] + ["steps=10", "output_interval=1.0"]
    gathered, per_rank = work / "gathered", work / "per_rank"
    sphnl_run(args, gathered, sets, args.mpirun, ranks)
    sphnl_run(args, per_rank, sets + ["snapshot_pieces=per_rank"], args.mpirun, ranks)
    a = json.loads((gathered / "summary.json").read_text())
    b = json.loads((per_rank / "summary.json").read_text())
    problems = []
    if [s["step"] for s in a["snapshots"]] != [s["step"] for s in b["snapshots"]]:
        problems.append("the two runs wrote snapshots at different steps")
    if any("csv" in s for s in b["snapshots"]):
        problems.append("snapshot_pieces=per_rank lists CSV files it does not write")
    for snap_a, snap_b in zip(a["snapshots"], b["snapshots"]):
        pvtu = per_rank / snap_b["vtu"]
        if pvtu.suffix != ".pvtu" or not pvtu.is_file():
            problems.append(f"no .pvtu for step {snap_b['step']}: {snap_b['vtu']}")
            continue
        sources = re.findall(r'<Piece Source="([^"]+)"/>', pvtu.read_text())
        if len(sources) != ranks:
            problems.append(f"{pvtu.name} names {len(sources)} pieces, expected {ranks}")
        merged = {}
        for src in sources:
            part = read_vtu_points(pvtu.parent / src)
            if set(part) & set(merged):
                problems.append(f"{src}: particles that another piece also holds")
            merged.update(part)
        whole = read_vtu_points(gathered / snap_a["vtu"])
        if merged != whole:
            problems.append(f"step {snap_b['step']}: the pieces hold {len(merged)} particles, the gathered "
                            f"snapshot {len(whole)}, or other positions")
    if '.pvtu"' not in (per_rank / "snapshots.pvd").read_text():
        problems.append("snapshots.pvd does not name the .pvtu files")
    print(f"  {ranks} ranks: {len(b['snapshots'])} snapshots of {ranks} pieces each")
    return problems


def against_serial(args, name, sets, ranks_list):
    work = Path(args.work) / name
    serial = work / "serial"
    sphnl_run(args, serial, sets)
    failures = []
    summaries = {}
    for p in ranks_list:
        out = work / f"p{p}"
        sphnl_run(args, out, sets, args.mpirun, p)
        problems, summaries[p] = compare(serial, out, p)
        failures += [f"P = {p}: {m}" for m in problems]
    return failures, summaries


# 50 steps: 7 list lifetimes of n_s = 7, and every particle of the 3 000 moved
# by many times the 1e-8 m the positions are compared to.
BASE = ["particles=3000", "steps=50", "output_interval=1.0", "progress=false"]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sphnl", required=True)
    ap.add_argument("--mpirun", default="mpirun")
    ap.add_argument("--work", required=True)
    ap.add_argument("--case")
    ap.add_argument("--program", help="case scenarios: the test_mpi_ranks executable")
    ap.add_argument("--skip", help="print this reason and report the case as skipped")
    args = ap.parse_args()
    if args.skip:
        print(f"MPI tests skipped: {args.skip}. Install libopenmpi-dev openmpi-bin and reconfigure (SPHNL_MPI=AUTO or ON).")
        return SKIP
    if args.case == "missing_mpirun":
        try:
            find_mpirun(args.mpirun)
        except FileNotFoundError as e:
            msg = str(e)
            ok = "mpirun not found" in msg and "openmpi-bin" in msg
            print(msg)
            return 0 if ok else 1
        print(f"{args.mpirun} exists; this case needs a path that does not")
        return 1
    try:
        args.mpirun = find_mpirun(args.mpirun)
    except FileNotFoundError as e:
        print(f"MPI tests skipped: {e}")
        return SKIP

    failures = []
    if args.case in ("cll", "vlc", "vlx", "kgc"):
        # Every list on 2, 3 and 4 ranks; KGC (with VL_X) on 3.
        list_kind = "vlx" if args.case == "kgc" else args.case
        sets = BASE + [f"list={list_kind}"] + ([] if list_kind == "cll" else ["list_steps=7"])
        if args.case == "kgc":
            sets = [s for s in sets if not s.startswith("steps")] + ["steps=20", "kgc=true"]
        ranks = [3] if args.case == "kgc" else [2, 3, 4]
        failures, _ = against_serial(args, args.case, sets, ranks)
    elif args.case == "gridders":
        for gridder, order, list_kind in (("A", "hilbert", "vlx"), ("C", "sort_xyz", "vlc"), ("D", "hilbert", "cll")):
            sets = BASE[:1] + ["steps=10", "output_interval=1.0", f"cell_order={order}", f"gridder={gridder}",
                               f"list={list_kind}", "list_steps=7"]
            f, _ = against_serial(args, f"{gridder}_{order}_{list_kind}", sets, [3])
            failures += [f"gridder {gridder} {order} {list_kind}: {m}" for m in f]
    elif args.case == "scenarios":
        p = run(mpirun_command(args.mpirun, 3) + [args.program], expect_rc=None)
        print(p.stdout[-3000:])
        if p.returncode != 0:
            failures.append(f"test_mpi_ranks under mpirun -np 3 exited {p.returncode}:\n{p.stderr[-3000:]}")
    elif args.case == "lonely_rank":
        # By particles the walls outweigh the water: the right-hand ranks own walls only.
        f, summaries = against_serial(args, "lonely", BASE[:1] + ["steps=10", "output_interval=1.0",
                                                                  "balance_by=particles"], [8])
        failures += f
        if summaries[8]["fluid_per_rank"]["min"] != 0:
            failures.append(f"expected a rank without fluid, got fluid_per_rank {summaries[8]['fluid_per_rank']}")
    elif args.case == "pieces":
        failures += pieces_against_gathered(args, 3)
    elif args.case == "bad_ranks":
        # particles=200 with h_coefficient=3: a grid of 27 cells of 2h (the domain has a margin of 2h).
        out = Path(args.work) / "bad_ranks"
        p = sphnl_run(args, out, ["particles=200", "h_coefficient=3", "steps=1"], args.mpirun, 28, expect_rc=2)
        text = p.stderr
        if "every rank must own at least one cell" not in text or "fewer ranks" not in text:
            failures.append(f"no clear error for more ranks than cells; stderr was:\n{text}")
        elif text.count("every rank must own") != 1:
            failures.append(f"the error should be printed once (by rank 0), got:\n{text}")
        else:
            print("  " + text.strip().splitlines()[0])
    else:
        ap.error(f"unknown case {args.case!r}")
    for f in failures:
        print("FAIL: " + f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
