#pragma once
// What both variants of gridder A (paper §2.3, sliding dynamic vector) share:
// the name and the stored arrays (cells_begin_gridder.hpp). They differ only
// in how build() inserts (sliding_vector.hpp, sliding_vector_shift_all.hpp).
#include "sphnl/gridders/cells_begin_gridder.hpp"

namespace sphnl {

class SlidingVectorBase : public CellsBeginGridder {
 public:
  const char* name() const override { return "A"; }
};

}  // namespace sphnl
