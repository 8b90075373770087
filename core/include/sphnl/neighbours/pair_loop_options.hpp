#pragma once
// PairLoopOptions: the ablation switches of the pair passes (README.md,
// "Ablations"; the RunConfig keys of the same names). Pair sources read them
// once per pass and run a template instantiation for the choice, so nothing
// is decided per pair.
#include "sphnl/kinds.hpp"

namespace sphnl {

struct PairLoopOptions {
  PairLoopKind loop = PairLoopKind::gather;  // cell-linked list: gather buffers, or cells read in place
  bool simd = true;                          // false: the scalar distance filter
  bool skip_boundary_pairs = false;          // cell sweep (gather): no boundary-boundary candidate is tested
  ThreadUpdates updates = ThreadUpdates::private_accumulators;  // threads > 1: private copies or phases
  ThreadSplit split = ThreadSplit::fluid;  // threads > 1: the cell-linked list's home cells by fluid, by pair work, or dynamic
};

}  // namespace sphnl
