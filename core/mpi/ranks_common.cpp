#include <cstdlib>

#include "sphnl/ranks.hpp"

namespace sphnl {

bool started_by_launcher() {
  for (const char* v : {"OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK"})
    if (std::getenv(v) != nullptr) return true;
  return false;
}

}  // namespace sphnl
