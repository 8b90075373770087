// Neighbour lists of a random point cloud with sphnl's public API, checked
// against a brute-force count; also a query of a second point set.
#include <sphnl/search.hpp>

#include <cstdio>
#include <random>
#include <vector>

int main() {
  const std::size_t n = 2000;
  const double radius = 0.08;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x(n), y(n), z(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = u(rng), y[i] = u(rng), z[i] = u(rng);

  sphnl::Search search(radius);  // gridder B, cells in sort_x order, reordering on
  search.build(x, y, z);
  const sphnl::CompressedRows rows = search.rows(sphnl::Rows::full);

  std::size_t brute = 0;  // ordered pairs (i, j), i != j, closer than radius
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      const double dx = x[i] - x[j], dy = y[i] - y[j], dz = z[i] - z[j];
      brute += i != j && dx * dx + dy * dy + dz * dz < radius * radius;
    }
  std::printf("points %zu radius %.2f entries %zu brute force %zu\n", n, radius, rows.indices.size(), brute);
  std::printf("point 0 has %lld neighbours\n", static_cast<long long>(rows.offsets[1] - rows.offsets[0]));

  const std::vector<double> qx{0.5}, qy{0.5}, qz{0.5};
  const sphnl::CompressedRows near = search.query(qx, qy, qz);
  std::printf("query (0.5, 0.5, 0.5): %zu points within radius\n", near.indices.size());
  const bool ok = rows.indices.size() == brute && rows.offsets.size() == n + 1;
  std::printf("%s\n", ok ? "ok" : "MISMATCH");
  return ok ? 0 : 1;
}
