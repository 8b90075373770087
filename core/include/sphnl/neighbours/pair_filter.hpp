#pragma once
// The distance test shared by every pair source: from candidate particles,
// keep those with 1e-18 < r^2 < (2h)^2 that are not two boundary particles
// (boundary-boundary pairs are never computed, PHYSICS.md).
#include <cstdint>

#include "sphnl/particle_view.hpp"

namespace sphnl {

/// Candidates j0..j1-1 (contiguous) of particle i; writes the survivors to `out`.
inline int filter_range(const ParticleView& v, std::uint32_t i, std::uint32_t j0, std::uint32_t j1, double support2,
                        std::uint32_t* __restrict out) {
  const double xi = v.x[i], yi = v.y[i], zi = v.z[i], fi = v.is_fluid[i];
  int n = 0;
  for (std::uint32_t j = j0; j < j1; ++j) {
    const double dx = xi - v.x[j], dy = yi - v.y[j], dz = zi - v.z[j];
    const double r2 = dx * dx + dy * dy + dz * dz;
    const bool keep = (r2 < support2) & (r2 > 1e-18) & (fi + v.is_fluid[j] > 0.0);
    out[n] = j;  // branch-free compaction
    n += keep;
  }
  return n;
}

/// Candidates given as a list (Verlet lists); writes the survivors to `out`.
/// The list holds no boundary-boundary pair, so only the distance is tested.
inline int filter_list(const ParticleView& v, std::uint32_t i, const std::uint32_t* __restrict candidates, int count,
                       double support2, std::uint32_t* __restrict out) {
  const double xi = v.x[i], yi = v.y[i], zi = v.z[i];
  int n = 0;
  for (int k = 0; k < count; ++k) {
    const std::uint32_t j = candidates[k];
    const double dx = xi - v.x[j], dy = yi - v.y[j], dz = zi - v.z[j];
    const double r2 = dx * dx + dy * dy + dz * dz;
    out[n] = j;
    n += (r2 < support2) & (r2 > 1e-18);
  }
  return n;
}

}  // namespace sphnl
