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
}  // namespace

void CellBuffer::reserve(std::size_t capacity) {
  if (capacity <= index_.size()) return;
  index_.resize(capacity);
  arrays_.resize(NUM_SLOTS);
  for (auto& a : arrays_) a.resize(capacity);
  auto p = [this](int s) { return arrays_[s].data(); };
  view_.x = p(X); view_.y = p(Y); view_.z = p(Z); view_.is_fluid = p(IS_FLUID);
  view_.mass = p(MASS); view_.rho = p(RHO); view_.vx = p(VX); view_.vy = p(VY); view_.vz = p(VZ);
  view_.p_over_rho2 = p(PR); view_.tensile_r = p(TR); view_.sound_speed = p(C);
  view_.ax = p(AX); view_.ay = p(AY); view_.az = p(AZ); view_.drho = p(DRHO);
  view_.ux = p(UX); view_.uy = p(UY); view_.uz = p(UZ);
  for (int k = 0; k < 6; ++k) { view_.kgc[k] = p(L0 + k); view_.m_kgc[k] = p(M0 + k); }
  if (!float_arrays_.empty()) {
    float_arrays_.clear();  // reallocated at the new capacity by the next fill_float
    float_view_ = ParticleViewF{};
  }
}

void CellBuffer::fill_float(unsigned mask) {
  if (float_arrays_.empty()) {
    float_arrays_.resize(NUM_SLOTS);
    for (auto& a : float_arrays_) a.resize(index_.size());
    auto p = [this](int s) { return float_arrays_[s].data(); };
    ParticleViewF& v = float_view_;
    v.x = p(X); v.y = p(Y); v.z = p(Z); v.is_fluid = p(IS_FLUID);
    v.mass = p(MASS); v.rho = p(RHO); v.vx = p(VX); v.vy = p(VY); v.vz = p(VZ);
    v.p_over_rho2 = p(PR); v.tensile_r = p(TR); v.sound_speed = p(C);
    v.ax = p(AX); v.ay = p(AY); v.az = p(AZ); v.drho = p(DRHO);
    v.ux = p(UX); v.uy = p(UY); v.uz = p(UZ);
    for (int k = 0; k < 6; ++k) { v.kgc[k] = p(L0 + k); v.m_kgc[k] = p(M0 + k); }
  }
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
