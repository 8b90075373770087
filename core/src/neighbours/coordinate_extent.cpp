#include "sphnl/neighbours/coordinate_extent.hpp"

#include <algorithm>
#include <vector>

namespace sphnl {

CoordinateExtent coordinate_extent(std::span<const double> a) {
  if (a.empty()) return {};
  const double* const v = a.data();
  const std::size_t n = a.size();
  double lo = v[0], hi = v[0], nan_if_bad = 0;
  // The simd reductions let the compiler reorder the minima, maxima and sum
  // into lanes, which it may not do for a plain loop (no -ffast-math here).
#pragma omp simd reduction(min : lo) reduction(max : hi) reduction(+ : nan_if_bad)
  for (std::size_t i = 0; i < n; ++i) {
    lo = v[i] < lo ? v[i] : lo;
    hi = v[i] > hi ? v[i] : hi;
    nan_if_bad += v[i] * 0.0;
  }
  return {lo, hi, nan_if_bad == 0};
}

CoordinateExtents coordinate_extents(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                                     int threads) {
  CoordinateExtents out{};
  const std::size_t n = x.size();
  if (n == 0) return out;
  constexpr std::size_t kMinPerThread = 65536;  // below, starting a team costs more than it saves
  const int team =
      static_cast<int>(std::clamp<std::size_t>(n / kMinPerThread, 1, static_cast<std::size_t>(std::max(1, threads))));
  const double* coords[3] = {x.data(), y.data(), z.data()};
  std::vector<CoordinateExtent> part(static_cast<std::size_t>(team) * 3);
#pragma omp parallel for num_threads(team) schedule(static) if (team > 1)
  for (int t = 0; t < team; ++t) {
    const std::size_t b = n * static_cast<std::size_t>(t) / static_cast<std::size_t>(team);
    const std::size_t e = n * static_cast<std::size_t>(t + 1) / static_cast<std::size_t>(team);
    for (int d = 0; d < 3; ++d)
      part[static_cast<std::size_t>(t) * 3 + d] = coordinate_extent(std::span<const double>(coords[d] + b, e - b));
  }
  for (int d = 0; d < 3; ++d) out[d] = part[d];
  for (std::size_t k = 3; k < part.size(); ++k) {
    CoordinateExtent& o = out[k % 3];
    o.lo = std::min(o.lo, part[k].lo);
    o.hi = std::max(o.hi, part[k].hi);
    o.finite = o.finite && part[k].finite;
  }
  return out;
}

}  // namespace sphnl
