"""experiments.beyond_mpi: the runs it plans and the tables it derives (from
synthetic summaries: no MPI and no timing needed)."""
import unittest

from experiments import beyond_mpi as B


def summary(total, comm=0.0, n=3000, steps=10):
    return {"wall_time_s": {"total": total, "communication": comm}, "steps": steps, "n_total": n,
            "bytes_sent_per_step": 100.0, "ghosts_per_rank": {"min": 1, "max": 5}}


class BeyondMpi(unittest.TestCase):
    def test_points_cover_scaling_and_pure_openmp_at_the_same_cores(self):
        names = [p[0] for p in B.points([1, 2], 1)]
        self.assertEqual(names, ["cll_p1_t1", "cll_p2_t1", "cll_p1_t2", "vlx_p1_t1", "vlx_p2_t1", "vlx_p1_t2"])
        self.assertEqual([p[0] for p in B.points([1], 2)], ["cll_p1_t2", "vlx_p1_t2"])

    def test_rows_and_tables(self):
        rows = [B.row("cll_p1_t1", 1, 1, "cll", summary(2.0)),
                B.row("cll_p2_t1", 2, 1, "cll", summary(1.25, comm=0.25)),
                B.row("vlx_p1_t1", 1, 1, "vlx", summary(1.0)),
                B.row("vlx_p2_t1", 2, 1, "vlx", summary(0.5, comm=0.1))]
        self.assertAlmostEqual(rows[1]["communication_share"], 0.2)
        self.assertAlmostEqual(rows[1]["n_per_rank"], 1500)
        self.assertAlmostEqual(rows[0]["s_per_step"], 0.2)
        md = B.tables(rows)
        self.assertIn("| cll | 2 x 1 | 1.60 |", md)   # 2.0 / 1.25
        self.assertIn("| vlx | 2 x 1 | 2.00 |", md)
        self.assertIn("| 1 x 1 | 3000 | 2.00 |", md)  # t_CLL / t_VLX at N/P = 3000
        self.assertIn("| 2 x 1 | 1500 | 2.50 |", md)


if __name__ == "__main__":
    unittest.main()
