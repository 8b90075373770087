// sphnl_ranks of a build without MPI: every run is serial.
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "sphnl/ranks.hpp"

namespace sphnl {

bool mpi_built() { return false; }

std::unique_ptr<Communicator> start_ranks() {
  const char* size = std::getenv("OMPI_COMM_WORLD_SIZE");
  if (!size) size = std::getenv("PMI_SIZE");
  if (started_by_launcher() && !(size && std::string(size) == "1"))
    throw std::runtime_error(
        "this sphnl was built without MPI, so it cannot run on several ranks (every rank would run the whole "
        "case alone); install MPI (Debian: apt-get install libopenmpi-dev openmpi-bin, or `make deps`) and rebuild "
        "(cmake -DSPHNL_MPI=ON), or run without mpirun");
  return nullptr;
}

}  // namespace sphnl
