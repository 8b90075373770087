"""End to end at the tiny size: the real sphnl_bench -> results JSON -> figures
and REPRODUCTION.md (docs/CONTRACTS.md §3). `make test` sets SPHNL_BUILD_DIR; without it
(e.g. a bare `python -m unittest`) the test is skipped, with it a missing
binary is a failure."""
import json
import os
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PYTHON = sys.executable


@unittest.skipUnless(os.environ.get("SPHNL_BUILD_DIR"), "SPHNL_BUILD_DIR not set (make test sets it)")
class TinyPipeline(unittest.TestCase):
    def test_every_figure_and_the_claims_table_come_from_the_fresh_json(self):
        bench = Path(os.environ["SPHNL_BUILD_DIR"]) / "benchmarks" / "sphnl_bench"
        self.assertTrue(bench.is_file(), f"{bench} is missing: build it with `make build`")
        specs = {p.stem: json.loads(p.read_text(encoding="utf-8")) for p in (ROOT / "experiments").glob("*.json")}
        # The counters kind runs under valgrind: tests/python/test_counters.py covers it.
        timed = [i for i, s in specs.items() if s.get("figure") and s["benchmark"] != "counters"]
        with tempfile.TemporaryDirectory() as tmp:
            results = Path(tmp) / "results"
            run = subprocess.run(
                [PYTHON, "-m", "experiments.run", "--size", "tiny", "--run-id", "e2e", "--only", ",".join(timed),
                 "--results-dir", str(results), "--bench", str(bench), "--cache-dir", str(Path(tmp) / "cache")],
                cwd=ROOT, capture_output=True, text=True, timeout=600)
            self.assertEqual(run.returncode, 0, run.stdout[-2000:] + run.stderr[-2000:])
            # The ablations (figure null: `make ablations`, not make reproduce) into the same
            # run, and search_api (figure null too): the API's rows pass the bench's pair check.
            ablations = sorted(p.stem for p in (ROOT / "experiments").glob("*.json")
                               if p.stem.startswith("ablation_")
                               or p.stem in ("beyond_loops", "beyond_thread_updates", "beyond_scaling", "beyond_dynamic", "beyond_precision",
                                              "beyond_pair_loop", "beyond_vl_loop", "beyond_inner_order",
                                              "search_api", "first_call", "peers_first_call"))
            run = subprocess.run(
                [PYTHON, "-m", "experiments.run", "--size", "tiny", "--run-id", "e2e", "--only", ",".join(ablations),
                 "--force-merge", "a second part of the same code (refused when the tree is dirty)",
                 "--results-dir", str(results), "--bench", str(bench), "--cache-dir", str(Path(tmp) / "cache")],
                cwd=ROOT, capture_output=True, text=True, timeout=600)
            self.assertEqual(run.returncode, 0, run.stdout[-2000:] + run.stderr[-2000:])
            run_dir = results / "e2e"
            experiments = sorted(p.stem for p in (ROOT / "experiments").glob("*.json"))
            ran = []
            for exp_id in experiments:
                spec = json.loads((ROOT / "experiments" / f"{exp_id}.json").read_text(encoding="utf-8"))
                # counters: tests/python/test_counters.py; mpi (sphnl run under mpirun): test_beyond_mpi.py
                if spec.get("uses") or exp_id in ("compare", "search") or spec["benchmark"] in ("counters", "mpi"):
                    continue
                out = run_dir / f"{exp_id}.json"
                self.assertTrue(out.is_file(), f"{exp_id}: no results JSON")
                doc = json.loads(out.read_text(encoding="utf-8"))
                names = [b["name"] for b in doc["benchmarks"]]
                self.assertTrue(names, f"{exp_id}: no benchmarks")
                self.assertFalse([b for b in doc["benchmarks"] if b.get("error_occurred")], f"{exp_id}: errors")
                self.assertIn("sphnl_git_revision", doc["context"])
                # The protocol with the real bench: 2 rounds at tiny, each with its
                # executed order; GB's warm-up call of every configuration is discarded.
                configs = len(set(names))
                self.assertEqual([r["round"] for r in doc["sphnl_rounds"]], [0, 1], exp_id)
                for r in doc["sphnl_rounds"]:
                    self.assertEqual(sorted(r["order"]), sorted(b["run_name"] for b in doc["benchmarks"]
                                                                if b["sphnl_round"] == r["round"]))
                    self.assertEqual(r["warmups_discarded"], configs, exp_id)
                self.assertIn(doc["sphnl_protocol"]["stop_reason"], ("target met", "max rounds"))
                if spec["benchmark"] == "step":
                    self.assertTrue(all(b["nl_bytes"] > 0 for b in doc["benchmarks"]), exp_id)
                    self.assertTrue(all(b["snapshot_time"] >= 0.2 for b in doc["benchmarks"]), exp_id)
                ran.append(exp_id)
            self.assertIn("fig06", ran)
            self.assertIn("fig14", ran)
            # The peers: both implementations on every cloud, order and call,
            # each having passed the pair-set check against sphnl's engine.
            self.assertIn("peers", ran)
            peers = json.loads((run_dir / "peers.json").read_text(encoding="utf-8"))["benchmarks"]
            for axis, values in (("impl", {"sphnl", "nanoflann"}), ("cloud", {"lattice", "random"}),
                                 ("memory_order", {"generated", "shuffled"}), ("call", {"warm", "first"})):
                self.assertEqual({b["run_name"].split(f"/{axis}:")[1].split("/")[0] for b in peers}, values, axis)
            self.assertEqual(len({b["entries"] for b in peers}), 2, "lattice and random: one entry count each")
            # fig16 sweeps three flow states at tiny too: one development run of
            # the case saved all three snapshots, each window starts from its own.
            cache = sorted(p.name for p in (Path(tmp) / "cache").glob("*.snap"))
            for t in ("0.2", "0.35", "0.5"):
                self.assertTrue([c for c in cache if f"_t{t}_thr" in c], cache)
            fig16 = json.loads((run_dir / "fig16.json").read_text(encoding="utf-8"))["benchmarks"]
            for b in fig16:
                want = float(b["run_name"].rsplit("/flow_time:", 1)[1])
                self.assertGreaterEqual(b["snapshot_time"], want)
                self.assertLess(b["snapshot_time"], want + 0.01)

            report = subprocess.run([PYTHON, "-m", "plots.report", str(run_dir)],
                                    cwd=ROOT, capture_output=True, text=True, timeout=600,
                                    env={**os.environ, "MPLBACKEND": "Agg"})
            self.assertEqual(report.returncode, 0, report.stdout[-2000:] + report.stderr[-2000:])
            newest_json = max((run_dir / f"{e}.json").stat().st_mtime for e in ran)
            for fig in ["fig%02d" % k for k in range(6, 18)] + ["peers"]:
                for ext in ("png", "svg"):
                    path = run_dir / "figures" / f"{fig}.{ext}"
                    self.assertTrue(path.is_file() and path.stat().st_size > 1000, f"{path} missing or empty")
                    self.assertGreaterEqual(path.stat().st_mtime, newest_json, f"{path} older than the JSON")
            table1 = (run_dir / "table1.md").read_text(encoding="utf-8")
            for phase in ("Neighbour List", "Force Computation", "System Update"):
                self.assertIn(f"| {phase} |", table1)
            reproduction = (run_dir / "REPRODUCTION.md").read_text(encoding="utf-8")
            self.assertIn("| Figure | Claim | Paper | Measured [95 % interval] | Verdict | Note |", reproduction)
            self.assertIn(str(run_dir), reproduction)
            # every measured experiment says how its drift was treated
            drift = reproduction.split("## Drift correction", 1)[1].split("\n## ", 1)[0]
            for exp_id in ran:
                self.assertIn(f"- `{exp_id}`: ", drift)
            claims = json.loads((run_dir / "claims.json").read_text(encoding="utf-8"))
            ids = {c["id"] for e in experiments for c in json.loads(
                (ROOT / "experiments" / f"{e}.json").read_text(encoding="utf-8"))["claims"]}
            self.assertEqual({c["id"] for c in claims}, ids)


if __name__ == "__main__":
    unittest.main()
