"""A model of the distributed runs without processes (docs/FINDINGS.md,
"Distributed runs: a projection"): the decomposition of the real particle
distribution of the dam break along the SortX or Hilbert cell order, as
core/src/parallel/decomposition.cpp cuts it, and a network model of the
step's communication built from the calls the code makes.

Decomposition (the code's rules, checked against `mpirun sphnl run` in
tests/python/test_decomposition_model.py):
  cells of side `cell` (2h for CLL) over the case's domain; keys along SortX
  (eq. 8: cz ncx ncy + cy ncx + cx) or Hilbert (every cell ranked by its
  index on the padded cube, core/src/orderings/hilbert.cpp); weights per key
  the code's `balance_by`: "interactions" (the default; interaction_weights,
  f (F + B) + b F of a cell's fluid f and boundary b particles and those of
  its 27 cells F, B) or "weight" (`balance_by=particles`: fluid 1, boundary
  1/4 per particle); rank r's range ends after the first key where the running weight
  reaches total r / P (KeyPartition::balanced); a cell's particles are a
  ghost on every other rank owning one of its 26 neighbour cells
  (Decomposition::ghost_destinations).

Work: the pairs a rank evaluates (core/include/sphnl/neighbours/pair_operation.hpp:
r < 2h, not boundary-boundary), counted from the particles. A rank
evaluates every pair of two of its own particles once and every pair of
one of its own with a ghost once (the other rank evaluates it too); pairs
of two ghosts are skipped. The busiest rank is the one with the most
pairs, and its compute is the serial step's time in proportion: serial
seconds x (its pairs) / (the serial run's pairs).

Communication per step, one term per call of the code (core/mpi/ranks_mpi.cpp:
`exchange` is MPI_Alltoall of the counts + MPI_Alltoallv, `exchange_with`
point-to-point messages with the partner ranks; `sum` is an MPI_Allgather,
summed in rank order; `max` an MPI_Allreduce):
  CLL (a build every step): the rebalance check sums a P-vector, then two
  exchanges (migration, all-to-all; ghosts, with the partners: 10 doubles
  per ghost), max of 3 values
  (dt, eq. 7), max (V_max) and sum (lost) in the update;
  VL_X between builds: one max (the rebuild vote), one exchange with the
  partners (ghost refresh: 7 doubles per ghost), the same three reductions.
The network: a message of b bytes costs `latency` + b / `bandwidth`; an
all-to-all (pairwise, as OpenMPI's for these sizes) costs P - 1 messages on
every rank; an allreduce or allgather of b bytes per rank log2(P) latencies
and (P - 1) b / bandwidth (recursive doubling / ring).
"""
import math

import numpy as np

FLUID, BOUNDARY = "fluid", "boundary"
WEIGHT = {FLUID: 1.0, BOUNDARY: 0.25}  # DomainExchange::weight
GHOST_DOUBLES, REFRESH_DOUBLES = 10, 7  # pack_ghost, refresh_ghosts (domain_exchange.cpp)
# Network defaults (parameters of `project`): an InfiniBand EDR/HDR-class
# cluster interconnect, one MPI message's latency and a node's bandwidth.
LATENCY_S = 1.5e-6
BANDWIDTH_BPS = 10e9
TANK_HEIGHT = 0.75  # the domain's room above the walls for splashes (core/src/case.cpp)


class ModelError(Exception):
    """The model cannot be made from these inputs; the message says why."""


def grid_of(x, y, z, h, cell):
    """(lo, n) of the case's CellGrid: every particle plus 2h (core/src/case.cpp),
    the top raised by the tank height, cells of side `cell` (ceil per axis)."""
    pos = (x, y, z)
    lo = np.array([p.min() - 2 * h for p in pos])
    hi = np.array([p.max() + 2 * h for p in pos])
    hi[2] += TANK_HEIGHT
    n = np.maximum(1, np.ceil((hi - lo) * (1.0 / cell)).astype(np.int64))
    return lo, n


def sort_x_keys(x, y, z, lo, n, cell):
    """SortX keys (eq. 8) of the particles, cell coordinates clamped into the grid as CellGrid::coord."""
    inv = 1.0 / cell
    c = [np.clip(((p - lo[d]) * inv).astype(np.int64), 0, n[d] - 1) for d, p in enumerate((x, y, z))]
    return c[2] * n[0] * n[1] + c[1] * n[0] + c[0]


