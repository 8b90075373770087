#include "sphnl/neighbours/cell_sweep.hpp"

#include <algorithm>

namespace sphnl {

namespace {
// Accumulator arrays of a ParticleSet in the order of Scratch::acc.
std::array<std::vector<double>*, 13> accumulators(ParticleSet& ps) {
  return {&ps.ax, &ps.ay, &ps.az, &ps.drho, &ps.ux, &ps.uy, &ps.uz,
          &ps.kgc_m[0], &ps.kgc_m[1], &ps.kgc_m[2], &ps.kgc_m[3], &ps.kgc_m[4], &ps.kgc_m[5]};
}
std::pair<int, int> slots(unsigned outputs) {
  const int first = (outputs & fields::force_out) ? 0 : 7;
  const int last = (outputs & fields::kgc_m_out) ? 13 : 7;
  return {first, last};
}
}  // namespace

void CellSweep::prepare(const Gridder& gridder, ParticleSet& ps, unsigned mask, int threads) {
  if (static_cast<int>(scratch_.size()) < threads) scratch_.resize(threads);
  const std::size_t capacity = 14 * static_cast<std::size_t>(gridder.max_cell_count()) + kFilterSlack;
  const unsigned outputs = mask & (fields::force_out | fields::kgc_m_out);
  const auto [first, last] = slots(outputs);
  for (int t = 0; t < threads; ++t) {
    Scratch& s = scratch_[t];
    if (s.cell_index.size() < capacity) {
      s.cell_index.resize(capacity);
      s.survivors.resize(capacity);
      s.buffer.reserve(capacity);
    }
    s.target = ParticleView::of(ps);
    if (t == 0 || !outputs) continue;
    // Threads other than 0 accumulate privately; zeroed here, summed in reduce().
    double* __restrict* dst[13] = {&s.target.ax, &s.target.ay, &s.target.az, &s.target.drho, &s.target.ux, &s.target.uy,
                        &s.target.uz, &s.target.m_kgc[0], &s.target.m_kgc[1], &s.target.m_kgc[2],
                        &s.target.m_kgc[3], &s.target.m_kgc[4], &s.target.m_kgc[5]};
    for (int a = first; a < last; ++a) {
      s.acc[a].assign(ps.size(), 0.0);
      *dst[a] = s.acc[a].data();
    }
  }
}

void CellSweep::reduce(ParticleSet& ps, unsigned outputs, int threads) {
  const auto [first, last] = slots(outputs);
  auto acc = accumulators(ps);
  for (int t = 1; t < threads; ++t)
    for (int a = first; a < last; ++a) {
      double* __restrict dst = acc[a]->data();
      const double* __restrict src = scratch_[t].acc[a].data();
      const std::size_t n = ps.size();
      for (std::size_t i = 0; i < n; ++i) dst[i] += src[i];
    }
}

std::size_t CellSweep::bytes() const {
  std::size_t b = 0;
  for (const auto& s : scratch_) {
    b += s.buffer.bytes() + (s.cell_index.capacity() + s.survivors.capacity()) * sizeof(std::uint32_t);
    for (const auto& a : s.acc) b += a.capacity() * sizeof(double);
  }
  return b;
}

}  // namespace sphnl
