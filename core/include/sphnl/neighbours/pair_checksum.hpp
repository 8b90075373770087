#pragma once
// PairChecksum: an order-independent fingerprint of a set of neighbour
// entries (i, j) (full lists: every pair in both rows), so two neighbour
// searches can be checked to have found the same pairs without sorting or
// storing either: the sum (mod 2^64) of a 64-bit mix of every entry, and the
// entry count. Rows in any order, entries within a row in any order, give the
// same value; a missing, extra or wrong entry changes it (up to a 2^-64
// collision).
#include <cstdint>
#include <stdexcept>
#include <string>

namespace sphnl {

struct PairChecksum {
  std::uint64_t sum = 0;
  std::uint64_t entries = 0;

  /// splitmix64's finaliser of (i, j): every bit of both indices reaches
  /// every bit of the result, so a sum of them cannot cancel by accident.
  static std::uint64_t mix(std::uint32_t i, std::uint32_t j) {
    std::uint64_t z = (std::uint64_t{i} << 32 | j) + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  void add(std::uint32_t i, std::uint32_t j) {
    sum += mix(i, j);
    ++entries;
  }
  /// Adds row `i` with neighbours row[0..count).
  void add_row(std::uint32_t i, const std::uint32_t* row, std::uint64_t count) {
    for (std::uint64_t k = 0; k < count; ++k) sum += mix(i, row[k]);
    entries += count;
  }
  PairChecksum& operator+=(const PairChecksum& o) {
    sum += o.sum;
    entries += o.entries;
    return *this;
  }
  bool operator==(const PairChecksum&) const = default;
};

/// Throws std::runtime_error naming both implementations when `got` (of
/// `impl`) is not `reference` (of `reference_impl`): a peer that finds other
/// pairs is not doing the same work, and its speed would mean nothing.
inline void require_same_pairs(const std::string& impl, const PairChecksum& got, const std::string& reference_impl,
                               const PairChecksum& reference) {
  if (got == reference) return;
  throw std::runtime_error("the pair set of " + impl + " differs from " + reference_impl + "'s (" + impl + ": " +
                           std::to_string(got.entries) + " entries, checksum " + std::to_string(got.sum) + "; " +
                           reference_impl + ": " + std::to_string(reference.entries) + " entries, checksum " +
                           std::to_string(reference.sum) +
                           "): both must list every j != i strictly closer than R; nothing is reported");
}

}  // namespace sphnl
