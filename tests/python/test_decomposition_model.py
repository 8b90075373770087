"""harness/decomposition_model.py: the code's decomposition rules on synthetic
weights, the network terms, and (with SPHNL_BUILD_DIR and mpirun) the ghost,
owned and pair counts of a real `mpirun -np 3 sphnl run` reproduced exactly."""
import contextlib
import io
import json
import math
import os
import shutil
import subprocess
import tempfile
import unittest
from pathlib import Path

import numpy as np

from harness import decomposition_model as D


def z_gradient_cloud(n, side, seed):
    """(x, y, z, types) of n fluid points in a side x side x 1 box whose
    density grows linearly with z (the SortX ranges are z-slabs)."""
    rng = np.random.default_rng(seed)
    return side * rng.random(n), side * rng.random(n), np.sqrt(rng.random(n)), np.array(["fluid"] * n)


class Partition(unittest.TestCase):
    def test_hilbert_index_of_the_unit_cube_is_a_path_of_unit_steps(self):
        c = np.arange(8)
        h = D.hilbert_index(c & 1, (c >> 1) & 1, c >> 2, 1)
        self.assertEqual(sorted(h.tolist()), list(range(8)))
        pts = np.stack([c & 1, (c >> 1) & 1, c >> 2], axis=1)[np.argsort(h)]
        self.assertTrue((np.abs(np.diff(pts, axis=0)).sum(axis=1) == 1).all())
        rank = D.hilbert_rank(np.array([4, 4, 4]))
        self.assertEqual(sorted(rank.tolist()), list(range(64)))

    def test_cuts_where_the_running_weight_reaches_each_share(self):
        # KeyPartition::balanced on 8 keys of weight 1: P = 4 -> ranges of 2
        self.assertEqual(list(D.balanced(np.ones(8), 4)), [0, 2, 4, 6, 8])
        # all the weight in one key: every rank still gets a key
        self.assertEqual(list(D.balanced(np.array([0, 0, 5.0, 0, 0]), 3)), [0, 3, 4, 5])
        with self.assertRaisesRegex(D.ModelError, "every rank must own at least one cell"):
            D.balanced(np.ones(2), 3)

    def test_owner_is_the_last_rank_beginning_at_or_before_the_key(self):
        begins = np.array([0, 2, 4, 6, 8])
        self.assertEqual(list(D.owner(begins, np.arange(8))), [0, 0, 1, 1, 2, 2, 3, 3])

    def test_a_slab_of_cells_sends_its_boundary_planes(self):
        # a 4 x 4 x 4 block of particles, one per cell of side 1: two ranks own two
        # z-planes each and receive the other's adjacent plane (16 cells) as ghosts
        g = np.arange(4) + 0.5
        x, y, z = (a.ravel() for a in np.meshgrid(g, g, g, indexing="ij"))
        types = np.array(["fluid"] * x.size)
        h = 1e-9  # no margin: the grid starts at the first particle
        counts = D.decompose(x - 0.5, y - 0.5, z - 0.5, types, h, 1.0, [1, 2])
        self.assertEqual(list(counts[1]["ghosts"]), [0])
        self.assertEqual(list(counts[2]["owned"]), [32, 32])
        self.assertEqual(list(counts[2]["ghosts"]), [16, 16])
        self.assertEqual(list(counts[2]["partners"]), [1, 1])

    def test_pairs_within_a_rank_once_across_ranks_on_both(self):
        # a 4 x 4 x 4 lattice of spacing 1 with 2h = 1.1: face neighbours only,
        # 4 z-planes x 24 in-plane pairs + 3 x 16 between planes = 144. Cells of
        # 2h from x = -2h: planes z = 0, 1 share a cell, so two ranks own
        # z = 0, 1 and z = 2, 3 and the 16 pairs between z = 1 and 2 are on both.
        g = np.arange(4.0)
        x, y, z = (a.ravel() for a in np.meshgrid(g, g, g, indexing="ij"))
        types = np.array(["fluid"] * x.size)
        h = 0.55
        c = D.decompose(x, y, z, types, h, 2 * h, [1, 2])
        self.assertEqual(c[1]["pairs_serial"], 144)
        self.assertEqual(list(c[1]["pairs_own"]), [144])
        self.assertEqual(list(c[2]["owned"]), [32, 32])
        self.assertEqual(list(c[2]["pairs_own"]), [64, 64])
        self.assertEqual(list(c[2]["pairs_cross"]), [16, 16])
        row = D.summary_row(64, 2, c[2])
        self.assertEqual((row["pairs_own"], row["pairs_cross"], row["pairs_all_ranks"]), (64, 16, 160))
        # two boundary particles never form a pair: one fluid particle left, at a corner (3 neighbours)
        types = np.array(["boundary"] * x.size)
        types[0] = "fluid"
        self.assertEqual(D.decompose(x, y, z, types, h, 2 * h, [1])[1]["pairs_serial"], 3)

    def test_ranges_balanced_by_pairs_even_out_a_density_gradient(self):
        # density growing with z (the SortX ranges are z-slabs): equal particle
        # counts give the dense slab more pairs; cutting by pairs moves particles
        # to the sparse slab and evens the pairs out
        n, h = 20000, 0.02
        x, y, z, types = z_gradient_cloud(n, 0.3, seed=1)
        pairs = D.interacting_pairs(x, y, z, types, h)
        busiest = {}
        for balance in D.BALANCES:
            c = D.decompose(x, y, z, types, h, 2 * h, [2], balance=balance, pairs=pairs)[2]
            r = D.summary_row(n, 2, c)
            busiest[balance] = (r["pairs_own"] + r["pairs_cross"]) / (r["pairs_serial"] / 2)
            if balance == "weight":
                self.assertLess(abs(c["owned"][0] - c["owned"][1]), 0.01 * n)
            else:
                self.assertGreater(c["owned"][0], 1.4 * c["owned"][1])   # the sparse, low slab
        self.assertGreater(busiest["weight"], 1.2)
        self.assertLess(busiest["pairs"], 1.1)
        # the code's estimate from cell counts comes close to the pairs counted
        self.assertLess(busiest["interactions"], 1.1)
        with self.assertRaisesRegex(D.ModelError, "balance 'time'"):
            D.decompose(x, y, z, types, h, 2 * h, [2], balance="time", pairs=pairs)


