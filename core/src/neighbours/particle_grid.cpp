#include "sphnl/neighbours/particle_grid.hpp"

namespace sphnl {

ParticleGrid::ParticleGrid(const Box& domain, CellOrderKind order, GridderKind gridder, const GridderOptions& options,
                           double period_y)
    : domain_(domain), period_y_(period_y), order_(make_cell_order(order)), gridder_(make_gridder(gridder, options)) {}

bool ParticleGrid::build(ParticleSet& ps, double cell_size, bool reorder, std::size_t owned) {
  // Verlet lists change 2H at every rebuild; the domain stays.
  GridRequest request;
  request.box = domain_;
  request.min_side = cell_size;
  request.period_y = period_y_;
  ghost_begin_ = owned < ps.size() ? static_cast<std::uint32_t>(owned) : ~std::uint32_t{0};
  fit_grid(request, grid_, *order_);
  sort_.place(grid_, *order_, *gridder_, ps.x, ps.y, ps.z, ps.type.data(), threads_);
  if (!reorder) return false;

  sort_.sort(*gridder_, owned);  // a distributed run: owned particles first, ghosts last
  if (inner_order_ == InnerOrder::morton) sort_.order_within_cells(grid_, ps.x, ps.y, ps.z);
  ps.permute(sort_.permutation(), f64_scratch_, u32_scratch_, threads_);
  sort_.permute_keys();
  gridder_->renumber(sort_.inverse_permutation());
  return true;
}

std::size_t ParticleGrid::bytes() const {
  return gridder_->bytes() + order_->bytes() + sort_.bytes() + u32_scratch_.capacity() * sizeof(std::uint32_t) +
         f64_scratch_.capacity() * sizeof(double);
}

}  // namespace sphnl
