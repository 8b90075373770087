#include "sphnl/neighbours/verlet_list.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <stdexcept>
#include <string>

namespace sphnl {

namespace {

// Candidates of buffer entry i among entries (i, total): r^2 < radius2 and not
// two boundary particles. Pairs at r^2 <= 1e-18 are kept: they may separate
// during the life of the list; the loop's filter_list drops them while they
// coincide.
template <class Emit>
std::uint32_t list_candidates(const ParticleView& v, std::uint32_t i, std::uint32_t total, double radius2, Emit&& emit) {
  const double xi = v.x[i], yi = v.y[i], zi = v.z[i], fi = v.is_fluid[i];
  std::uint32_t n = 0;
  for (std::uint32_t j = i + 1; j < total; ++j) {
    const double dx = xi - v.x[j], dy = yi - v.y[j], dz = zi - v.z[j];
    const double r2 = dx * dx + dy * dy + dz * dz;
    if (r2 < radius2 && fi + v.is_fluid[j] > 0.0) {
      emit(n, j);
      ++n;
    }
  }
  return n;
}

std::array<std::vector<double>*, 13> accumulators(ParticleSet& ps) {
  return {&ps.ax, &ps.ay, &ps.az, &ps.drho, &ps.ux, &ps.uy, &ps.uz,
          &ps.kgc_m[0], &ps.kgc_m[1], &ps.kgc_m[2], &ps.kgc_m[3], &ps.kgc_m[4], &ps.kgc_m[5]};
}

std::pair<int, int> accumulator_slots(unsigned outputs) {
  return {(outputs & fields::force_out) ? 0 : 7, (outputs & fields::kgc_m_out) ? 13 : 7};
}

}  // namespace

void VerletList::build(const ParticleGrid& pg, ParticleSet& ps, double list_radius2, int threads) {
  const std::size_t n = ps.size();
  // 1. count the candidates of every particle (offsets_[i + 1] holds i's count)
  offsets_.assign(n + 1, 0);
  std::uint32_t* counts = offsets_.data() + 1;
  sweep_.run(pg.grid(), pg.order(), pg.gridder(), ps, fields::position, threads,
             [&](int, CellSweep::Scratch& s, std::uint32_t n_home) {
               const ParticleView v = s.buffer.view();
               const std::uint32_t total = s.buffer.size();
               const std::uint32_t* global = s.buffer.index();
               for (std::uint32_t i = 0; i < n_home; ++i)
                 counts[global[i]] = list_candidates(v, i, total, list_radius2, [](std::uint32_t, std::uint32_t) {});
             });
  // 2. prefix sum
  std::uint64_t sum = 0;
  std::uint32_t longest = 0;
  for (std::size_t i = 0; i < n; ++i) {
    longest = std::max(longest, offsets_[i + 1]);
    sum += offsets_[i + 1];
    if (sum > std::numeric_limits<std::uint32_t>::max())
      throw std::runtime_error("Verlet list holds more than 2^32 candidate pairs (" + std::to_string(n) +
                               " particles); use list=cll or a smaller list_steps / skin_factor");
    offsets_[i + 1] = static_cast<std::uint32_t>(sum);
  }
  max_count_ = longest;
  // 3. fill (capacity is kept between builds: no allocation once it has grown)
  neighbours_.resize(sum);
  std::uint32_t* nb = neighbours_.data();
  const std::uint32_t* off = offsets_.data();
  sweep_.run(pg.grid(), pg.order(), pg.gridder(), ps, fields::position, threads,
             [&](int, CellSweep::Scratch& s, std::uint32_t n_home) {
               const ParticleView v = s.buffer.view();
               const std::uint32_t total = s.buffer.size();
               const std::uint32_t* global = s.buffer.index();
               for (std::uint32_t i = 0; i < n_home; ++i) {
                 std::uint32_t* out = nb + off[global[i]];
                 list_candidates(v, i, total, list_radius2, [&](std::uint32_t k, std::uint32_t j) { out[k] = global[j]; });
               }
             });
}

void VerletList::prepare_loop(ParticleSet& ps, unsigned outputs, int threads) {
  if (static_cast<int>(scratch_.size()) < threads) scratch_.resize(threads);
  const std::uint32_t n = offsets_.empty() ? 0 : static_cast<std::uint32_t>(offsets_.size() - 1);
  if (n != ps.size()) throw std::logic_error("VerletList used before build() for the current particle set");
  const auto [first, last] = accumulator_slots(outputs);
  const std::uint64_t total = pairs();
  for (int t = 0; t < threads; ++t) {
    Scratch& s = scratch_[t];
    // room for a whole SIMD store past the last survivor (filter_list compacts 8 lanes at a time)
    if (s.survivors.size() < max_count_ + 16u) s.survivors.resize(max_count_ + 16u);
    // Thread t takes the particles whose lists start in its share of the pairs.
    auto split = [&](int k) {
      const std::uint64_t target = total * static_cast<std::uint64_t>(k) / static_cast<std::uint64_t>(threads);
      if (k == threads) return n;
      return static_cast<std::uint32_t>(std::lower_bound(offsets_.begin(), offsets_.end() - 1, target) - offsets_.begin());
    };
    s.begin = split(t);
    s.end = split(t + 1);
    s.view = ParticleView::of(ps);
    if (t == 0 || !outputs) continue;
    double* __restrict* dst[13] = {&s.view.ax, &s.view.ay, &s.view.az, &s.view.drho, &s.view.ux, &s.view.uy,
                                   &s.view.uz, &s.view.m_kgc[0], &s.view.m_kgc[1], &s.view.m_kgc[2],
                                   &s.view.m_kgc[3], &s.view.m_kgc[4], &s.view.m_kgc[5]};
    for (int a = first; a < last; ++a) {
      s.acc[a].assign(ps.size(), 0.0);
      *dst[a] = s.acc[a].data();
    }
  }
}

void VerletList::reduce(ParticleSet& ps, unsigned outputs, int threads) {
  const auto [first, last] = accumulator_slots(outputs);
  auto acc = accumulators(ps);
  const std::size_t n = ps.size();
  for (int t = 1; t < threads; ++t)
    for (int a = first; a < last; ++a) {
      double* __restrict dst = acc[a]->data();
      const double* __restrict src = scratch_[t].acc[a].data();
      for (std::size_t i = 0; i < n; ++i) dst[i] += src[i];
    }
}

std::size_t VerletList::list_bytes() const {
  return (offsets_.capacity() + neighbours_.capacity()) * sizeof(std::uint32_t);
}

std::size_t VerletList::bytes() const {
  std::size_t b = list_bytes() + sweep_.bytes();
  for (const auto& s : scratch_) {
    b += s.survivors.capacity() * sizeof(std::uint32_t);
    for (const auto& a : s.acc) b += a.capacity() * sizeof(double);
  }
  return b;
}

}  // namespace sphnl
