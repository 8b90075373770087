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
  PairCounts& operator+=(const PairCounts& o) {
    candidates += o.candidates;
    interactions += o.interactions;
    idle_lanes += o.idle_lanes;
    return *this;
  }
};

}  // namespace sphnl