def bits_for(n):
    """morton::bits_for: the bits of the padded cube's side."""
    b = 0
    while (1 << b) < n:
        b += 1
    return b


def hilbert_index(x, y, z, bits):
    """hilbert::index (core/src/orderings/hilbert.cpp, Skilling's transpose
    algorithm), element-wise on arrays of cell coordinates."""
    X = [np.asarray(v, dtype=np.uint64).copy() for v in (x, y, z)]
    M = 1 << (bits - 1)
    Q = M
    while Q > 1:
        P = Q - 1
        for i in range(3):
            hit = (X[i] & Q) != 0
            t = (X[0] ^ X[i]) & P
            X[0] = np.where(hit, X[0] ^ P, X[0] ^ t)
            if i:
                X[i] = np.where(hit, X[i], X[i] ^ t)
        Q >>= 1
    for i in (1, 2):
        X[i] ^= X[i - 1]
    t = np.zeros_like(X[2])
    Q = M
    while Q > 1:
        t = np.where((X[2] & Q) != 0, t ^ (Q - 1), t)
        Q >>= 1
    for i in range(3):
        X[i] ^= t
    h = np.zeros_like(X[0])
    for q in range(bits - 1, -1, -1):
        for i in range(3):
            h = (h << np.uint64(1)) | ((X[i] >> np.uint64(q)) & np.uint64(1))
    return h


