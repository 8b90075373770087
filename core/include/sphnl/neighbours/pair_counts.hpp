#pragma once
#include <cstdint>

namespace sphnl {

/// Work done by one pass of a pair source, summed over threads.
struct alignas(64) PairCounts {
  std::uint64_t candidates = 0;    // candidate pairs distance-tested (each unordered pair once)
  std::uint64_t interactions = 0;  // pairs that passed (r < 2h) and were evaluated
  PairCounts& operator+=(const PairCounts& o) {
    candidates += o.candidates;
    interactions += o.interactions;
    return *this;
  }
};

}  // namespace sphnl
