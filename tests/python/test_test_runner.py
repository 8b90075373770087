"""tools/run_python_tests.py: which classes it finds and the order it runs them in."""
import importlib.util
import pathlib
import tempfile
import unittest

REPO = pathlib.Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("run_python_tests", REPO / "tools" / "run_python_tests.py")
runner = importlib.util.module_from_spec(spec)
spec.loader.exec_module(runner)


class TestOrder(unittest.TestCase):
    def test_known_times_first_longest_first_then_binaries(self):
        units = ["test_stats.TestBootstrap", "test_pipeline.TinyPipeline", "test_harness.TestClaims",
                 "test_stats.TestTiesAndPooling"]
        times = {"test_stats.TestBootstrap": 2.0, "test_harness.TestClaims": 5.0}
        order = runner.longest_first(units, times)
        self.assertEqual(order[:2], ["test_harness.TestClaims", "test_stats.TestBootstrap"])
        self.assertEqual(order[2], "test_pipeline.TinyPipeline")   # starts the real binaries

    def test_committed_seed_names_existing_classes(self):
        seed = runner.read_times(runner.SEED_TIMES)
        self.assertTrue(seed, f"{runner.SEED_TIMES} is missing or empty")
        known = set(runner.test_classes(""))
        self.assertEqual(sorted(set(seed) - known), [], "stale names: refresh with --save-seconds")
        self.assertTrue(all(isinstance(t, (int, float)) and t >= 0 for t in seed.values()))

    def test_missing_or_corrupt_times_are_empty(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = pathlib.Path(tmp) / "t.json"
            self.assertEqual(runner.read_times(path), {})
            path.write_text("{not json", encoding="utf-8")
            self.assertEqual(runner.read_times(path), {})
            runner.write_times(path, {"a.B": 1.5})
            self.assertEqual(runner.read_times(path), {"a.B": 1.5})
            self.assertEqual([p.name for p in pathlib.Path(tmp).iterdir()], ["t.json"])


if __name__ == "__main__":
    unittest.main()
