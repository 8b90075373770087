#pragma once
// DistributedNeighbours: what a distributed run adds to the neighbour-list
// phase (RebuildPolicy::prepare), so that the policy's decisions (CLL every
// step, VL_C every C steps, VL_X on a displacement over dh/2) stay in one place
// for serial and distributed runs. DomainExchange implements it; a serial run
// passes none. Particles [0, owned()) are this rank's, the rest are ghosts.
#include <cstddef>

#include "sphnl/neighbours/particle_grid.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

class DistributedNeighbours {
 public:
  virtual ~DistributedNeighbours() = default;
  /// True on every rank when `local` is true on any: VL_X rebuilds everywhere
  /// as soon as one rank's particles moved more than dh/2.
  virtual bool any_rank(bool local) = 0;
  /// Before a grid build with cells of side `cell`: drops the ghosts, moves
  /// particles that left this rank's cells to their owners (rebalancing first
  /// when needed) and appends the ghosts of the new halo.
  virtual void exchange_particles(ParticleSet& ps, double cell) = 0;
  virtual std::size_t owned() const = 0;
  /// After the grid (and list) build: fixes which particles each ghost comes
  /// from until the next build (`permuted`: the build reordered the particles).
  virtual void built(const ParticleGrid& grid, bool permuted, ParticleSet& ps) = 0;
  /// Between builds (Verlet lists): the ghosts' values travel again, the ghost
  /// set stays.
  virtual void refresh_ghosts(ParticleSet& ps) = 0;
};

}  // namespace sphnl
