#pragma once
// Binary snapshots of a simulation's state, so that benchmarks can start from a
// developed flow instead of t = 0. Layout: magic "SPHNLSNP", version, N, dx, h,
// t, steps, lost, the config as JSON text, the particle arrays, and an FNV-1a
// checksum of everything before it. Written to a temporary name, then renamed.
#include <cstdint>
#include <string>

#include "sphnl/simulation.hpp"

namespace sphnl {

struct SnapshotInfo {
  std::uint64_t n = 0;
  double dx = 0, h = 0, time = 0;
  long steps = 0;
  std::uint64_t lost = 0;
  std::string config_json;   // the config the state was made with
  std::uint64_t checksum = 0;
};

/// Writes the state of `sim` to `path` (atomically).
void save_snapshot(const std::string& path, const Simulation& sim);
/// Reads only the header and verifies the checksum; throws on a missing,
/// truncated or corrupt file, naming the path and the problem.
SnapshotInfo read_snapshot_info(const std::string& path);
/// Whether a state made with the config `stored_json` (SnapshotInfo::config_json)
/// is the state `wanted` reaches: every key the snapshot stored has wanted's
/// value, and every key it lacks (added to RunConfig after it was written)
/// has its default in `wanted`. A new key's default keeps the behaviour the
/// code had before the key existed (docs/CONTRACTS.md), so adding a key leaves
/// stored states valid; a stored key the code no longer knows makes one stale.
/// Throws on text that is not a JSON object.
bool snapshot_config_matches(const std::string& stored_json, const RunConfig& wanted);
/// Restores the state stored in `path` into `sim`, which must have been built
/// for the same case (same N); throws naming the mismatch otherwise.
SnapshotInfo load_snapshot(const std::string& path, Simulation& sim);

}  // namespace sphnl
