#include "sphnl/kgc.hpp"

#include <Eigen/Dense>
#include <algorithm>

namespace sphnl {

void clear_kgc_matrices(ParticleSet& ps) {
  for (auto& m : ps.kgc_m) std::fill(m.begin(), m.end(), 0.0);
}

double kgc_trace_sum(const ParticleSet& ps, std::size_t count) {
  const std::size_t n = std::min(count, ps.size());
  double sum = 0;
  for (std::size_t i = 0; i < n; ++i) sum += ps.kgc_m[0][i] + ps.kgc_m[3][i] + ps.kgc_m[5][i];
  return sum;
}

std::size_t invert_kgc_matrices(ParticleSet& ps, std::size_t count) {
  const std::size_t n = std::min(count, ps.size());
  std::size_t fallbacks = 0;
  // symmetric storage order xx, xy, xz, yy, yz, zz
  constexpr int kRow[6] = {0, 0, 0, 1, 1, 2}, kCol[6] = {0, 1, 2, 1, 2, 2};
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Matrix3d l = Eigen::Matrix3d::Identity();
    if (ps.type[i] == ParticleType::fluid) {
      Eigen::Matrix3d m;
      for (int c = 0; c < 6; ++c) m(kRow[c], kCol[c]) = m(kCol[c], kRow[c]) = ps.kgc_m[c][i];
      const bool conditioned = std::abs(m.determinant()) > 0.01 && std::abs(m(0, 0)) > 0.25 &&
                               std::abs(m(1, 1)) > 0.25 && std::abs(m(2, 2)) > 0.25;
      if (conditioned) {
        l = m.inverse();
        l = 0.5 * (l + l.transpose());  // exact inverse of a symmetric matrix, up to round-off
      } else {
        ++fallbacks;
      }
    }
    for (int c = 0; c < 6; ++c) ps.kgc[c][i] = l(kRow[c], kCol[c]);
  }
  return fallbacks;
}

}  // namespace sphnl
