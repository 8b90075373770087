#pragma once
// The one brute-force oracle of the C++ tests: every pair of a particle set
// tested in O(N^2), with the distance arithmetic of the library (distance2, so
// pairs at exactly r = R agree with every search path).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "sphnl/kernel.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/particles.hpp"

namespace sphnl::test {

/// Pairs (smaller id, larger id), sorted.
using PairSet = std::vector<std::pair<std::uint32_t, std::uint32_t>>;

struct OracleRules {
  /// Pairs need r^2 > min_r2: CubicSpline::kMinR2 for the SPH pair sources
  /// (coincident particles never interact), below 0 for NeighbourSearch.
  double min_r2 = CubicSpline::kMinR2;
  /// > 0: y is periodic with this period; y distances are to the nearest image.
  double period_y = 0;
};

/// Every pair with min_r2 < r^2 < radius2 of gridded (not out) particles that
/// are not both boundary particles (the rules of pair_filter.hpp), by id.
inline PairSet brute_force_pairs(const ParticleSet& ps, double radius2, const OracleRules& rules = {}) {
  PairSet pairs;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    if (ps.type[i] == ParticleType::out) continue;
    for (std::size_t j = i + 1; j < ps.size(); ++j) {
      if (ps.type[j] == ParticleType::out) continue;
      if (ps.type[i] == ParticleType::boundary && ps.type[j] == ParticleType::boundary) continue;
      double dy = ps.y[i] - ps.y[j];
      if (rules.period_y > 0) dy -= rules.period_y * std::round(dy / rules.period_y);
      const double r2 = distance2(ps.x[i] - ps.x[j], dy, ps.z[i] - ps.z[j]);
      if (r2 < radius2 && r2 > rules.min_r2) pairs.emplace_back(std::min(ps.id[i], ps.id[j]), std::max(ps.id[i], ps.id[j]));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace sphnl::test
