#pragma once
// RunConfig: every run-time choice of a simulation, with the key names of the
// table in README.md, "Configuration" (JSON file and `--set
// key=value` use the same names).
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "sphnl/input_error.hpp"
#include "sphnl/kinds.hpp"

namespace sphnl {

enum class Lattice : std::uint8_t { bcc, cubic };
/// Snapshots of a run on several ranks: `gathered` (rank 0 writes every
/// particle in id order: the serial files) or `per_rank` (each rank a .vtu
/// piece of its own particles, rank 0 a .pvtu naming them; no gather, no CSV).
enum class SnapshotPieces : std::uint8_t { gathered, per_rank };

const char* to_string(Lattice l);
const char* to_string(SnapshotPieces p);

struct RunConfig {
  // size: exactly one of particles / dx is used (dx > 0 wins when set)
  long particles = 31239;
  double dx = 0;
  // duration: steps > 0 wins over end_time
  long steps = 0;
  double end_time = 0.5;
  double output_interval = 0.05;  // simulated seconds between snapshots; 0 = final only
  SnapshotPieces snapshot_pieces = SnapshotPieces::gathered;  // several ranks only
  // physics (docs/PHYSICS.md)
  double h_coefficient = 0.866025;
  double cfl = 0.3;
  int euler_every = 50;
  double sound_speed_coef = 10;
  bool clamp_boundary_density = false;
  double viscosity_alpha = 0.1;
  double xsph_epsilon = 0.5;
  Lattice lattice = Lattice::bcc;
  double max_lost_fraction = 0.1;  // stop when more than this fraction of the fluid has left
  // execution
  int threads = 1;
  // threads > 1: private accumulator copies summed afterwards (`private`), or
  // home cells in phases where no two threads write one particle (`phased`)
  ThreadUpdates thread_updates = ThreadUpdates::private_accumulators;
  // threads > 1: the cell-linked list's home cells cut into thread ranges of
  // equal fluid weight (`fluid`) or equal estimated pair work (`interactions`),
  // or handed out in chunks as threads finish (`dynamic`, private updates only)
  ThreadSplit thread_split = ThreadSplit::fluid;
  bool progress = true;
  // neighbour search
  GridderKind gridder = GridderKind::B;
  CellOrderKind cell_order = CellOrderKind::sort_x;
  bool reorder = true;
  int reorder_every = 1;
  InnerOrder inner_order = InnerOrder::index;  // each cell's particles after reordering (kinds.hpp)
  int max_parts_in_cell = 0;   // gridder C row length; 0 = sized from h/dx
  ListKind list = ListKind::cll;
  int list_steps = 1;          // n_s: C of VL_C, X of VL_X
  double skin_factor = 0;      // nu of Delta h; 0 = paper default (1.2 VL_C, 1.0 VL_X)
  bool kgc = false;            // kernel gradient correction: the second loop per step
  bool verify_lists = false;   // check every step that no interacting pair is missing
  Precision precision = Precision::double_precision;  // the pair kernel's arithmetic (kinds.hpp)
  // ablations (README.md, "Ablations"); the defaults are the normal path
  PairLoopKind pair_loop = PairLoopKind::gather;  // cell-linked list: gather buffers or in place
  bool simd = true;                 // false: the scalar distance filter and pair kernels
  bool skip_boundary_pairs = false; // cell sweep: never distance-test boundary-boundary candidates
  SlidingVariant gridder_a_variant = SlidingVariant::occupied;
  InitialOrder initial_order = InitialOrder::generated;
  int extra_loops = 0;              // extra pair passes per step (KGC matrix, computed, not applied)
  // distributed runs (mpirun -np P): re-cut the ranks' key ranges at a build
  // when the heaviest rank holds more than (1 + this) times the mean work
  double rebalance_threshold = 0.1;
  BalanceBy balance_by = BalanceBy::interactions;  // the work the key ranges balance (kinds.hpp)

  double effective_skin_factor() const {
    if (skin_factor > 0) return skin_factor;
    return list == ListKind::vlc ? 1.2 : 1.0;
  }
};

/// Builds a RunConfig from a JSON object, validating every key.
RunConfig config_from_json(const nlohmann::json& j);
/// The full configuration as JSON (every key, defaults included).
nlohmann::json config_to_json(const RunConfig& c);
/// Parses one `key=value` override into `j` (value read as JSON when it parses,
/// else as a string, so `gridder=B` and `reorder=false` both work).
void apply_override(nlohmann::json& j, const std::string& key_value);
/// Names of every accepted key, for error messages.
std::vector<std::string> config_keys();

}  // namespace sphnl
