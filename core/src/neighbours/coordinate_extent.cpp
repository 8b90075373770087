#include "sphnl/neighbours/coordinate_extent.hpp"

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

}  // namespace sphnl
