#pragma once
// PairOperation: what a pair source (cell-linked list, Verlet list) requires of
// the operation it runs on pairs. The force (ForceOp), the KGC pre-pass
// (KgcMatrixOp) and the tests' recorders all meet it:
//
//   kFields   the particle fields (fields::...) the operation reads and writes;
//             the cell sweep gathers only those, and scatters back the outputs.
//   interact(view, i, js, n)
//             particle i with js[0..n), all distinct, every pair with
//             1e-18 < r^2 < (2h)^2 and not boundary-boundary; each unordered
//             pair is handed over once, so the operation applies it to both.
//   interact_blocks(view, i, first, lanes, blocks)    (optional)
//             the same pairs as blocks of kPairBlock consecutive entries with
//             a lane mask (pair_loop=masked, filter_blocks); an operation
//             without it is handed the blocks' pairs as a list.
#include <concepts>
#include <cstdint>

#include "sphnl/particle_view.hpp"

namespace sphnl {

template <class Op>
concept PairOperation = requires(Op& op, const ParticleView& v, std::uint32_t i, const std::uint32_t* js, int n) {
  { Op::kFields } -> std::convertible_to<unsigned>;
  op.interact(v, i, js, n);
};

template <class Op, class View>
concept BlockPairOperation = requires(Op& op, const View& v, std::uint32_t i, const std::uint32_t* first,
                                      const std::uint8_t* lanes, int blocks) {
  op.interact_blocks(v, i, first, lanes, blocks);
};

}  // namespace sphnl
