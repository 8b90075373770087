#pragma once
// The point clouds of the neighbour tests (uniform, clustered, planar, points
// on cell boundaries).
#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/particles.hpp"

namespace sphnl::test {

/// Fluid particles at `pts`, id = index.
inline ParticleSet cloud_from(const std::vector<std::array<double, 3>>& pts) {
  ParticleSet ps;
  ps.resize(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ps.x[i] = pts[i][0];
    ps.y[i] = pts[i][1];
    ps.z[i] = pts[i][2];
    ps.type[i] = ParticleType::fluid;
    ps.is_fluid[i] = 1.0;
    ps.id[i] = static_cast<std::uint32_t>(i);
  }
  return ps;
}

/// The bounding box of `ps`, grown by `margin` on every side.
inline Box bounds_of(const ParticleSet& ps, double margin) {
  Box b{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}};
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const double p[3] = {ps.x[i], ps.y[i], ps.z[i]};
    for (int d = 0; d < 3; ++d) {
      b.lo[d] = std::min(b.lo[d], p[d] - margin);
      b.hi[d] = std::max(b.hi[d], p[d] + margin);
    }
  }
  return b;
}

struct Cloud {
  const char* name;
  ParticleSet ps;
  double radius;
};

/// Four clouds of 1320-1500 points with a search radius each: uniform in a
/// cube, four Gaussian clusters, a plane, and a lattice of spacing R/2 (many
/// points on cell faces, many pairs at exactly r = R, which are not
/// neighbours: the test is strict).
inline std::vector<Cloud> test_clouds() {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(-3.0, 5.0);
  std::normal_distribution<double> gauss(0.0, 0.3);
  std::vector<Cloud> clouds;
  std::vector<std::array<double, 3>> p;
  for (int i = 0; i < 1500; ++i) p.push_back({u(rng), u(rng), u(rng)});
  clouds.push_back({"uniform", cloud_from(p), 0.9});
  p.clear();
  const double centres[4][3] = {{0, 0, 0}, {2, 1, -1}, {-1.5, 2, 0.5}, {0.3, -2, 2}};
  for (int i = 0; i < 1500; ++i) {
    const double* c = centres[i % 4];
    p.push_back({c[0] + gauss(rng), c[1] + gauss(rng), c[2] + gauss(rng)});
  }
  clouds.push_back({"clustered", cloud_from(p), 0.25});
  p.clear();
  for (int i = 0; i < 1500; ++i) p.push_back({u(rng), u(rng), 0.125});  // all on one plane
  clouds.push_back({"sheet", cloud_from(p), 0.5});
  p.clear();
  for (int k = 0; k < 10; ++k)
    for (int j = 0; j < 12; ++j)
      for (int i = 0; i < 11; ++i) p.push_back({0.5 * i - 2.0, 0.5 * j, 0.5 * k + 1.0});
  clouds.push_back({"cell_boundaries", cloud_from(p), 1.0});
  return clouds;
}

}  // namespace sphnl::test
