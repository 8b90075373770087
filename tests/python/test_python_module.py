"""The pybind11 module `sphnl` (build/python/sphnl*.so) against a brute-force
answer (scipy's cKDTree, itself checked against numpy on a small cloud):
row i = the neighbours of point i strictly closer than radius, sorted, in
input order; half lists; float32 and float64; non-contiguous input; every
bad input raises ValueError naming the problem. The module is found in
$SPHNL_BUILD_DIR/python (set by `make test`) or build/python; the tests are
skipped, saying so, when it was not built (pybind11 missing)."""
import importlib
import os
import sys
import unittest
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[2]
MODULE_DIR = Path(os.environ.get("SPHNL_BUILD_DIR", ROOT / "build")) / "python"


def load_module():
    if not list(MODULE_DIR.glob("sphnl*.so")):
        return None
    sys.path.insert(0, str(MODULE_DIR))
    try:
        return importlib.import_module("sphnl")
    finally:
        sys.path.remove(str(MODULE_DIR))


sphnl = load_module()
SKIP = f"sphnl Python module not built in {MODULE_DIR} (install pybind11-dev python3-pybind11, then make build)"


def brute_rows(points, radius, half=False):
    """Sorted neighbour rows, strict r < radius, from cKDTree plus an exact
    re-test (query_ball_point includes r == radius)."""
    tree = cKDTree(points)
    rows = []
    for i, cand in enumerate(tree.query_ball_point(points, radius * (1 + 1e-9))):
        cand = np.array(sorted(j for j in cand if j != i and (not half or j > i)), dtype=np.int64)
        if len(cand):
            d2 = ((points[cand] - points[i]) ** 2).sum(axis=1)
            cand = cand[d2 < radius * radius]
        rows.append(cand)
    return rows


def rows_of(offsets, indices):
    return [indices[offsets[i]:offsets[i + 1]].astype(np.int64) for i in range(len(offsets) - 1)]


def clouds():
    rng = np.random.default_rng(5)
    uniform = rng.uniform(-1, 2, size=(1500, 3))
    centres = np.array([[0, 0, 0], [1, 1, 0], [0, 1, 1]])
    clustered = centres[np.arange(1500) % 3] + rng.normal(0, 0.1, size=(1500, 3))
    planar = np.column_stack([rng.uniform(0, 3, 1500), rng.uniform(0, 3, 1500), np.full(1500, 0.5)])
    g = np.arange(10) * 0.5
    lattice = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)  # pairs at exactly r = R
    return [("uniform", uniform, 0.25), ("clustered", clustered, 0.05), ("planar", planar, 0.2), ("lattice", lattice, 1.0)]


