#include "sphnl/neighbours/cell_work.hpp"

#include "sphnl/neighbours/stencil.hpp"

namespace sphnl {

void interaction_weights(const CellGrid& grid, const CellOrder& order, std::span<const double> fluid,
                         std::span<const double> boundary, std::uint32_t key_begin, std::uint32_t key_end,
                         std::span<double> out) {
  const auto coords = order.key_coords();
  for (std::uint32_t key = key_begin; key < key_end; ++key) {
    if (fluid[key] == 0 && boundary[key] == 0) {
      out[key] = 0;
      continue;
    }
    // A key holding particles is a real cell (no particle maps to a padding key of kNoCellCoords).
    double stencil_fluid = 0, stencil_boundary = 0;
    for_each_stencil_cell(grid, order, CellOrder::unpack_coords(coords[key]), kFullStencil, [&](std::uint32_t k, double) {
      stencil_fluid += fluid[k];
      stencil_boundary += boundary[k];
    });
    out[key] = fluid[key] * (stencil_fluid + stencil_boundary) + boundary[key] * stencil_fluid;
  }
}

void sweep_pair_work(const CellGrid& grid, const CellOrder& order, std::span<const double> fluid,
                     std::span<const double> boundary, std::span<double> out) {
  const auto coords = order.key_coords();
  for (std::uint32_t key = 0; key < out.size(); ++key) {
    const double f = fluid[key], b = boundary[key];
    if (f == 0 && b == 0) {
      out[key] = 0;
      continue;
    }
    double w = 0.5 * f * (f - 1) + f * b;
    for_each_stencil_cell(grid, order, CellOrder::unpack_coords(coords[key]), kHalfStencil,
                          [&](std::uint32_t k, double) { w += f * (fluid[k] + boundary[k]) + b * fluid[k]; });
    out[key] = w;
  }
}

}  // namespace sphnl
