"""plots/noise.py on synthetic results files whose noise is known: slow
drift inside a round (which pairing with the nearest repetition cancels and
pairing by round does not), the scatter measures, and the errors."""
import contextlib
import io
import json
import math
import pathlib
import tempfile
import unittest

import numpy as np

from plots import noise

NAME = "step/particles:1000/gridder:B/cell_order:sort_x/reorder:1/list:{lst}/list_steps:{ns}/kgc:0/threads:1"


def write_results(path, rounds=4, reps=8, drift=0.2, jitter=0.002, ratio=0.9, sequence=True, seed=1):
    """A fig14-like file: CLL and VL_X at n_s = 3 and 7, VL_X `ratio` times CLL.

    Each round runs the repetitions in a random order, as the harness does,
    while the machine speed follows a slow sine of amplitude `drift` along
    the run order, plus independent jitter; rounds differ by a factor too."""
    rng = np.random.default_rng(seed)
    configs = [("cll", 3), ("vlx", 3), ("cll", 7), ("vlx", 7)]
    entries = []
    for r in range(rounds):
        round_speed = 1 + 0.05 * r
        phase = rng.uniform(0, 2 * math.pi)
        order = [(rep, c) for rep in range(reps) for c in configs]
        rng.shuffle(order)
        for seq, (rep, (lst, ns)) in enumerate(order, start=1):
            slow = 1 + drift * math.sin(phase + seq / 8.0)
            t = 0.01 * (ratio if lst == "vlx" else 1.0) * round_speed * slow * (1 + jitter * rng.standard_normal())
            e = {"name": NAME.format(lst=lst, ns=ns), "run_name": NAME.format(lst=lst, ns=ns),
                 "run_type": "iteration", "repetitions": reps, "repetition_index": rep,
                 "iterations": 1, "real_time": t * 1e3, "cpu_time": t * 1e3, "time_unit": "ms",
                 "s_per_step": t, "sphnl_round": r, "witness_core_gflops": 50 / slow}
            if sequence:
                e["run_sequence"] = float(seq)
            entries.append(e)
    doc = {"context": {}, "benchmarks": entries, "sphnl_protocol": {"metric": "s_per_step"}}
    pathlib.Path(path).write_text(json.dumps(doc))


def run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = noise.main([str(a) for a in argv])
    return rc, out.getvalue(), err.getvalue()


class NoiseTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)
        self.path = self.dir / "fig14.json"

    def tearDown(self):
        self.tmp.cleanup()

    def test_nearest_pairing_cancels_slow_drift(self):
        write_results(self.path)
        df, metric = noise.load(self.path)
        self.assertEqual(metric, "s_per_step")
        pairs = noise.pairing(df, "list=cll", resamples=300)
        self.assertEqual(sorted(pairs["list_steps"]), [3, 7])
        for _, r in pairs.iterrows():
            # the drift nearly cancels between neighbours: the true ratio 0.9
            # within 2 %, inside the interval, which is far narrower than by round
            self.assertAlmostEqual(r["nearest"], 0.9, delta=0.018)
            self.assertLessEqual(r["nearest_low"], 0.9)
            self.assertGreaterEqual(r["nearest_high"], 0.9)
            self.assertLess(r["nearest_halfwidth_pct"], r["by_round_halfwidth_pct"] / 2.5)
            self.assertEqual(r["repetitions"], 32)

    def test_scatter_separates_slow_noise(self):
        write_results(self.path)
        sc = noise.scatter(noise.load(self.path)[0])
        self.assertEqual((sc["configurations"], sc["rounds"]), (4, 4))
        self.assertGreater(sc["within_round_cv_pct"], 5)        # the sine's amplitude, 20 %
        self.assertGreater(sc["lag1_autocorrelation"], 0.5)     # slow: neighbours agree
        self.assertLess(sc["rank_correlation_witness_core_gflops"], -0.9)
        write_results(self.path, drift=0.0, jitter=0.05)
        sc = noise.scatter(noise.load(self.path)[0])
        self.assertLess(abs(sc["lag1_autocorrelation"]), 0.4)   # white noise

    def test_any_key_widens_the_baseline(self):
        write_results(self.path)
        df, _ = noise.load(self.path)
        pairs = noise.pairing(df, "list=cll", any_keys=["list_steps"], resamples=200)
        self.assertEqual(len(pairs), 2)
        self.assertTrue((abs(pairs["nearest"] - 0.9) < 0.01).all())

    def test_cli_writes_markdown_and_json(self):
        write_results(self.path)
        out_json = self.dir / "noise.json"
        rc, out, err = run([self.path, "--pair", "list=cll", "--resamples", "200", "--out", out_json])
        self.assertEqual(rc, 0, err)
        self.assertIn("nearest in run order", out)
        self.assertIn("| vlx |", out)
        doc = json.loads(out_json.read_text())
        self.assertEqual(len(doc["pairs"]), 2)
        self.assertIn("within_round_cv_pct", doc["scatter"])

    def test_errors_name_the_problem(self):
        write_results(self.path)
        rc, _, err = run([self.path, "--pair", "list=kd"])
        self.assertEqual(rc, 2)
        self.assertIn("no configuration has list = kd", err)
        rc, _, err = run([self.path, "--pair", "lst"])
        self.assertEqual(rc, 2)
        self.assertIn("expected KEY=VALUE", err)
        rc, _, err = run([self.path, "--pair", "list=cll", "--any", "nope"])
        self.assertIn("--any nope: not a parameter", err)
        rc, _, err = run([self.dir / "missing.json"])
        self.assertEqual(rc, 2)
        self.assertIn("cannot read benchmark JSON", err)
        write_results(self.path, sequence=False)
        rc, _, err = run([self.path])
        self.assertEqual(rc, 2)
        self.assertIn("no run_sequence", err)
        self.assertFalse((self.dir / "noise.json").exists())


if __name__ == "__main__":
    unittest.main()
