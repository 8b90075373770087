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
//   interact_candidates(view, i, js, n, support2)    (optional)
//             a Verlet list's stored candidates of i, the distance test
//             (1e-18 < r^2 < support2, as filter_list) made in the loop, the
//             number of pairs returned (pair_loop=masked on a Verlet list); an
//             operation without it is handed the survivors of filter_list.
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "sphnl/particle_view.hpp"

namespace sphnl {

/// The lanes of a j-block: `pair_loop=masked` hands the pair kernel whole
/// blocks of kPairBlock consecutive candidates with a lane mask instead of a
/// compacted list (filter_blocks writes them).
inline constexpr int kPairBlock = 8;

template <class Op>
concept PairOperation = requires(Op& op, const ParticleView& v, std::uint32_t i, const std::uint32_t* js, int n) {
  { Op::kFields } -> std::convertible_to<unsigned>;
  op.interact(v, i, js, n);
};

/// A compacted list's entry as the index of a vector gather. Signed 32 bits:
/// x86 gathers take signed 32-bit indices, so GCC gathers with them directly;
/// from an unsigned 32-bit index it must widen to 64 bits, and for float
/// fields (16 lanes, two vectors of 64-bit indices) it finds no vector type
/// and leaves the whole loop scalar (the compacted loop of precision=mixed
/// was). Particle counts are limited to 2^31 - 1 (Simulation checks).
[[gnu::always_inline]] inline std::int32_t gather_index(std::uint32_t j) { return static_cast<std::int32_t>(j); }

/// Put after a lane lambda's parameters: the lane must be inlined into the
/// vector loop of for_each_block_lane (a call would keep it scalar).
#define SPHNL_INLINE_LANE __attribute__((always_inline))

/// The lanes of an interact_blocks call: lane(p, j, live) for lane p of every
/// block, j its entry, `live` whether it is a pair; each block's lanes form
/// one vector loop (`Simd` = false: kept scalar, the ablation simd=off).
/// `Real` is the lane's arithmetic: the lane index p and the mask bits are
/// integers of its width (BlockLane<Real>), so that one vector of the loop
/// holds one block. GCC sizes a loop's vectors by its narrowest type: with
/// a 32-bit index beside double arithmetic, 512-bit vectors would take 16
/// lanes of index, more than a block's 8, and it fell back to two 256-bit
/// halves per block; a 64-bit index lets it run a double block as one
/// 512-bit vector (docs/PERFORMANCE.md, "One vector per block").
template <class Real>
using BlockLane = std::conditional_t<sizeof(Real) == 8, std::int64_t, std::int32_t>;

template <bool Simd, class Real, class Lane>
[[gnu::always_inline]] inline void for_each_block_lane(const std::uint32_t* __restrict first,
                                                       const std::uint8_t* __restrict lanes, int blocks, Lane&& lane) {
  using Int = BlockLane<Real>;
  // The block width hidden from the optimiser: with a known trip count of 8
  // GCC unrolls the lane loop into scalar code before the vectoriser sees it.
  Int width = kPairBlock;
  asm("" : "+r"(width));
  for (int b = 0; b < blocks; ++b) {
    const std::size_t j0 = first[b];  // size_t: j0 + p must be affine for the vectoriser
    const Int bits = lanes[b];
#pragma omp simd if(simd : Simd)
    for (Int p = 0; p < width; ++p) lane(p, j0 + static_cast<std::size_t>(p), ((bits >> p) & 1) != 0);
  }
}

template <class Op, class View>
concept BlockPairOperation = requires(Op& op, const View& v, std::uint32_t i, const std::uint32_t* first,
                                      const std::uint8_t* lanes, int blocks) {
  op.interact_blocks(v, i, first, lanes, blocks);
};

template <class Op, class View>
concept CandidatePairOperation = requires(Op& op, const View& v, std::uint32_t i, const std::uint32_t* js, int n,
                                          double support2) {
  { op.interact_candidates(v, i, js, n, support2) } -> std::convertible_to<int>;
};

}  // namespace sphnl
