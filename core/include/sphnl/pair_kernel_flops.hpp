#pragma once
// Floating-point operations per pair of the pair operations (pair_kernel.hpp,
// kgc.hpp), counted by hand from their source as written: the roofline
// position of the force phase (docs/PERFORMANCE.md, which lists the count line
// by line). Change the count when the kernel's arithmetic changes.
//
// Rules: every +, -, * of the loop body is one operation, both pieces of the
// cubic spline are counted (the vectorised loop evaluates both and selects),
// and nothing is removed that the compiler may merge or hoist (the two
// `t = 2 - q`, `0.25 a2`, `m_b * pterm` used three times): the count is that
// of the source, not of the instructions. Comparisons, max, |x|, negation and
// selects are not counted. A division and a square root count one each
// (they cost far more than one FMA slot: docs/PERFORMANCE.md).
namespace sphnl {

struct PairFlops {
  int adds = 0, muls = 0, divs = 0, sqrts = 0;
  constexpr int total() const { return adds + muls + divs + sqrts; }
  constexpr PairFlops operator+(const PairFlops& o) const {
    return {adds + o.adds, muls + o.muls, divs + o.divs, sqrts + o.sqrts};
  }
};

/// ForceOp<false>::interact, per pair (eqs. 1-4, 6).
inline constexpr PairFlops kForcePairFlops{40, 72, 3, 1};
/// What ForceOp<true> adds per pair: L_a grad_a W_ab and L_b grad_b W_ba (two 3x3 products).
inline constexpr PairFlops kForceKgcExtraFlops{12, 18, 0, 0};
/// KgcMatrixPass::interact, per pair (the KGC pre-pass and each extra loop).
inline constexpr PairFlops kKgcMatrixPairFlops{19, 29, 2, 1};

/// Flops of the force phase per pair evaluated: the main loop, with KGC its
/// corrected gradients and the pre-pass, and `extra_loops` more M_a passes.
constexpr int force_phase_flops_per_pair(bool kgc, int extra_loops) {
  int f = kForcePairFlops.total();
  if (kgc) f += kForceKgcExtraFlops.total() + kKgcMatrixPairFlops.total();
  return f + extra_loops * kKgcMatrixPairFlops.total();
}

static_assert(kForcePairFlops.total() == 116 && kKgcMatrixPairFlops.total() == 51);

}  // namespace sphnl
