#pragma once
// Particle data as a structure of arrays (SoA): the pair loops read a handful
// of fields of many particles, so each field is its own contiguous array.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace sphnl {

enum class ParticleType : std::uint8_t {
  fluid = 0,
  boundary = 1,  // dynamic boundary particle (Crespo et al. 2007): density evolves, never moves
  out = 2,       // fluid particle that left the domain or the density window; parked, no interactions
};

struct ParticleSet {
  // --- state carried between steps (permuted by reordering) ---
  std::vector<double> x, y, z;
  std::vector<double> vx, vy, vz;
  std::vector<double> rho;
  std::vector<double> vx_prev, vy_prev, vz_prev, rho_prev;  // Verlet level n-1
  std::vector<double> mass;
  std::vector<ParticleType> type;
  std::vector<std::uint32_t> id;  // original particle id: outputs are reported by id
  std::vector<double> is_fluid;   // 1.0 for fluid, 0.0 otherwise: a branch-free mask for the pair loop

  // --- derived each step from rho (equation of state, eq. 5) ---
  std::vector<double> pressure;       // P
  std::vector<double> sound_speed;    // c = c0 (rho/rho0)^3
  std::vector<double> p_over_rho2;    // P / rho^2 (eq. 2)
  std::vector<double> tensile_r;      // R of Monaghan's tensile correction

  // --- accumulated by the pair loop each step ---
  std::vector<double> ax, ay, az;     // dv/dt
  std::vector<double> drho;           // drho/dt (eq. 4)
  std::vector<double> ux, uy, uz;     // XSPH velocity correction (eq. 6)

  // --- kernel gradient correction (Bonet & Lok 1999), symmetric 3x3 stored as
  //     xx, xy, xz, yy, yz, zz: M_a accumulated by the pre-pass, L_a = M_a^-1 ---
  std::vector<double> kgc_m[6];
  std::vector<double> kgc[6];

  std::size_t size() const { return x.size(); }
  void resize(std::size_t n);
  /// Clears the pair-loop accumulators (dv/dt, drho/dt, XSPH).
  void clear_accumulators();
  /// Applies `order` (new index -> old index) to every state array; `scratch`
  /// is reused between calls so that reordering does not allocate. `threads`
  /// split each array's copy (the same bits for any count).
  void permute(std::span<const std::uint32_t> order, std::vector<double>& scratch,
               std::vector<std::uint32_t>& scratch_u32, int threads = 1);
  /// Bytes allocated by the particle arrays (capacity x element size).
  std::size_t bytes() const;
  std::size_t count(ParticleType t) const;
};

}  // namespace sphnl
