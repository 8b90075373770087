"""harness/drift.py on synthetic repetitions whose drift is known: the
leave-one-out neighbour mean, the window choice (a slow drift is corrected,
white noise is left alone), no bias in a ratio, which columns are scaled,
the level of an experiment measured on a slower machine, the report's
lines, and that the intervals of the corrected times still cover the truth."""
import unittest

import numpy as np
import pandas as pd

from harness import drift as D
from harness.drift_model import coverage, experiment
from plots import report


class NeighbourMeanTest(unittest.TestCase):
    def test_leave_one_out_window(self):
        v = [1.0, 2.0, 4.0, 8.0, 16.0]
        np.testing.assert_allclose(D.neighbour_mean(v, 1), [2.0, 2.5, 5.0, 10.0, 8.0])
        np.testing.assert_allclose(D.neighbour_mean(v, 2), [3.0, 13 / 3, 6.75, 22 / 3, 6.0])
        np.testing.assert_allclose(D.neighbour_mean([3.0], 1), [0.0])


class DriftTest(unittest.TestCase):
    def test_slow_drift_is_corrected(self):
        rows = experiment(np.random.default_rng(3), configs=20, reps=5, rounds=4, sd_white=0.01)
        out, summary = D.corrected(rows)
        s = summary["x"]
        self.assertIsNotNone(s["window"])
        self.assertLess(s["scatter_pct_after"], 0.6 * s["scatter_pct_before"])
        # the corrected times of one configuration scatter less than the raw ones
        raw_cv = rows.groupby("cfg")["s_per_step"].std() / rows.groupby("cfg")["s_per_step"].mean()
        cor_cv = out.groupby("cfg")["s_per_step"].std() / out.groupby("cfg")["s_per_step"].mean()
        self.assertLess(cor_cv.median(), 0.6 * raw_cv.median())
        # times divided, rates multiplied, by the same factor; the rest untouched
        np.testing.assert_allclose(out["s_per_step"] * out[D.FACTOR], rows["s_per_step"])
        np.testing.assert_allclose(out["real_time_s"] * out[D.FACTOR], rows["real_time_s"])
        np.testing.assert_allclose(out["pairs_per_s"] / out[D.FACTOR], rows["pairs_per_s"])
        pd.testing.assert_series_equal(out["witness_core_gflops"], rows["witness_core_gflops"])
        pd.testing.assert_series_equal(out["nl_bytes"], rows["nl_bytes"])

    def test_white_noise_is_left_alone(self):
        # Without drift no neighbour predicts a repetition, so every window
        # adds scatter and none is chosen. (An estimate that included the
        # repetition itself would shrink its residual and be chosen here.)
        rows = experiment(np.random.default_rng(4), configs=20, reps=10, rounds=3, sd_round=0.0,
                          sd_drift=0.0, rho=0.0, sd_white=0.03)
        out, summary = D.corrected(rows)
        self.assertIsNone(summary["x"]["window"])
        pd.testing.assert_series_equal(out["s_per_step"], rows["s_per_step"])
        self.assertTrue((out[D.FACTOR] == 1.0).all())

    def test_no_bias_in_a_ratio(self):
        # Many configurations of very different speed, no drift at all: any
        # correction the window choice still applies must leave the ratio.
        rows = experiment(np.random.default_rng(5), configs=30, reps=6, rounds=4, sd_drift=0.0,
                          sd_round=0.05, sd_white=0.01)
        out, _ = D.corrected(rows, windows=(1,))
        med = out.groupby("cfg")["s_per_step"].median()
        self.assertAlmostEqual(med["c1"] / med["c0"], 0.9, delta=0.01)

    def test_an_experiment_measured_on_a_slower_machine_is_levelled(self):
        # The same 20 configurations in two experiments, the second measured
        # 10 % slower throughout: its configurations are brought to the first's level.
        one = experiment(np.random.default_rng(8), sd_white=0.01, name="one")
        two = one.assign(experiment="two", real_time_s=1.1 * one["real_time_s"],
                         s_per_step=1.1 * one["s_per_step"])
        out, _ = D.corrected(pd.concat([one, two], ignore_index=True))
        med = out.groupby(["experiment", "cfg"])["s_per_step"].median().unstack("experiment")
        self.assertLess(abs(np.median(med["two"] / med["one"]) - 1.0), 0.03)

    def test_rows_without_run_order_or_with_errors(self):
        rows = experiment(np.random.default_rng(6), configs=8)
        old = rows.drop(columns=["run_sequence"]).assign(experiment="old")
        bad = rows.copy()
        bad.loc[bad.index[:5], "error_occurred"] = True
        bad.loc[bad.index[:5], "real_time_s"] = np.nan
        out, summary = D.corrected(pd.concat([old, bad], ignore_index=True))
        self.assertEqual(summary["old"]["repetitions"], 0)
        self.assertIsNone(summary["old"]["window"])
        olds = out[out.experiment == "old"]
        np.testing.assert_array_equal(olds["s_per_step"].to_numpy(), old["s_per_step"].to_numpy())
        self.assertEqual(summary["x"]["repetitions"], len(rows) - 5)
        errored = out[(out.experiment == "x") & out.error_occurred]
        self.assertTrue((errored[D.FACTOR] == 1.0).all())

    def test_intervals_still_cover_the_truth(self):
        # 30 synthetic experiments with a drift like this VM's (lag-1 0.8,
        # 5 % rounds and drift, 2 % white): the 95 % interval of c1 / c0 from
        # corrected times covers 0.9 about as often as from raw times and is
        # narrower.
        out, _ = coverage(30, seed=7, configs=10)
        self.assertGreaterEqual(out["corrected"][0], 25 / 30)
        self.assertLess(out["corrected"][1], 0.8 * out["raw"][1])



class ReportSectionTest(unittest.TestCase):
    def test_lines_of_each_case(self):
        rows = experiment(np.random.default_rng(3), configs=20, reps=5, rounds=4, sd_white=0.01)
        flat = experiment(np.random.default_rng(4), configs=20, reps=10, rounds=3, sd_round=0.0,
                          sd_drift=0.0, rho=0.0, sd_white=0.03, name="flat")
        flat["cfg"] = "flat " + flat["cfg"]  # other configurations than x's
        old = rows.drop(columns=["run_sequence"]).assign(experiment="old")
        _, summary = D.corrected(pd.concat([rows, flat, old], ignore_index=True))
        lines = report.drift_section(summary)
        self.assertEqual(len(lines), 3)
        self.assertTrue(lines[0].startswith("- `flat`: no window reduced the scatter of "), lines[0])
        self.assertEqual(lines[1], "- `old`: no run order recorded; times as measured")
        k = summary["x"]["window"]
        self.assertRegex(lines[2], rf"^- `x`: {k} neighbour\(s\) on each side; scatter of the residuals "
                                   r"\d+\.\d % → \d+\.\d % \(400 repetitions\)$")
        # two experiments sharing configurations: each line gives its level
        summary = {"a": {**summary["x"], "level_pct": 3.04}, "b": {**summary["flat"], "level_pct": -2.95}}
        lines = report.drift_section(summary)
        self.assertTrue(lines[0].endswith("; level +3.0 % against the experiments it shares configurations with"))
        self.assertTrue(lines[1].endswith("; level -3.0 % against the experiments it shares configurations with"))
        # a level too small to print is shown as none, not as "+0.0 %" or "-0.0 %"
        lines = report.drift_section({"a": {**summary["a"], "level_pct": -0.01}})
        self.assertTrue(lines[0].endswith("; level ±0.0 % against the experiments it shares configurations with"))


if __name__ == "__main__":
    unittest.main()
