// An SPH density sum with for_each_pair: rho_i = sum_j m W(|x_i - x_j|, h)
// over a cubic lattice of spacing dx with the 3-D cubic spline (Monaghan
// 1992; support 2h), no neighbour list stored. Deep inside the lattice
// rho must be close to m / dx^3 (the kernel is normalised).
#include <sphnl/search.hpp>

#include <cmath>
#include <cstdio>
#include <vector>

namespace {
double cubic_spline(double r, double h) {
  const double q = r / h, sigma = 1.0 / (M_PI * h * h * h);
  if (q < 1) return sigma * (1 - 1.5 * q * q + 0.75 * q * q * q);
  if (q < 2) return sigma * 0.25 * (2 - q) * (2 - q) * (2 - q);
  return 0;
}
}  // namespace

int main() {
  const int side = 20;
  const double dx = 0.01, h = 1.3 * dx, mass = 1000.0 * dx * dx * dx;  // water, 1000 kg/m^3
  std::vector<double> x, y, z;
  for (int k = 0; k < side; ++k)
    for (int j = 0; j < side; ++j)
      for (int i = 0; i < side; ++i) x.push_back(i * dx), y.push_back(j * dx), z.push_back(k * dx);
  const std::size_t n = x.size();

  sphnl::Search search(2 * h);
  search.build(x, y, z);
  std::vector<double> rho(n, mass * cubic_spline(0, h));  // self contribution
  search.for_each_pair([&](std::uint32_t i, std::uint32_t j) {
    const double r = std::hypot(x[i] - x[j], y[i] - y[j], z[i] - z[j]);
    const double w = mass * cubic_spline(r, h);
    rho[i] += w;
    rho[j] += w;
  });
  const std::size_t centre = (side / 2) * side * side + (side / 2) * side + side / 2;
  const double error = std::fabs(rho[centre] - 1000.0) / 1000.0;
  std::printf("%zu particles, h = %.4f: rho(centre) = %.2f kg/m^3, rho(corner) = %.2f kg/m^3\n", n, h, rho[centre], rho[0]);
  std::printf("relative error at the centre %.4f (limit 0.02)\n", error);
  const bool ok = error < 0.02 && rho[0] < 0.5 * rho[centre];
  std::printf("%s\n", ok ? "ok" : "WRONG DENSITY");
  return ok ? 0 : 1;
}
