#pragma once
#include <cstdint>

namespace sphnl {

/// Work done by one pass of a pair source, summed over threads.
struct alignas(64) PairCounts {
  std::uint64_t candidates = 0;    // candidate pairs distance-tested (each unordered pair once)
  std::uint64_t interactions = 0;  // pairs that passed (r < 2h) and were evaluated
  // Lanes the pair kernel evaluated beyond the pairs: the masked-off lanes of
  // pair_loop=masked's j-blocks (zero for a loop over compacted pairs).
  std::uint64_t idle_lanes = 0;
  // Where a pass's wall time goes with threads (docs/PERFORMANCE.md, "Where
  // two threads lose"): the seconds the threads spent in their pair loops,
  // summed over threads (waits at barriers and the end of the region left
  // out); the wall seconds of the parallel region; and the seconds of the
  // serial sum of private accumulators after it. busy / (threads x region)
  // is 1 when no thread waited.
  double busy_seconds = 0;
  double region_seconds = 0;
  double reduce_seconds = 0;
  PairCounts& operator+=(const PairCounts& o) {
    candidates += o.candidates;
    interactions += o.interactions;
    idle_lanes += o.idle_lanes;
    busy_seconds += o.busy_seconds;
    region_seconds += o.region_seconds;
    reduce_seconds += o.reduce_seconds;
    return *this;
  }
};

}  // namespace sphnl
