#pragma once
// The small dam-break configuration of the simulation tests.
#include "sphnl/config.hpp"

namespace sphnl::test {

/// The dam break of paper §2.2 with `particles` particles (3000 by default: a
/// few seconds for a few hundred steps), no progress line.
inline RunConfig small_dam_break_config(long particles = 3000) {
  RunConfig c;
  c.particles = particles;
  c.progress = false;
  return c;
}

}  // namespace sphnl::test
