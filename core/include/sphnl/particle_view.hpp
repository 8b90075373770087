#pragma once
// ParticleView: raw pointers to the fields the pair loops read and write. It
// points either at the global ParticleSet (Verlet lists) or at a small
// cell-gather buffer (cell-linked list), so one pair kernel serves both.
// ParticleViewF is the same in float: the cell-gather buffer's float copy
// for precision=mixed (positions relative to the buffer's first entry).
#include <cstdint>
#include <type_traits>

#include "sphnl/particles.hpp"

namespace sphnl {

template <class T>
struct BasicParticleView {
  // read
  const T* __restrict x = nullptr;
  const T* __restrict y = nullptr;
  const T* __restrict z = nullptr;
  const T* __restrict vx = nullptr;
  const T* __restrict vy = nullptr;
  const T* __restrict vz = nullptr;
  const T* __restrict rho = nullptr;
  const T* __restrict mass = nullptr;
  const T* __restrict p_over_rho2 = nullptr;
  const T* __restrict tensile_r = nullptr;
  const T* __restrict sound_speed = nullptr;
  const T* __restrict is_fluid = nullptr;
  const T* __restrict kgc[6] = {};  // L_a, only read by the corrected kernel
  // accumulate
  T* __restrict ax = nullptr;
  T* __restrict ay = nullptr;
  T* __restrict az = nullptr;
  T* __restrict drho = nullptr;
  T* __restrict ux = nullptr;
  T* __restrict uy = nullptr;
  T* __restrict uz = nullptr;
  T* __restrict m_kgc[6] = {};      // M_a accumulated by the KGC pre-pass

  static BasicParticleView of(ParticleSet& ps)
    requires std::is_same_v<T, double>
  {
    BasicParticleView v;
    v.x = ps.x.data(); v.y = ps.y.data(); v.z = ps.z.data();
    v.vx = ps.vx.data(); v.vy = ps.vy.data(); v.vz = ps.vz.data();
    v.rho = ps.rho.data(); v.mass = ps.mass.data();
    v.p_over_rho2 = ps.p_over_rho2.data(); v.tensile_r = ps.tensile_r.data();
    v.sound_speed = ps.sound_speed.data(); v.is_fluid = ps.is_fluid.data();
    v.ax = ps.ax.data(); v.ay = ps.ay.data(); v.az = ps.az.data(); v.drho = ps.drho.data();
    v.ux = ps.ux.data(); v.uy = ps.uy.data(); v.uz = ps.uz.data();
    for (int k = 0; k < 6; ++k) { v.kgc[k] = ps.kgc[k].data(); v.m_kgc[k] = ps.kgc_m[k].data(); }
    return v;
  }
};

using ParticleView = BasicParticleView<double>;
using ParticleViewF = BasicParticleView<float>;

}  // namespace sphnl

namespace sphnl {
/// Which fields a pair operation reads and accumulates, so that a cell-gather
/// buffer copies only those.
namespace fields {
inline constexpr unsigned position = 1u;     // x, y, z, is_fluid (always needed by the filter)
inline constexpr unsigned mass_rho = 2u;     // mass, rho
inline constexpr unsigned force_in = 4u;     // v, p_over_rho2, tensile_r, sound_speed (+ mass_rho)
inline constexpr unsigned kgc_l = 8u;        // L_a
inline constexpr unsigned force_out = 16u;   // ax, ay, az, drho, ux, uy, uz
inline constexpr unsigned kgc_m_out = 32u;   // M_a
// A float copy of the read fields (positions relative to the buffer's first
// entry) and float accumulators for force_out, for a pair operation that
// reads ParticleViewF (precision=mixed on the cell-linked list).
inline constexpr unsigned float_copy = 64u;
}  // namespace fields
}  // namespace sphnl
