// Gridder C, the static matrix (paper §2.3): fixed rows of MaxPartsInCell.
#include "sphnl/gridders/static_matrix.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "sphnl/input_error.hpp"

namespace sphnl {

StaticMatrix::StaticMatrix(const GridderOptions& options) {
  if (options.max_parts_in_cell < 0)
    throw ConfigError("max_parts_in_cell must be >= 0 (0 = sized from h/dx), got " +
                      std::to_string(options.max_parts_in_cell));
  const int rows = options.max_parts_in_cell > 0 ? options.max_parts_in_cell : default_max_parts_in_cell(options);
  max_parts_ = static_cast<std::uint32_t>(rows);
}

void StaticMatrix::build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) {
  num_keys_ = num_keys;
  const std::size_t n = cell_key.size();
  n_parts_in_cell_.assign(num_keys, 0);
  if (max_parts_ == 0) {
    // No lattice to size from (a bare point cloud): twice the fullest cell of the first build.
    for (std::size_t i = 0; i < n; ++i)
      if (cell_key[i] != kNoCell) ++n_parts_in_cell_[cell_key[i]];
    const std::uint32_t fullest = num_keys ? *std::max_element(n_parts_in_cell_.begin(), n_parts_in_cell_.end()) : 0;
    max_parts_ = std::max(1u, 2 * fullest);
    std::fill(n_parts_in_cell_.begin(), n_parts_in_cell_.end(), 0u);
  }
  parts_in_cell_.resize(std::size_t{num_keys} * max_parts_);
  const std::uint32_t row = max_parts_;
  std::uint32_t* parts = parts_in_cell_.data();
  std::uint32_t* count = n_parts_in_cell_.data();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t c = cell_key[i];
    if (c == kNoCell) continue;
    const std::uint32_t slot = count[c]++;
    if (slot < row) parts[std::size_t{c} * row + slot] = static_cast<std::uint32_t>(i);
  }
  std::uint32_t max_count = 0, fullest_key = 0;
  for (std::uint32_t k = 0; k < num_keys; ++k)
    if (count[k] > max_count) { max_count = count[k]; fullest_key = k; }
  max_cell_count_ = max_count;
  if (max_count > row)
    throw std::runtime_error("gridder C (static matrix): cell " + std::to_string(fullest_key) + " holds " +
                             std::to_string(max_count) + " particles, more than MaxPartsInCell = " +
                             std::to_string(row) + "; raise the config key max_parts_in_cell (e.g. --set "
                             "max_parts_in_cell=" + std::to_string(2 * max_count) + ") or use gridder B");
}
}  // namespace sphnl
