#pragma once
// Gridder D, "linked list" (paper §2.3, Fig. 4): head[cell] is the first
// particle of the cell, next[particle] the following particle of the same
// cell (kEnd closes the list). Building touches each particle once and needs
// no count; reading a cell chases pointers through scattered memory.
#include <algorithm>

#include "sphnl/gridders/gridder.hpp"
#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

class LinkedList final : public Gridder {
 public:
  static constexpr std::uint32_t kEnd = 0xFFFFFFFFu;
  const char* name() const override { return "D"; }

  void build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) override {
    num_keys_ = num_keys;
    const std::size_t n = cell_key.size();
    head_.assign(num_keys, kEnd);
    next_.resize(n);
    // Pushing at the head, walking the particles backwards: every list then
    // holds its particles in increasing index, the order gridders A-C use, so
    // all gridders sum pair contributions in the same order.
    for (std::size_t i = n; i-- > 0;) {
      const std::uint32_t c = cell_key[i];
      if (c == kNoCell) continue;
      next_[i] = head_[c];
      head_[c] = static_cast<std::uint32_t>(i);
    }
    // Longest list (sizes the sweep's buffers): one walk of the lists.
    std::uint32_t max_count = 0;
    for (std::uint32_t k = 0; k < num_keys; ++k) {
      std::uint32_t count = 0;
      for (std::uint32_t p = head_[k]; p != kEnd; p = next_[p]) ++count;
      max_count = std::max(max_count, count);
    }
    max_cell_count_ = max_count;
  }

  std::uint32_t gather_cell(std::uint32_t key, std::uint32_t* out) const override {
    std::uint32_t count = 0;
    for (std::uint32_t p = head_[key]; p != kEnd; p = next_[p]) out[count++] = p;
    return count;
  }

  void cell_order_permutation(std::vector<std::uint32_t>& order) const override {
    order.resize(0);
    for (std::uint32_t k = 0; k < num_keys_; ++k)
      for (std::uint32_t p = head_[k]; p != kEnd; p = next_[p]) order.push_back(p);
  }

  void renumber(std::span<const std::uint32_t> new_index_of_old) override {
    // next is indexed by particle: move every link to the particle's new slot.
    scratch_.resize(next_.size());
    for (std::uint32_t k = 0; k < num_keys_; ++k) {
      if (head_[k] == kEnd) continue;
      for (std::uint32_t p = head_[k]; p != kEnd; p = next_[p])
        scratch_[new_index_of_old[p]] = next_[p] == kEnd ? kEnd : new_index_of_old[next_[p]];
      head_[k] = new_index_of_old[head_[k]];
    }
    next_.swap(scratch_);
  }

  std::size_t bytes() const override {
    return (head_.capacity() + next_.capacity() + scratch_.capacity()) * sizeof(std::uint32_t);
  }

 private:
  std::vector<std::uint32_t> head_;  // first particle of each cell
  std::vector<std::uint32_t> next_;  // next particle of the same cell
  std::vector<std::uint32_t> scratch_;  // next_ being renumbered after reordering
};

}  // namespace sphnl
