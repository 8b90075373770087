#pragma once
// PairRecorder: a pair operation that records the pairs a pair source hands
// it. Pair sources pass either global indices (Verlet lists) or indices into a
// cell-gather buffer (cell-linked list), so pairs are recorded by the
// positions of both particles and mapped to ids afterwards (particles of the
// test sets never coincide).
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <unordered_map>
#include <vector>

#include "sphnl/neighbours/pair_operation.hpp"
#include "sphnl/particle_view.hpp"
#include "sphnl/particles.hpp"
#include "support/oracle.hpp"

namespace sphnl::test {

struct PairRecorder {
  static constexpr unsigned kFields = fields::position;
  std::vector<std::array<double, 6>>* out = nullptr;
  void interact(const ParticleView& v, std::uint32_t i, const std::uint32_t* js, int n) {
    for (int p = 0; p < n; ++p) out->push_back({v.x[i], v.y[i], v.z[i], v.x[js[p]], v.y[js[p]], v.z[js[p]]});
  }
};
static_assert(PairOperation<PairRecorder>);

struct PositionHash {
  std::size_t operator()(const std::array<double, 3>& p) const {
    std::uint64_t b[3];
    std::memcpy(b, p.data(), sizeof b);
    return static_cast<std::size_t>(b[0] * 0x9E3779B97F4A7C15ull ^ b[1] * 0xC2B2AE3D27D4EB4Full ^ b[2]);
  }
};

/// The recorded pairs as (smaller id, larger id), sorted, looked up by position
/// in `ps`. Positions of periodic images (shifted by the period) are mapped
/// back when period_y > 0.
inline PairSet recorded_ids(const ParticleSet& ps, const std::vector<std::array<double, 6>>& pairs) {
  std::unordered_map<std::array<double, 3>, std::uint32_t, PositionHash> id_at;
  for (std::size_t i = 0; i < ps.size(); ++i)
    if (ps.type[i] != ParticleType::out) id_at[{ps.x[i], ps.y[i], ps.z[i]}] = ps.id[i];
  PairSet ids;
  ids.reserve(pairs.size());
  for (const auto& p : pairs) {
    const std::uint32_t a = id_at.at({p[0], p[1], p[2]}), b = id_at.at({p[3], p[4], p[5]});
    ids.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

}  // namespace sphnl::test
