#pragma once
// Private accumulators of one worker thread. Pair loops update both particles
// of a pair, so two threads may add to the same particle; each thread other
// than the first adds into its own zeroed copy of the accumulator arrays, and
// the copies are summed in thread order afterwards (deterministic results for
// a fixed thread count). Shared by the cell sweep and the Verlet list loop.
#include <cstddef>
#include <vector>

#include "sphnl/particle_view.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

class ThreadAccumulators {
 public:
  /// Points the accumulators of `view` named by `outputs` (fields::force_out,
  /// fields::kgc_m_out) at private arrays of n zeros.
  void attach(ParticleView& view, std::size_t n, unsigned outputs);
  /// Adds the private arrays named by `outputs` into the particles' own.
  void add_into(ParticleSet& ps, unsigned outputs) const;
  std::size_t bytes() const;

 private:
  std::vector<double> acc_[13];  // ax ay az drho ux uy uz, then M_a xx xy xz yy yz zz
};

}  // namespace sphnl
