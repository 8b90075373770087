#include "sphnl/neighbours/cell_buffer.hpp"

#include <algorithm>

namespace sphnl {

namespace {
// Field slots in CellBuffer::arrays_.
enum Slot : int {
  X, Y, Z, IS_FLUID, MASS, RHO, VX, VY, VZ, PR, TR, C,
  L0, L1, L2, L3, L4, L5,
  AX, AY, AZ, DRHO, UX, UY, UZ,
  M0, M1, M2, M3, M4, M5,
  NUM_SLOTS
};

template <class T>
void gather_field(double* __restrict dst, const T* __restrict src, const std::uint32_t* __restrict index, std::uint32_t n) {
  for (std::uint32_t k = 0; k < n; ++k) dst[k] = src[index[k]];
}
template <class T>
void scatter_field(double* __restrict dst, const T* __restrict src, const std::uint32_t* __restrict index, std::uint32_t n) {
  for (std::uint32_t k = 0; k < n; ++k) dst[index[k]] += static_cast<double>(src[k]);
}
void to_float(float* __restrict dst, const double* __restrict src, double origin, std::uint32_t n) {
  for (std::uint32_t k = 0; k < n; ++k) dst[k] = static_cast<float>(src[k] - origin);
}

/// Sizes one array per slot to `capacity` and points `view` at them.
template <class T>
void allocate_slots(std::vector<std::vector<T>>& arrays, std::size_t capacity, BasicParticleView<T>& view) {
  arrays.resize(NUM_SLOTS);
  for (auto& a : arrays) a.resize(capacity);
  auto p = [&arrays](int s) { return arrays[s].data(); };
  view.x = p(X); view.y = p(Y); view.z = p(Z); view.is_fluid = p(IS_FLUID);
  view.mass = p(MASS); view.rho = p(RHO); view.vx = p(VX); view.vy = p(VY); view.vz = p(VZ);
  view.p_over_rho2 = p(PR); view.tensile_r = p(TR); view.sound_speed = p(C);
  view.ax = p(AX); view.ay = p(AY); view.az = p(AZ); view.drho = p(DRHO);
  view.ux = p(UX); view.uy = p(UY); view.uz = p(UZ);
  for (int k = 0; k < 6; ++k) { view.kgc[k] = p(L0 + k); view.m_kgc[k] = p(M0 + k); }
}
}  // namespace

void CellBuffer::reserve(std::size_t capacity) {
  if (capacity <= index_.size()) return;
  index_.resize(capacity);
  allocate_slots(arrays_, capacity, view_);
  if (!float_arrays_.empty()) allocate_slots(float_arrays_, capacity, float_view_);  // precision=mixed in use
}

void CellBuffer::fill_float(unsigned mask) {
  if (float_arrays_.empty()) allocate_slots(float_arrays_, index_.size(), float_view_);
  if (size_ == 0) return;
  auto f = [&](int slot, double origin = 0) {
    to_float(float_arrays_[slot].data(), arrays_[slot].data(), origin, size_);
  };
  f(X, arrays_[X][0]); f(Y, arrays_[Y][0]); f(Z, arrays_[Z][0]); f(IS_FLUID);
  if (mask & (fields::mass_rho | fields::force_in)) { f(MASS); f(RHO); }
  if (mask & fields::force_in) {
    f(VX); f(VY); f(VZ); f(PR); f(TR); f(C);
  }
  if (mask & fields::kgc_l)
    for (int k = 0; k < 6; ++k) f(L0 + k);
  if (mask & fields::force_out)
    for (int s = AX; s <= UZ; ++s) std::fill_n(float_arrays_[s].data(), size_, 0.0f);
}

void CellBuffer::gather(const ParticleSet& ps, const std::uint32_t* index, std::uint32_t count, unsigned mask) {
  size_ = count;
  if (index != index_.data()) std::copy(index, index + count, index_.data());
  const std::uint32_t* idx = index_.data();
  auto g = [&](int slot, const std::vector<double>& src) { gather_field(arrays_[slot].data(), src.data(), idx, count); };
  auto zero = [&](int slot) { std::fill_n(arrays_[slot].data(), count, 0.0); };
  g(X, ps.x); g(Y, ps.y); g(Z, ps.z); g(IS_FLUID, ps.is_fluid);
  if (mask & (fields::mass_rho | fields::force_in)) { g(MASS, ps.mass); g(RHO, ps.rho); }
  if (mask & fields::force_in) {
    g(VX, ps.vx); g(VY, ps.vy); g(VZ, ps.vz);
    g(PR, ps.p_over_rho2); g(TR, ps.tensile_r); g(C, ps.sound_speed);
  }
  if (mask & fields::kgc_l)
    for (int k = 0; k < 6; ++k) g(L0 + k, ps.kgc[k]);
  if (mask & fields::force_out)
    for (int s = AX; s <= UZ; ++s) zero(s);
  if (mask & fields::kgc_m_out)
    for (int s = M0; s <= M5; ++s) zero(s);
}

void CellBuffer::shift_y(std::uint32_t begin, std::uint32_t end, double shift) {
  double* y = arrays_[Y].data();
  for (std::uint32_t k = begin; k < end; ++k) y[k] += shift;
}

void CellBuffer::scatter_add(const ParticleView& t, unsigned mask) const {
  const std::uint32_t* idx = index_.data();
  auto s = [&](double* dst, int slot) {
    if (slot >= AX && slot <= UZ && (mask & fields::float_copy))
      scatter_field(dst, float_arrays_[slot].data(), idx, size_);
    else
      scatter_field(dst, arrays_[slot].data(), idx, size_);
  };
  if (mask & fields::force_out) {
    s(t.ax, AX); s(t.ay, AY); s(t.az, AZ); s(t.drho, DRHO);
    s(t.ux, UX); s(t.uy, UY); s(t.uz, UZ);
  }
  if (mask & fields::kgc_m_out)
    for (int k = 0; k < 6; ++k) s(t.m_kgc[k], M0 + k);
}

std::size_t CellBuffer::bytes() const {
  std::size_t b = index_.capacity() * sizeof(std::uint32_t);
  for (const auto& a : arrays_) b += a.capacity() * sizeof(double);
  for (const auto& a : float_arrays_) b += a.capacity() * sizeof(float);
  return b;
}

}  // namespace sphnl