@unittest.skipIf(sphnl is None, SKIP)
class PythonModuleTest(unittest.TestCase):
    def assert_rows(self, got, want, what):
        self.assertEqual(len(got), len(want), what)
        for i, (g, w) in enumerate(zip(got, want)):
            np.testing.assert_array_equal(g, w, err_msg=f"{what}: row {i}")

    def test_brute_force_reference_is_right(self):
        pts = np.random.default_rng(1).uniform(0, 1, size=(200, 3))
        d2 = ((pts[:, None, :] - pts[None, :, :]) ** 2).sum(axis=2)
        want = [np.array([j for j in range(200) if j != i and d2[i, j] < 0.04], dtype=np.int64) for i in range(200)]
        self.assert_rows(brute_rows(pts, 0.2), want, "cKDTree reference")

    def test_full_and_half_lists_match_brute_force(self):
        for name, pts, radius in clouds():
            full = brute_rows(pts, radius)
            self.assertGreater(sum(len(r) for r in full), len(pts), name)
            for gridder, order, reorder in [("B", "sort_x", True), ("A", "hilbert", False), ("C", "sort_xyz", True),
                                            ("D", "sort_xy", False)]:
                what = f"{name} {gridder}/{order}/reorder={reorder}"
                offsets, indices = sphnl.neighbours(pts, radius, gridder=gridder, cell_order=order, reorder=reorder)
                self.assertEqual(offsets.dtype, np.int64, what)
                self.assertEqual(offsets.shape, (len(pts) + 1,), what)
                self.assertEqual(offsets[0], 0, what)
                self.assertEqual(offsets[-1], len(indices), what)
                self.assert_rows(rows_of(offsets, indices), full, what)
            offsets, indices = sphnl.neighbours(pts, radius, half=True)
            self.assert_rows(rows_of(offsets, indices), brute_rows(pts, radius, half=True), f"{name} half")

    def test_threads_split_the_work_not_the_answer(self):
        for name, pts, radius in clouds():
            for half in (False, True):
                one = sphnl.neighbours(pts, radius, half=half)
                two = sphnl.neighbours(pts, radius, half=half, threads=2)
                np.testing.assert_array_equal(two[0], one[0], err_msg=f"{name} half={half}")
                np.testing.assert_array_equal(two[1], one[1], err_msg=f"{name} half={half}")

    def test_float32_searches_the_float32_values(self):
        for name, pts, radius in clouds():
            p32 = pts.astype(np.float32)
            offsets, indices = sphnl.neighbours(p32, radius)
            self.assert_rows(rows_of(offsets, indices), brute_rows(p32.astype(np.float64), radius), f"{name} float32")

    def test_non_contiguous_input_is_copied_once_and_gives_the_same_rows(self):
        _, pts, radius = clouds()[0]
        wide = np.zeros((len(pts), 5))
        wide[:, 1:4] = pts
        view = wide[:, 1:4]
        self.assertFalse(view.flags["C_CONTIGUOUS"])
        a = sphnl.neighbours(view, radius)
        b = sphnl.neighbours(np.ascontiguousarray(view), radius)
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])
        fortran = np.asfortranarray(pts)
        np.testing.assert_array_equal(sphnl.neighbours(fortran, radius)[1], b[1])

    def test_degenerate_clouds(self):
        same = np.tile([[1.0, 2.0, 3.0]], (30, 1))
        offsets, indices = sphnl.neighbours(same, 0.1)
        self.assertEqual(len(indices), 30 * 29)
        self.assert_rows(rows_of(offsets, indices), [np.array([j for j in range(30) if j != i]) for i in range(30)],
                         "identical points")
        offsets, indices = sphnl.neighbours(np.zeros((1, 3)), 1.0)
        np.testing.assert_array_equal(offsets, [0, 0])
        self.assertEqual(len(indices), 0)
        offsets, indices = sphnl.neighbours(np.zeros((0, 3)), 1.0)
        np.testing.assert_array_equal(offsets, [0])
        self.assertEqual(len(indices), 0)

    def test_bad_input_raises_value_error_naming_the_problem(self):
        good = np.zeros((4, 3))
        cases = [
            (lambda: sphnl.neighbours(np.zeros((4, 2)), 1.0), "shape"),
            (lambda: sphnl.neighbours(np.zeros(12), 1.0), "shape"),
            (lambda: sphnl.neighbours(np.zeros((4, 3), dtype=np.int64), 1.0), "float64 or float32"),
            (lambda: sphnl.neighbours(good, 0.0), "radius"),
            (lambda: sphnl.neighbours(good, -1.0), "radius"),
            (lambda: sphnl.neighbours(good, float("nan")), "radius"),
            (lambda: sphnl.neighbours(good, float("inf")), "radius"),
            (lambda: sphnl.neighbours(good, 1.0, gridder="E"), "gridder"),
            (lambda: sphnl.neighbours(good, 1.0, cell_order="zorder"), "cell_order"),
            (lambda: sphnl.neighbours(good, 1.0, threads=0), "threads"),
        ]
        nan_pts = good.copy()
        nan_pts[2, 1] = np.nan
        cases.append((lambda: sphnl.neighbours(nan_pts, 1.0), "y[2] is NaN"))
        inf_pts = good.astype(np.float32)
        inf_pts[3, 0] = np.inf
        cases.append((lambda: sphnl.neighbours(inf_pts, 1.0), "x[3] is infinite"))
        for call, words in cases:
            with self.assertRaises(ValueError) as ctx:
                call()
            self.assertIn(words, str(ctx.exception))


if __name__ == "__main__":
    unittest.main()
