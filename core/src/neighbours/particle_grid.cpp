#include "sphnl/neighbours/particle_grid.hpp"

#include <stdexcept>
#include <string>

namespace sphnl {

ParticleGrid::ParticleGrid(const Box& domain, CellOrderKind order, GridderKind gridder, const GridderOptions& options,
                           double period_y)
    : domain_(domain), period_y_(period_y), order_(make_cell_order(order)), gridder_(make_gridder(gridder, options)) {}

bool ParticleGrid::build(ParticleSet& ps, double cell_size, bool reorder, std::size_t owned) {
  if (cell_size != grid_.cell_size) {  // Verlet lists change 2H at every rebuild
    grid_ = CellGrid(domain_, cell_size, period_y_);
    if (period_y_ > 0 && grid_.n[1] < CellGrid::kMinPeriodicCells)
      throw std::invalid_argument("a periodic y of " + std::to_string(period_y_) + " m holds " +
                                  std::to_string(grid_.n[1]) + " cells of " + std::to_string(cell_size) +
                                  " m; it must hold at least 3: widen the slab to >= 3 cell sizes (6h)");
    order_->setup(grid_);
  }
  keys_.resize(ps.size());
  order_->compute_keys(grid_, ps, keys_);
  gridder_->build(keys_, order_->num_keys());
  if (!reorder) return false;

  // New index -> old index: gridded particles in cell order, then the out ones.
  gridder_->cell_order_permutation(permutation_);
  if (owned < ps.size()) {
    // Ghosts after the owned particles, both in cell order (stable).
    keys_scratch_.clear();
    u32_scratch_.clear();
    for (const std::uint32_t i : permutation_) (i < owned ? u32_scratch_ : keys_scratch_).push_back(i);
    permutation_.assign(u32_scratch_.begin(), u32_scratch_.end());
    u32_scratch_.clear();
  }
  for (std::size_t i = 0; i < ps.size(); ++i)
    if (keys_[i] == kNoCell) permutation_.push_back(static_cast<std::uint32_t>(i));
  if (owned < ps.size()) permutation_.insert(permutation_.end(), keys_scratch_.begin(), keys_scratch_.end());
  ps.permute(permutation_, f64_scratch_, u32_scratch_);
  keys_scratch_.resize(keys_.size());
  for (std::size_t k = 0; k < keys_.size(); ++k) keys_scratch_[k] = keys_[permutation_[k]];
  keys_.swap(keys_scratch_);
  // keys_scratch_ is free again: use it for the inverse permutation.
  for (std::size_t k = 0; k < permutation_.size(); ++k) keys_scratch_[permutation_[k]] = static_cast<std::uint32_t>(k);
  gridder_->renumber(keys_scratch_);
  return true;
}

std::size_t ParticleGrid::bytes() const {
  return gridder_->bytes() + order_->bytes() +
         (keys_.capacity() + permutation_.capacity() + keys_scratch_.capacity() + u32_scratch_.capacity()) *
             sizeof(std::uint32_t) +
         f64_scratch_.capacity() * sizeof(double);
}

}  // namespace sphnl