def hilbert_rank(n):
    """Hilbert::prepare: every real cell's rank along the curve, indexed by its SortX key."""
    bits = max(1, bits_for(int(n[0])), bits_for(int(n[1])), bits_for(int(n[2])))
    c = np.arange(int(n[0] * n[1] * n[2]), dtype=np.int64)
    cz, rem = np.divmod(c, n[0] * n[1])
    cy, cx = np.divmod(rem, n[0])
    order = np.argsort(hilbert_index(cx, cy, cz, bits), kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return rank


def balanced(weights, ranks):
    """KeyPartition::balanced: begins[0..P] (begins[P] = number of keys)."""
    nkeys = len(weights)
    if ranks > nkeys:
        raise ModelError(f"{ranks} ranks for {nkeys} cells: every rank must own at least one cell")
    running = np.cumsum(weights)
    total = float(running[-1]) if nkeys else 0.0
    begins = np.full(ranks + 1, nkeys, dtype=np.int64)
    begins[0] = 0
    for r in range(1, ranks):
        i = int(np.searchsorted(running, total * r / ranks, side="left"))
        if i < nkeys:
            begins[r] = i + 1
    for q in range(1, ranks):
        begins[q] = max(begins[q], begins[q - 1] + 1)
    for q in range(ranks - 1, 0, -1):
        begins[q] = min(begins[q], nkeys - (ranks - q))
    return begins


def owner(begins, keys):
    """KeyPartition::owner: the last rank whose range begins at or before the key."""
    return np.searchsorted(begins[:-1], keys, side="right") - 1


def interacting_pairs(x, y, z, types, h):
    """(m, 2) indices of every pair the serial pair pass evaluates: 0 < r < 2h
    (r^2 > 1e-18) and not two boundary particles."""
    from scipy.spatial import cKDTree
    pts = np.column_stack((x, y, z))
    ij = cKDTree(pts).query_pairs(2 * h, output_type="ndarray")
    d2 = ((pts[ij[:, 0]] - pts[ij[:, 1]]) ** 2).sum(axis=1)
    fluid = np.asarray(types) == FLUID
    keep = (d2 < (2 * h) ** 2) & (d2 > 1e-18) & (fluid[ij[:, 0]] | fluid[ij[:, 1]])
    return ij[keep]


BALANCES = ("interactions", "weight", "pairs")


def interaction_weights(sortx, types, n):
    """interaction_weights (core/src/parallel/decomposition.cpp) of every
    SortX key: a cell's fluid f and boundary b particles against those of its
    27 cells (itself included) F, B: f (F + B) + b F. No periodic seam (the
    dam break has none)."""
    nkeys = int(n[0] * n[1] * n[2])
    shape = (int(n[2]), int(n[1]), int(n[0]))  # SortX: x fastest
    f = np.bincount(sortx[types == FLUID], minlength=nkeys).astype(float).reshape(shape)
    b = np.bincount(sortx[types == BOUNDARY], minlength=nkeys).astype(float).reshape(shape)

    def stencil(a):
        p = np.pad(a, 1)
        return sum(p[1 + dz:1 + dz + shape[0], 1 + dy:1 + dy + shape[1], 1 + dx:1 + dx + shape[2]]
                   for dz in (-1, 0, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    F, B = stencil(f), stencil(b)
    return (f * (F + B) + b * F).ravel()


def decompose(x, y, z, types, h, cell, ranks_list, order="sort_x", balance="interactions", pairs=None):
    """{P: counts} of the dam break's particles cut into P ranks along the
    cell order `order` (sort_x or hilbert): owned particles and weights,
    ghosts received and the ranks they come from, and the pairs each rank
    evaluates (`pairs_own`: both particles its own; `pairs_cross`: one its
    own, one a ghost). `balance`: the ranges cut as the code cuts them, by
    estimated candidate pairs per cell ("interactions", the default) or by
    particle weights (fluid 1, boundary 1/4: "weight", `balance_by=particles`),
    or, a what-if, by each particle's share of the serial pairs counted (half
    its pairs: "pairs"). `pairs`: interacting_pairs of these particles, if made."""
    if order not in ("sort_x", "hilbert"):
        raise ModelError(f"cell order {order!r}: the model has sort_x and hilbert")
    if balance not in BALANCES:
        raise ModelError(f"balance {balance!r}: the model has {', '.join(BALANCES)}")
    lo, n = grid_of(x, y, z, h, cell)
    sortx = sort_x_keys(x, y, z, lo, n, cell)
    to_key = hilbert_rank(n) if order == "hilbert" else None

    def key_of(k):  # SortX key -> the order's key
        return k if to_key is None else to_key[k]
    keys = key_of(sortx)
    nkeys = int(n[0] * n[1] * n[2])
    ij = interacting_pairs(x, y, z, types, h) if pairs is None else pairs
    if balance == "interactions":
        weights = np.zeros(nkeys)
        weights[key_of(np.arange(nkeys))] = interaction_weights(sortx, types, n)
    else:
        if balance == "weight":
            w = np.where(types == FLUID, WEIGHT[FLUID], WEIGHT[BOUNDARY])
        else:
            w = 0.5 * np.bincount(ij.ravel(), minlength=len(keys))
        weights = np.bincount(keys, weights=w, minlength=nkeys)
    cells_x, per_cell = np.unique(sortx, return_counts=True)  # occupied cells, by SortX key
    cells = key_of(cells_x)
    cz, rem = np.divmod(cells_x, n[0] * n[1])
    cy, cx = np.divmod(rem, n[0])
    # the interacting pairs as counts per pair of occupied cells (index into cells_x)
    cell_of = np.searchsorted(cells_x, sortx)
    ca, cb = cell_of[ij[:, 0]], cell_of[ij[:, 1]]
    lo_c, hi_c = np.minimum(ca, cb), np.maximum(ca, cb)
    cell_pairs, pair_counts = np.unique(lo_c * len(cells_x) + hi_c, return_counts=True)
    pa, pb = np.divmod(cell_pairs, len(cells_x))
    out = {}
    for ranks in ranks_list:
        if ranks > nkeys:
            continue
        begins = balanced(weights, ranks)
        home = owner(begins, cells)
        pairs = []  # (cell index, destination rank) of every ghost copy
        for dz in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    if dx == dy == dz == 0:
                        continue
                    nx, ny, nz = cx + dx, cy + dy, cz + dz
                    ok = (nx >= 0) & (nx < n[0]) & (ny >= 0) & (ny < n[1]) & (nz >= 0) & (nz < n[2])
                    idx = np.nonzero(ok)[0]
                    r = owner(begins, key_of(nz[idx] * n[0] * n[1] + ny[idx] * n[0] + nx[idx]))
                    far = r != home[idx]
                    pairs.append(idx[far] * (ranks + 1) + r[far])
        pairs = np.unique(np.concatenate(pairs)) if pairs else np.array([], dtype=np.int64)
        cell_idx, dest = np.divmod(pairs, ranks + 1)
        ghosts = np.bincount(dest, weights=per_cell[cell_idx], minlength=ranks).astype(np.int64)
        src = home[cell_idx]
        links = np.unique(dest * ranks + src)
        partners = np.bincount(links // ranks, minlength=ranks)
        owned = np.bincount(home, weights=per_cell, minlength=ranks).astype(np.int64)
        rank_w = np.bincount(home, weights=weights[cells], minlength=ranks)
        ghost_w = np.bincount(dest, weights=weights[cells][cell_idx], minlength=ranks)
        ra, rb = home[pa], home[pb]
        same = ra == rb
        pairs_own = np.bincount(ra[same], weights=pair_counts[same], minlength=ranks).astype(np.int64)
        cross = ~same
        pairs_cross = (np.bincount(ra[cross], weights=pair_counts[cross], minlength=ranks)
                       + np.bincount(rb[cross], weights=pair_counts[cross], minlength=ranks)).astype(np.int64)
        out[ranks] = {"owned": owned, "ghosts": ghosts, "partners": partners, "weight": rank_w,
                      "ghost_weight": ghost_w, "cells": nkeys, "occupied_cells": len(cells),
                      "pairs_own": pairs_own, "pairs_cross": pairs_cross, "pairs_serial": int(len(ij))}
    return out


def pareto_frontier(share, duplicated):
    """[[share, duplicated]] of the ranks no other rank exceeds in both: the
    busiest rank after scaling the two by any positive factors is one of
    them (the surface rule of `extrapolate`)."""
    out = []
    for a, b in sorted(zip(share.tolist(), duplicated.tolist()), key=lambda t: (-t[0], -t[1])):
        if not out or b > out[-1][1]:
            out.append([float(a), float(b)])
    return out


def summary_row(n_particles, ranks, c):
    """The counts of one (N, P) as the numbers the projection needs."""
    owned, ghosts, w = c["owned"], c["ghosts"], c["weight"]
    pairs = c["pairs_own"] + c["pairs_cross"]
    busiest = int(np.argmax(pairs))
    return {"pairs_own": int(c["pairs_own"][busiest]), "pairs_cross": int(c["pairs_cross"][busiest]),
            # per rank: its share of the serial pairs (own + cross / 2) and the
            # duplicated half of its cross pairs, on the frontier
            "pairs_frontier": pareto_frontier(c["pairs_own"] + c["pairs_cross"] / 2, c["pairs_cross"] / 2),
            "pairs_serial": int(c["pairs_serial"]), "pairs_all_ranks": int(pairs.sum()),
            "total_weight": float(w.sum()), "N": int(n_particles), "P": int(ranks),
            "owned_max": int(owned.max()), "owned_min": int(owned.min()),
            "ghosts_max": int(ghosts.max()), "ghosts_mean": float(ghosts.mean()),
            "ghosts_total": int(ghosts.sum()), "partners_max": int(c["partners"].max()),
            "imbalance": float(w.max() / w.mean() - 1.0) if w.mean() > 0 else 0.0,
            "ghost_bytes_build_max": int(ghosts.max()) * GHOST_DOUBLES * 8,
            "cells": int(c["cells"]), "occupied_cells": int(c["occupied_cells"])}


# ------------------------------------------------------------------ scaling N
def fit_exponent(rows, key, ranks):
    """alpha of key ∝ N^alpha at P = ranks, from the two largest N measured."""
    pts = sorted((r["N"], r[key]) for r in rows if r["P"] == ranks and r[key] > 0)
    if len(pts) < 2:
        return None
    (n0, v0), (n1, v1) = pts[-2], pts[-1]
    return math.log(v1 / v0) / math.log(n1 / n0)


GHOST_EXPONENT = 2.0 / 3.0
# The similarity variable of each order's ranges, as a power of N at fixed
# cells per particle (cells ∝ N): a Hilbert range is a compact blob whose
# shape depends on its cells, C ∝ N / P; a SortX range is a part of a stack
# of z-planes of cells, whose shape depends on the ranks per plane ∝ P / N^(1/3).
SIMILAR_P_EXPONENT = {"hilbert": 1.0, "sort_x": 1.0 / 3.0}


def _ratios(row):
    """The busiest rank's pairs and counts in units of the mean share (scale-free)."""
    share_pairs, share_n = row["pairs_serial"] / row["P"], row["N"] / row["P"]
    return {"pairs_own": row["pairs_own"] / share_pairs, "pairs_cross": row["pairs_cross"] / share_pairs,
            "owned_max": row["owned_max"] / share_n, "ghosts_max": row["ghosts_max"] / share_n}


def extrapolate(rows, n_target, ranks, order="sort_x"):
    """Counts at N = n_target, P = ranks: measured if there, else scaled from
    the largest N counted (N0) by one of two documented rules.
    Similar ranges: refining the case at fixed geometry (h ∝ dx, N ∝ dx^-3)
    with P' = P (N0 / N)^k ranks at N0 (k = SIMILAR_P_EXPONENT of the order)
    gives ranges of the same shape in cells, so the busiest rank's own and
    cross pairs and its counts in units of the mean share are those counted
    at (N0, P'), interpolated in log P' between the counted P. Where P' < 2
    (ranks hold more cells than the counted case has), ranks are in the
    thin-surface regime and the fixed-P rule applies, from the largest N
    counted at that P: owned particles and a rank's share of the serial
    pairs (own + cross / 2) ∝ N, ghosts and cross pairs ∝ N^(2/3) (a layer
    of cells one cell thick), so the serial pairs scale as N and no rank's
    pairs fall below the mean share. The partners are those counted at the
    nearest P'."""
    here = [r for r in rows if r["P"] == ranks]
    exact = [r for r in here if r["N"] == n_target]
    if exact:
        return dict(exact[0], extrapolated=False)
    if not rows:
        return None
    n0 = max(r["N"] for r in rows)
    base = sorted((r for r in rows if r["N"] == n0), key=lambda r: r["P"])
    p_sim = ranks * (n0 / n_target) ** SIMILAR_P_EXPONENT[order]
    pairs_serial = base[0]["pairs_serial"] * n_target / n0
    if p_sim >= 2 and p_sim <= base[-1]["P"]:
        ps = np.log([r["P"] for r in base])
        rat = {k: float(np.interp(math.log(p_sim), ps, [_ratios(r)[k] for r in base]))
               for k in ("pairs_own", "pairs_cross", "owned_max", "ghosts_max")}
        near = min(base, key=lambda r: abs(math.log(r["P"] / p_sim)))
        share_pairs, share_n = pairs_serial / ranks, n_target / ranks
        g = rat["ghosts_max"] * share_n
        return {**near, "N": int(n_target), "P": ranks, "pairs_serial": pairs_serial,
                "pairs_own": rat["pairs_own"] * share_pairs, "pairs_cross": rat["pairs_cross"] * share_pairs,
                "owned_max": rat["owned_max"] * share_n, "ghosts_max": g, "ghost_bytes_build_max": g * GHOST_DOUBLES * 8,
                "similar_p": p_sim, "extrapolated": True}
    if not here:
        return None
    b = max(here, key=lambda r: r["N"])
    s = n_target / b["N"]
    g = s ** GHOST_EXPONENT
    # A rank's share of the serial pairs (own + cross / 2) grows as s, the
    # duplicated half of its cross pairs as g (so the serial pairs grow as
    # s); the busiest rank at n_target is one of the frontier's.
    frontier = b.get("pairs_frontier") or [[b["pairs_own"] + b["pairs_cross"] / 2, b["pairs_cross"] / 2]]
    share, dup = max(frontier, key=lambda sd: sd[0] * s + sd[1] * g)
    return {**b, "N": int(n_target), "owned_max": b["owned_max"] * s, "ghosts_max": b["ghosts_max"] * g,
            "pairs_own": share * s - dup * g, "pairs_cross": 2 * dup * g,
            "pairs_serial": b["pairs_serial"] * s,
            "ghost_bytes_build_max": b["ghosts_max"] * g * GHOST_DOUBLES * 8, "similar_p": p_sim, "extrapolated": True}


# ------------------------------------------------------------------ the step
def message_s(nbytes, latency, bandwidth):
    return latency + nbytes / bandwidth


def alltoall_s(ranks, nbytes_total, latency, bandwidth):
    """An exchange: MPI_Alltoall of one int per rank, then MPI_Alltoallv of
    `nbytes_total` leaving this rank; both pairwise: P - 1 messages each."""
    if ranks == 1:
        return 0.0
    return 2 * (ranks - 1) * latency + (4 * (ranks - 1) + nbytes_total) / bandwidth


def allreduce_s(ranks, nbytes, latency, bandwidth):
    return 0.0 if ranks == 1 else math.log2(ranks) * latency + 2 * nbytes / bandwidth


def allgather_s(ranks, nbytes_each, latency, bandwidth):
    return 0.0 if ranks == 1 else math.ceil(math.log2(ranks)) * latency + (ranks - 1) * nbytes_each / bandwidth


def step_terms(row, s_per_particle_step, lst="cll", latency=LATENCY_S, bandwidth=BANDWIDTH_BPS,
               exchange="code"):
    """Seconds per step of the busiest rank, by term. Compute: the measured
    serial step (s_per_particle_step x N) times the rank's share of the
    serial run's pairs: its own pairs plus the pairs with a ghost, which
    both ranks evaluate (pairs of two ghosts are skipped, docs/DESIGN.md).
    The per-particle parts of the step (integration, the cell sort) are
    spread in the same proportion: an approximation that holds while the
    pair pass dominates the step.
    exchange: "code", as the code exchanges (core/mpi/ranks_mpi.cpp): the
    migration an all-to-all (MPI_Alltoall of the counts + MPI_Alltoallv: P - 1
    messages), the ghosts and their refreshes point to point with the
    `partners_max` ranks that share a ghost layer, a count and a data message
    each; "alltoall": every exchange an all-to-all (the code before its
    neighbour exchange); "neighbour": every exchange, migration included,
    with the partners only and one message each (as MPI_Neighbor_alltoallv
    with the counts known from the send lists)."""
    if exchange not in ("code", "alltoall", "neighbour"):
        raise ModelError(f"exchange {exchange!r}: the model has code, alltoall and neighbour")
    p = row["P"]
    per_pair = s_per_particle_step * row["N"] / row["pairs_serial"]
    terms = {"compute": per_pair * (row["pairs_own"] + (row["pairs_cross"] if p > 1 else 0))}
    if p == 1:
        return {**terms, "exchange_latency": 0.0, "exchange_bytes": 0.0, "reductions": 0.0, "rank_vector_sum": 0.0}
    doubles = GHOST_DOUBLES if lst == "cll" else REFRESH_DOUBLES
    exchanges = 2 if lst == "cll" else 1  # CLL: migration + ghosts; VL_X between builds: the refresh
    ghost_bytes = row["ghosts_max"] * doubles * 8
    partners = row.get("partners_max", p - 1)
    if exchange == "neighbour":
        terms["exchange_latency"] = exchanges * partners * latency
    elif exchange == "alltoall":
        terms["exchange_latency"] = exchanges * alltoall_s(p, 0, latency, bandwidth)
    else:  # the migration (CLL) all-to-all, the ghosts (or refresh) 2 messages per partner
        terms["exchange_latency"] = (exchanges - 1) * alltoall_s(p, 0, latency, bandwidth) + 2 * partners * latency
    terms["exchange_bytes"] = ghost_bytes / bandwidth
    red = allreduce_s(p, 24, latency, bandwidth) + allreduce_s(p, 8, latency, bandwidth) \
        + allgather_s(p, 8, latency, bandwidth) + (allreduce_s(p, 8, latency, bandwidth) if lst != "cll" else 0)
    terms["reductions"] = red
    # the rebalance check of every CLL build: a P-vector summed in rank order (an allgather of P doubles)
    terms["rank_vector_sum"] = allgather_s(p, 8 * p, latency, bandwidth) if lst == "cll" else 0.0
    return terms


def project(rows, n_list, ranks_list, s_per_particle_step, lst="cll", latency=LATENCY_S,
            bandwidth=BANDWIDTH_BPS, exchange="code", order="sort_x"):
    """[{N, P, terms..., step_s, efficiency, extrapolated}] of every (N, P)
    the counts reach (measured or extrapolated in N)."""
    out = []
    for n in n_list:
        serial = s_per_particle_step * n
        for p in ranks_list:
            row = extrapolate(rows, n, p, order)
            if row is None:
                continue
            terms = step_terms(row, s_per_particle_step, lst, latency, bandwidth, exchange)
            step = sum(terms.values())
            comm = step - terms["compute"]
            out.append({"N": n, "P": p, **terms, "step_s": step, "communication_share": comm / step,
                        "efficiency": serial / (p * step), "ghosts_max": row["ghosts_max"],
                        "owned_max": row["owned_max"], "extrapolated": row.get("extrapolated", False)})
    return out
