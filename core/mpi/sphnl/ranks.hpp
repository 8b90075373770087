#pragma once
// Starting the ranks of a distributed run: `mpirun -np P sphnl run ...` (or
// srun) starts P processes; each asks here for its communicator. Built as the
// library sphnl_ranks, against MPI when CMake found it (SPHNL_MPI), else
// without: then a launch of more than one rank is refused with the fix.
#include <memory>
#include <string>

#include "sphnl/parallel/communicator.hpp"

namespace sphnl {

/// True when this build can run on several ranks (built with MPI).
bool mpi_built();

/// Whether a launcher (mpirun, mpiexec, srun) started this process: it sets
/// OMPI_COMM_WORLD_RANK, PMI_RANK or PMIX_RANK.
bool started_by_launcher();

/// The communicator of this process's ranks: null for a serial run (no
/// launcher, or a launch of one rank, which then runs exactly as without one).
/// Initialises MPI when a launcher started the process; MPI is finalised when
/// the returned communicator is destroyed. Throws std::runtime_error when a
/// launcher started this process but the build has no MPI.
std::unique_ptr<Communicator> start_ranks();

}  // namespace sphnl
