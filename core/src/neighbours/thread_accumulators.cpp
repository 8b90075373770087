#include "sphnl/neighbours/thread_accumulators.hpp"

#include <array>
#include <utility>

namespace sphnl {

namespace {
/// Slots [first, last) of the 13 accumulators that `outputs` names.
std::pair<int, int> slots(unsigned outputs) {
  return {(outputs & fields::force_out) ? 0 : 7, (outputs & fields::kgc_m_out) ? 13 : 7};
}
}  // namespace

void ThreadAccumulators::attach(ParticleView& v, std::size_t n, unsigned outputs) {
  const std::array<double* __restrict*, 13> dst = {&v.ax, &v.ay, &v.az, &v.drho, &v.ux, &v.uy, &v.uz,
                                                    &v.m_kgc[0], &v.m_kgc[1], &v.m_kgc[2], &v.m_kgc[3],
                                                    &v.m_kgc[4], &v.m_kgc[5]};
  const auto [first, last] = slots(outputs);
  for (int a = first; a < last; ++a) {
    acc_[a].assign(n, 0.0);  // capacity is kept: no allocation once grown
    *dst[a] = acc_[a].data();
  }
}

void ThreadAccumulators::add_into(ParticleSet& ps, unsigned outputs) const {
  const std::array<std::vector<double>*, 13> dst = {&ps.ax, &ps.ay, &ps.az, &ps.drho, &ps.ux, &ps.uy, &ps.uz,
                                                     &ps.kgc_m[0], &ps.kgc_m[1], &ps.kgc_m[2], &ps.kgc_m[3],
                                                     &ps.kgc_m[4], &ps.kgc_m[5]};
  const auto [first, last] = slots(outputs);
  const std::size_t n = ps.size();
  for (int a = first; a < last; ++a) {
    double* __restrict d = dst[a]->data();
    const double* __restrict s = acc_[a].data();
    for (std::size_t i = 0; i < n; ++i) d[i] += s[i];
  }
}

std::size_t ThreadAccumulators::bytes() const {
  std::size_t b = 0;
  for (const auto& a : acc_) b += a.capacity() * sizeof(double);
  return b;
}

}  // namespace sphnl
