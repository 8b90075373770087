#pragma once
// The particles of every rank at rank 0, for outputs: snapshots and the
// summary of a distributed run are written by rank 0 alone, in id order as a
// serial run writes them.
#include <cstddef>

#include "sphnl/parallel/communicator.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

/// Rank 0 gets the owned particles [0, owned) of every rank, sorted by id,
/// with the fields snapshots hold (x, v, rho, pressure, type, id; mass too);
/// the other ranks get an empty set. Collective: every rank must call it.
ParticleSet gather_particles(Communicator& comm, const ParticleSet& ps, std::size_t owned);

}  // namespace sphnl
