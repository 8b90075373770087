#include "sphnl/particles.hpp"

#include "sphnl/permutation.hpp"

#include <algorithm>

namespace sphnl {

namespace {
template <class F>
void for_each_f64_state(ParticleSet& ps, F&& f) {
  for (auto* v : {&ps.x, &ps.y, &ps.z, &ps.vx, &ps.vy, &ps.vz, &ps.rho, &ps.vx_prev, &ps.vy_prev, &ps.vz_prev,
                  &ps.rho_prev, &ps.mass, &ps.is_fluid, &ps.pressure, &ps.sound_speed, &ps.p_over_rho2,
                  &ps.tensile_r})
    f(*v);
}
template <class F>
void for_each_f64_scratch(ParticleSet& ps, F&& f) {
  for (auto* v : {&ps.ax, &ps.ay, &ps.az, &ps.drho, &ps.ux, &ps.uy, &ps.uz}) f(*v);
  for (auto& v : ps.kgc_m) f(v);
  for (auto& v : ps.kgc) f(v);
}
}  // namespace

void ParticleSet::resize(std::size_t n) {
  for_each_f64_state(*this, [n](std::vector<double>& v) { v.resize(n, 0.0); });
  for_each_f64_scratch(*this, [n](std::vector<double>& v) { v.resize(n, 0.0); });
  type.resize(n, ParticleType::fluid);
  id.resize(n, 0);
}

void ParticleSet::clear_accumulators() {
  for (auto* v : {&ax, &ay, &az, &drho, &ux, &uy, &uz}) std::fill(v->begin(), v->end(), 0.0);
}

void ParticleSet::permute(std::span<const std::uint32_t> order, std::vector<double>& scratch,
                          std::vector<std::uint32_t>& scratch_u32, int threads) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(order.size());
  for_each_f64_state(*this, [&](std::vector<double>& v) {
    gather_by<double>(v, order, scratch, threads);
    v.swap(scratch);
  });
  gather_by<std::uint32_t>(id, order, scratch_u32, threads);
  id.swap(scratch_u32);
  // type is one byte per particle: permute through the u32 scratch
#pragma omp parallel num_threads(threads) if (threads > 1)
  {
#pragma omp for schedule(static)
    for (std::ptrdiff_t k = 0; k < n; ++k) scratch_u32[k] = static_cast<std::uint32_t>(type[order[k]]);
#pragma omp for schedule(static)
    for (std::ptrdiff_t k = 0; k < n; ++k) type[k] = static_cast<ParticleType>(scratch_u32[k]);
  }
}

std::size_t ParticleSet::bytes() const {
  std::size_t b = 0;
  auto& self = const_cast<ParticleSet&>(*this);
  for_each_f64_state(self, [&](std::vector<double>& v) { b += v.capacity() * sizeof(double); });
  for_each_f64_scratch(self, [&](std::vector<double>& v) { b += v.capacity() * sizeof(double); });
  return b + type.capacity() + id.capacity() * sizeof(std::uint32_t);
}

std::size_t ParticleSet::count(ParticleType t) const {
  return static_cast<std::size_t>(std::count(type.begin(), type.end(), t));
}

}  // namespace sphnl
