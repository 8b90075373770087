#pragma once
// ParticleView: raw pointers to the fields the pair loops read and write. It
// points either at the global ParticleSet (Verlet lists) or at a small
// cell-gather buffer (cell-linked list), so one pair kernel serves both.
#include <cstdint>

#include "sphnl/particles.hpp"

namespace sphnl {

struct ParticleView {
  // read
  const double* __restrict x = nullptr;
  const double* __restrict y = nullptr;
  const double* __restrict z = nullptr;
  const double* __restrict vx = nullptr;
  const double* __restrict vy = nullptr;
  const double* __restrict vz = nullptr;
  const double* __restrict rho = nullptr;
  const double* __restrict mass = nullptr;
  const double* __restrict p_over_rho2 = nullptr;
  const double* __restrict tensile_r = nullptr;
  const double* __restrict sound_speed = nullptr;
  const double* __restrict is_fluid = nullptr;
  const double* __restrict kgc[6] = {};  // L_a, only read by the corrected kernel
  // accumulate
  double* __restrict ax = nullptr;
  double* __restrict ay = nullptr;
  double* __restrict az = nullptr;
  double* __restrict drho = nullptr;
  double* __restrict ux = nullptr;
  double* __restrict uy = nullptr;
  double* __restrict uz = nullptr;
  double* __restrict m_kgc[6] = {};      // M_a accumulated by the KGC pre-pass

  static ParticleView of(ParticleSet& ps) {
    ParticleView v;
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
}  // namespace fields
}  // namespace sphnl
