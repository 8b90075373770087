#pragma once
// Gridder C, "static matrix" (paper §2.3, Fig. 3): PartsInCell has one row of
// MaxPartsInCell slots per cell and NPartsInCell the fill of each row. Every
// cell pays for a full row whether it holds particles or not, which is why C
// needs the most memory in Fig. 7. MaxPartsInCell is "externally fixed": a cell
// that overflows its row stops the run with an error naming the cell, its count
// and the option to raise; particles are never dropped.
#include <algorithm>
#include <cstdint>
#include <string>

#include "sphnl/gridders/gridder.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

class StaticMatrix final : public Gridder {
 public:
  /// `max_parts_in_cell` > 0 fixes the row length; 0 sizes it from the
  /// options' lattice (default_max_parts_in_cell) or, when they give none,
  /// from twice the fullest cell of the first build.
  explicit StaticMatrix(const GridderOptions& options);
  const char* name() const override { return "C"; }

  void build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) override;

  std::uint32_t gather_cell(std::uint32_t key, std::uint32_t* out) const override {
    const std::uint32_t count = n_parts_in_cell_[key];
    const std::uint32_t* row = parts_in_cell_.data() + std::size_t{key} * max_parts_;
    std::copy(row, row + count, out);
    return count;
  }

  std::span<const std::uint32_t> cell_members(std::uint32_t key, std::uint32_t*) const override {
    return {parts_in_cell_.data() + std::size_t{key} * max_parts_, n_parts_in_cell_[key]};
  }

  void cell_order_permutation(std::vector<std::uint32_t>& order) const override {
    order.resize(0);
    for (std::uint32_t k = 0; k < num_keys_; ++k) {
      const std::uint32_t* row = parts_in_cell_.data() + std::size_t{k} * max_parts_;
      order.insert(order.end(), row, row + n_parts_in_cell_[k]);
    }
  }

  void renumber(std::span<const std::uint32_t> new_index_of_old) override {
    for (std::uint32_t k = 0; k < num_keys_; ++k) {
      std::uint32_t* row = parts_in_cell_.data() + std::size_t{k} * max_parts_;
      for (std::uint32_t s = 0; s < n_parts_in_cell_[k]; ++s) row[s] = new_index_of_old[row[s]];
    }
  }

  std::size_t bytes() const override {
    return (parts_in_cell_.capacity() + n_parts_in_cell_.capacity()) * sizeof(std::uint32_t);
  }

  /// Row length in use (0 before the first build when sized from data).
  std::uint32_t max_parts_in_cell() const { return max_parts_; }

 private:
  std::uint32_t max_parts_ = 0;                 // MaxPartsInCell
  std::vector<std::uint32_t> parts_in_cell_;    // PartsInCell[cell * MaxPartsInCell + slot]
  std::vector<std::uint32_t> n_parts_in_cell_;  // NPartsInCell[cell]
};

}  // namespace sphnl