class Terms(unittest.TestCase):
    ROW = {"P": 64, "N": 64000, "pairs_serial": 2_000_000, "owned_max": 1000, "ghosts_max": 500,
           "pairs_own": 30_000, "pairs_cross": 10_000}

    def test_one_rank_is_compute_only(self):
        t = D.step_terms({"P": 1, "N": 1000, "pairs_serial": 20_000, "pairs_own": 20_000, "pairs_cross": 0,
                          "owned_max": 1000, "ghosts_max": 0}, 1e-6)
        self.assertEqual(sum(t.values()), t["compute"])
        self.assertAlmostEqual(t["compute"], 1e-3)  # the serial step

    def test_terms_follow_the_calls_of_the_code(self):
        t = D.step_terms(self.ROW, 1e-6, latency=1e-6, bandwidth=1e9, exchange="alltoall")
        # the serial step (64 ms) times the rank's share of the serial pairs, its cross pairs included
        self.assertAlmostEqual(t["compute"], 64e-3 * 40_000 / 2_000_000)
        # 2 exchanges x (alltoall of the counts + alltoallv): P - 1 messages each, 4 B a count
        self.assertAlmostEqual(t["exchange_latency"], 2 * (2 * 63 * 1e-6 + 4 * 63 / 1e9))
        # as the code exchanges: the migration all-to-all, the ghosts a count and a data message per partner
        code = D.step_terms({**self.ROW, "partners_max": 2}, 1e-6, latency=1e-6, bandwidth=1e9)
        self.assertAlmostEqual(code["exchange_latency"], 2 * 63 * 1e-6 + 4 * 63 / 1e9 + 2 * 2 * 1e-6)
        with self.assertRaisesRegex(D.ModelError, "exchange 'mpi'"):
            D.step_terms(self.ROW, 1e-6, exchange="mpi")
        self.assertAlmostEqual(t["exchange_bytes"], 500 * 80 / 1e9)
        self.assertAlmostEqual(t["rank_vector_sum"], 6e-6 + 63 * 8 * 64 / 1e9)
        nb = D.step_terms({**self.ROW, "partners_max": 2}, 1e-6, latency=1e-6, bandwidth=1e9, exchange="neighbour")
        self.assertAlmostEqual(nb["exchange_latency"], 2 * 2 * 1e-6)  # 2 exchanges of 2 messages
        vl = D.step_terms(self.ROW, 1e-6, "vlx", latency=1e-6, bandwidth=1e9)
        self.assertEqual(vl["rank_vector_sum"], 0)
        self.assertAlmostEqual(vl["exchange_bytes"], 500 * 56 / 1e9)

    def test_extrapolation_in_n_by_similar_ranges_or_the_surface_rule(self):
        def row(n, owned, ghosts):
            return {"N": n, "P": 4, "owned_max": owned, "ghosts_max": ghosts, "ghost_bytes_build_max": 80 * ghosts,
                    "pairs_own": 20.0 * owned, "pairs_cross": 10.0 * ghosts, "pairs_serial": 80.0 * owned}
        rows = [row(1000, 250, 100), row(8000, 2000, 400)]
        self.assertAlmostEqual(D.fit_exponent(rows, "ghosts_max", 4), 2 / 3)
        # P' = 4 x (8000 / 64000) < 2 for Hilbert: the thin-surface rule, ghosts ∝ N^(2/3) at P = 4
        e = D.extrapolate(rows, 64000, 4, "hilbert")
        self.assertTrue(e["extrapolated"])
        self.assertAlmostEqual(e["ghosts_max"], 1600)
        self.assertAlmostEqual(e["owned_max"], 16000)
        # the rank's share of the serial pairs (40 000 + 4 000 / 2) grows 8x, its
        # duplicated half of the cross pairs (2 000) 4x
        self.assertAlmostEqual(e["pairs_cross"], 16000)
        self.assertAlmostEqual(e["pairs_own"], 42000 * 8 - 2000 * 4)
        # the busiest rank after scaling can be another than the busiest counted
        b = dict(row(8000, 2000, 400), pairs_own=40000, pairs_cross=4000,
                 pairs_frontier=[[43000.0, 500.0], [42000.0, 2000.0]])   # the first is busier at 8 000
        e = D.extrapolate([b], 8000 * 1000, 4, "hilbert")
        self.assertAlmostEqual(e["pairs_cross"], 2 * 500 * 100)   # g = 1000^(2/3) = 100
        self.assertAlmostEqual(e["pairs_own"] + e["pairs_cross"], 43000 * 1000 + 500 * 100)
        # similar ranges: P = 64 at 8 x the particles has the shape of P' = 8 at 8 000 (Hilbert: C ∝ N / P)
        rows += [dict(row(8000, 1000, 300), P=8), dict(row(8000, 500, 250), P=16)]
        for r in rows[2:]:
            r["pairs_serial"] = 80.0 * 2000
        e = D.extrapolate(rows, 64000, 64, "hilbert")
        self.assertAlmostEqual(e["similar_p"], 8)
        share = 64000 / 64
        self.assertAlmostEqual(e["ghosts_max"], 300 / (8000 / 8) * share)
        # cross pairs in units of the mean share of the serial pairs, as at P' = 8
        self.assertAlmostEqual(e["pairs_cross"] / (80.0 * 2000 * 8 / 64), 3000 / (80.0 * 2000 / 8))
        proj = D.project(rows[:2], [8000, 64000], [4], 1e-6)
        self.assertEqual([p["extrapolated"] for p in proj], [False, True])
        self.assertTrue(all(0 < p["efficiency"] < 1 for p in proj))


