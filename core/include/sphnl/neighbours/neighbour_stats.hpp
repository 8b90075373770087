#pragma once
// NeighbourStats: the counters of the neighbour search that a run reports
// (summary.json, the step benchmarks), summed over steps.
#include <cstddef>
#include <cstdint>

namespace sphnl {

/// Counters of the neighbour search, summed over steps.
struct NeighbourStats {
  std::uint64_t builds = 0;          // grid/list builds (CLL: one per step)
  std::uint64_t candidates = 0;      // candidate pairs tested in the main loop
  std::uint64_t interactions = 0;    // pairs evaluated in the main loop
  std::uint64_t idle_lanes = 0;      // pair_loop=masked: kernel lanes evaluated that were not pairs
  // The main loop's PairCounts timing, summed over steps: the threads' seconds
  // in their pair loops (summed over threads), the parallel region's wall
  // seconds, the serial reduction of private accumulators after it.
  double pair_busy_seconds = 0;
  double pair_region_seconds = 0;
  double pair_reduce_seconds = 0;
  std::uint64_t max_steps_per_list = 0;
  // Verlet lists (paper §2.5); all zero for the cell-linked list
  std::uint64_t list_steps = 0;         // steps that used a list (sum of list lifetimes)
  std::uint64_t forced_rebuilds = 0;    // builds forced because a particle went out (not by C / dh/2)
  std::uint64_t list_pairs = 0;         // pairs stored in the current list
  std::uint64_t list_pairs_built = 0;   // pairs stored by the builds, summed over builds (the build's work)
  std::size_t list_bytes = 0;           // bytes of the current list (offsets + indices)
  std::size_t max_list_bytes = 0;       // largest list_bytes seen
  double skin = 0;                      // dh of the current list (m)
  std::uint64_t vl_misses = 0;          // pairs with r < 2h missing from the list (verify_lists only)
  std::uint64_t verified_steps = 0;     // steps checked by verify_lists
  std::uint64_t kgc_fallbacks = 0;      // fluid particles whose L_a fell back to I (summed over steps)
  // extra_loops (README.md, "Ablations"): the extra pair passes run and the
  // sum over them of sum_a trace(M_a) (their result, kept so it is observable)
  std::uint64_t extra_loop_passes = 0;
  double extra_loop_checksum = 0;
  /// Pair-kernel lanes evaluated per pair: 1, more with pair_loop=masked.
  double kernel_lanes_per_pair() const {
    return interactions ? 1.0 + static_cast<double>(idle_lanes) / static_cast<double>(interactions) : 0.0;
  }
  /// Mean steps per list: lifetimes of the lists built (CLL: 1).
  double mean_steps_per_list() const {
    return builds ? static_cast<double>(list_steps ? list_steps : builds) / static_cast<double>(builds) : 0.0;
  }
};

}  // namespace sphnl
