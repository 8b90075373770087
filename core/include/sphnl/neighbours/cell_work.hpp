#pragma once
// The estimated pair work of a cell, from the fluid and boundary particles of
// it and of the cells around it: the weights that cut the cell keys into
// equal shares of work, for ranks (parallel/decomposition.hpp) and for the
// threads of a cell sweep (neighbours/cell_sweep.hpp).
#include <cstdint>
#include <span>

#include "sphnl/grid.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

/// Estimated pair work of each key in [key_begin, key_end), the weights that
/// balance ranks by interactions (BalanceBy::interactions). With cells of side
/// >= the interaction radius a cell's particles meet those of the 27 cells
/// around it (itself included), and every such candidate pair costs a
/// distance test and, inside the radius, the pair kernel; boundary-boundary
/// pairs never reach the kernel, so
///   w_k = f_k (F_k + B_k) + b_k F_k,
/// f_k and b_k the fluid and boundary particles of cell k, F_k and B_k those
/// of its stencil (wrapped across a periodic y seam). A pair counts in both of
/// its cells, as a pair across a rank boundary is computed on both sides.
/// `fluid` and `boundary` hold the counts per key; every out[k] of the range
/// is written, the others are left as they are.
void interaction_weights(const CellGrid& grid, const CellOrder& order, std::span<const double> fluid,
                         std::span<const double> boundary, std::uint32_t key_begin, std::uint32_t key_end,
                         std::span<double> out);

/// The candidate pairs of each key as a cell sweep's home cell (CellSweep:
/// the pairs inside the cell and with its 13 forward cells, kHalfStencil),
/// without the boundary-boundary ones, which never reach the kernel:
///   w_k = f_k (f_k - 1) / 2 + f_k b_k + sum over forward j of f_k (f_j + b_j) + b_k f_j.
/// Every candidate pair lies in exactly one home cell's sum, so a key range's
/// total is the candidates its thread tests and hands on, the weights that
/// balance threads (ThreadSplit::interactions). All keys are written.
void sweep_pair_work(const CellGrid& grid, const CellOrder& order, std::span<const double> fluid,
                     std::span<const double> boundary, std::span<double> out);

}  // namespace sphnl
