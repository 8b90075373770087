#include "sphnl/parallel/decomposition.hpp"

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <string>

#include "sphnl/neighbours/stencil.hpp"

namespace sphnl {

KeyPartition KeyPartition::balanced(std::span<const double> weights, int ranks) {
  const std::size_t n = weights.size();
  if (ranks < 1) throw std::invalid_argument("a partition needs at least one rank");
  if (static_cast<std::size_t>(ranks) > n)
    throw std::invalid_argument(std::to_string(ranks) + " ranks for " + std::to_string(n) +
                                " cells: every rank must own at least one cell");
  const double total = std::accumulate(weights.begin(), weights.end(), 0.0);
  std::vector<std::uint32_t> begins(static_cast<std::size_t>(ranks) + 1, static_cast<std::uint32_t>(n));
  begins[0] = 0;
  double running = 0;
  int r = 1;
  for (std::size_t key = 0; key < n && r < ranks; ++key) {
    running += weights[key];
    while (r < ranks && running >= total * r / ranks) begins[r++] = static_cast<std::uint32_t>(key + 1);
  }
  // Every rank keeps at least one key (with no weight at all, or a weight in
  // one key, the cuts above pile up): spread the cuts over the remaining keys.
  for (int q = 1; q < ranks; ++q) begins[q] = std::max(begins[q], begins[q - 1] + 1);
  for (int q = ranks - 1; q >= 1; --q)
    begins[q] = std::min<std::uint32_t>(begins[q], static_cast<std::uint32_t>(n - (ranks - q)));
  return KeyPartition(std::move(begins));
}

int KeyPartition::owner(std::uint32_t key) const {
  // The last rank whose range begins at or before `key` (empty ranges skipped).
  const auto it = std::upper_bound(begin_.begin(), begin_.end() - 1, key);
  return static_cast<int>(it - begin_.begin()) - 1;
}

std::vector<double> KeyPartition::rank_weights(std::span<const double> weights) const {
  std::vector<double> w(ranks(), 0.0);
  for (int r = 0; r < ranks(); ++r)
    for (std::uint32_t k = begin(r); k < end(r) && k < weights.size(); ++k) w[r] += weights[k];
  return w;
}

double imbalance(std::span<const double> rank_weights) {
  if (rank_weights.empty()) return 0;
  const double total = std::accumulate(rank_weights.begin(), rank_weights.end(), 0.0);
  if (total <= 0) return 0;
  const double mean = total / static_cast<double>(rank_weights.size());
  return *std::max_element(rank_weights.begin(), rank_weights.end()) / mean - 1.0;
}

void Decomposition::ghost_destinations(std::uint32_t key, std::vector<int>& out) const {
  out.clear();
  const std::uint64_t c = order_->key_coords()[key];
  if (c == CellOrder::kNoCellCoords) return;
  const int home = partition_->owner(key);
  for_each_stencil_cell(*grid_, *order_, CellOrder::unpack_coords(c), kFullStencil, [&](std::uint32_t k, double) {
    const int r = partition_->owner(k);
    if (r != home) out.push_back(r);
  });
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

std::vector<std::uint32_t> Decomposition::halo_cells(int rank) const {
  std::vector<std::uint32_t> halo;
  const auto coords = order_->key_coords();
  for (std::uint32_t key = partition_->begin(rank); key < partition_->end(rank); ++key) {
    if (coords[key] == CellOrder::kNoCellCoords) continue;
    for_each_stencil_cell(*grid_, *order_, CellOrder::unpack_coords(coords[key]), kFullStencil,
                          [&](std::uint32_t k, double) {
                            if (partition_->owner(k) != rank) halo.push_back(k);
                          });
  }
  std::sort(halo.begin(), halo.end());
  halo.erase(std::unique(halo.begin(), halo.end()), halo.end());
  return halo;
}

std::vector<int> Decomposition::partners(int rank) const {
  std::vector<int> out;
  for (const std::uint32_t key : halo_cells(rank)) out.push_back(partition_->owner(key));
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace sphnl