class Projection(unittest.TestCase):
    def test_projection_from_stored_counts_both_balances_deterministic(self):
        from plots import mpi_projection
        n, h = 6000, 0.03
        x, y, z, types = z_gradient_cloud(n, 0.4, seed=2)
        pairs = D.interacting_pairs(x, y, z, types, h)
        rows = [dict(D.summary_row(n, p, c), order=order, balance=balance)
                for order in mpi_projection.ORDERS for balance in D.BALANCES
                for p, c in D.decompose(x, y, z, types, h, 2 * h, [1, 2, 4], order=order, balance=balance,
                                        pairs=pairs).items()]
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp)
            (out / "decomposition_counts.json").write_text(json.dumps({"rows": rows}), encoding="utf-8")
            args = ["--out", tmp, "--s-per-particle-step", "2e-6", "--ranks", "1,2,4", "--targets", "1e5"]
            svgs = []
            for _ in range(2):
                with contextlib.redirect_stdout(io.StringIO()):
                    self.assertEqual(mpi_projection.main(args), 0)
                svgs.append((out / "decomposition_model.svg").read_bytes())
            self.assertEqual(svgs[0], svgs[1])
            md = (out / "projection.md").read_text(encoding="utf-8")
            self.assertIn("| efficiency, ranges by particle weights | efficiency, ranges balanced by pairs |", md)
            proj = json.loads((out / "projection.json").read_text(encoding="utf-8"))["rows"]
            self.assertLessEqual({("sort_x", 100000), ("hilbert", n)}, {(r["order"], r["N"]) for r in proj})
            for r in proj:
                self.assertLessEqual(r["efficiency"], 1.0 + 1e-12)
                self.assertLessEqual(r["efficiency_pair_balance"], 1.0 + 1e-12)
            # the density gradient along z: SortX slabs balanced by pairs, or by the code's
            # estimate of them, are faster at P = 2 than slabs of equal particle weight
            at = {(r["order"], r["N"], r["P"]): r for r in proj}
            self.assertGreater(at[("sort_x", n, 2)]["efficiency_pair_balance"],
                               at[("sort_x", n, 2)]["efficiency_weight_balance"])
            self.assertGreater(at[("sort_x", n, 2)]["efficiency"], at[("sort_x", n, 2)]["efficiency_weight_balance"])


@unittest.skipUnless(os.environ.get("SPHNL_BUILD_DIR") and shutil.which("mpirun"),
                     "needs SPHNL_BUILD_DIR (make test sets it) and mpirun")
class AgainstTheCode(unittest.TestCase):
    def test_counts_of_three_real_ranks(self):
        import pandas as pd
        sphnl = str(Path(os.environ["SPHNL_BUILD_DIR"]) / "sphnl")
        cmd = ["mpirun", "-np", "3", "--oversubscribe"] + (["--allow-run-as-root"] if os.getuid() == 0 else [])
        env = {**os.environ, "OMPI_MCA_btl_vader_single_copy_mechanism": "none"}
        for order, balance_by, balance in (("sort_x", "interactions", "interactions"),
                                           ("hilbert", "interactions", "interactions"),
                                           ("sort_x", "particles", "weight"), ("hilbert", "particles", "weight")):
            with self.subTest(order=order, balance_by=balance_by), tempfile.TemporaryDirectory() as tmp:
                # one CLL step from t = 0: the ghosts of its build are those of the t = 0 distribution
                r = subprocess.run(cmd + [sphnl, "run", "--quiet", "--out", tmp, "--set", "particles=3000",
                                          "--set", "steps=1", "--set", "output_interval=1", "--set", "progress=false",
                                          "--set", f"cell_order={order}", "--set", f"balance_by={balance_by}"],
                                   capture_output=True, text=True, env=env, timeout=120)
                self.assertEqual(r.returncode, 0, r.stderr)
                s = json.loads((Path(tmp) / "summary.json").read_text())
                df = pd.read_csv(Path(tmp) / s["snapshots"][0]["csv"])
                c = D.decompose(df["x"].to_numpy(), df["y"].to_numpy(), df["z"].to_numpy(), df["type"].to_numpy(),
                                s["h"], 2 * s["h"], [3], order=order, balance=balance)[3]
                self.assertEqual({"min": int(c["ghosts"].min()), "max": int(c["ghosts"].max())}, s["ghosts_per_rank"])
                self.assertEqual({"min": int(c["owned"].min()), "max": int(c["owned"].max())}, s["particles_per_rank"])
                # nothing migrates at t = 0: the bytes of the step are the ghosts' 10 doubles each
                self.assertEqual(s["bytes_sent_per_step"], c["ghosts"].sum() * D.GHOST_DOUBLES * 8)
                # the pairs the three ranks evaluated in their one step, summed: own pairs once,
                # pairs across a range boundary on both ranks, no pair of two ghosts
                self.assertEqual((c["pairs_own"] + c["pairs_cross"]).sum(), s["neighbour_stats"]["interactions"])
                serial = subprocess.run([sphnl, "run", "--quiet", "--out", f"{tmp}/serial", "--set", "particles=3000",
                                         "--set", "steps=1", "--set", "output_interval=0", "--set", "progress=false",
                                         "--set", f"cell_order={order}"],
                                        capture_output=True, text=True, timeout=120)
                self.assertEqual(serial.returncode, 0, serial.stderr)
                s1 = json.loads((Path(tmp) / "serial" / "summary.json").read_text())
                self.assertEqual(c["pairs_serial"], s1["neighbour_stats"]["interactions"])

if __name__ == "__main__":
    unittest.main()
