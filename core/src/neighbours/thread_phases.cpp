#include "sphnl/neighbours/thread_phases.hpp"

#include <algorithm>

#include "sphnl/neighbours/stencil.hpp"

namespace sphnl {

namespace {
constexpr std::uint8_t kExport = 1, kForeign = 2, kContested = 4, kSerial = 8;
}  // namespace

void ThreadPhases::plan(const CellGrid& grid, const CellOrder& order, std::span<const std::uint32_t> thread_begin,
                        std::span<const double> weight, int threads) {
  threads_ = threads;
  keys_.resize(static_cast<std::size_t>(kParallelPhases * threads));
  for (auto& k : keys_) k.clear();
  serial_.clear();
  const std::uint32_t num_keys = order.num_keys();
  const std::uint64_t* coords = order.key_coords().data();
  owner_.assign(num_keys, -1);
  state_.assign(num_keys, 0);
  stamp_.assign(num_keys, -1);
  for (int t = 0; t < threads; ++t)
    for (std::uint32_t key = thread_begin[t]; key < thread_begin[t + 1]; ++key)
      if (weight[key] > 0) owner_[key] = static_cast<std::int16_t>(t);

  // The write set of home cell `key`: itself and its occupied forward cells.
  auto write_set = [&](std::uint32_t key) {
    writes_.clear();
    writes_.push_back(key);
    for_each_stencil_cell(grid, order, CellOrder::unpack_coords(coords[key]), kHalfStencil,
                          [&](std::uint32_t k, double) {
                            if (owner_[k] >= 0) writes_.push_back(k);
                          });
  };
  // Exports, and the foreign cells they write.
  for (std::uint32_t key = 0; key < num_keys; ++key) {
    if (owner_[key] < 0) continue;
    write_set(key);
    for (std::uint32_t w : writes_)
      if (owner_[w] != owner_[key]) {
        state_[key] |= kExport;
        state_[w] |= kForeign;
      }
  }
  // Phase 1 must hold no two exports of different threads writing one cell;
  // an export that would meet one goes to the serial list. Contested cells:
  // own-only cells that write a foreign cell.
  std::vector<double> contested(threads, 0.0);
  for (std::uint32_t key = 0; key < num_keys; ++key) {
    if (owner_[key] < 0) continue;
    const std::int16_t t = owner_[key];
    write_set(key);
    if (state_[key] & kExport) {
      const bool clash = std::any_of(writes_.begin(), writes_.end(), [&](std::uint32_t w) { return stamp_[w] >= 0 && stamp_[w] != t; });
      if (clash) state_[key] |= kSerial;
      else
        for (std::uint32_t w : writes_) stamp_[w] = t;
    } else if (std::any_of(writes_.begin(), writes_.end(), [&](std::uint32_t w) { return (state_[w] & kForeign) != 0; })) {
      state_[key] |= kContested;
      contested[t] += weight[key];
    }
  }
  // Even out the phases: every thread fills phase 2 up to the largest
  // contested load with its first free own-only cells (free: neither export
  // nor contested, so it may run in either phase).
  const double phase2 = *std::max_element(contested.begin(), contested.end());
  std::vector<double> moved(threads, 0.0);
  for (std::uint32_t key = 0; key < num_keys; ++key) {
    if (owner_[key] < 0) continue;
    const int t = owner_[key];
    const std::uint8_t s = state_[key];
    if (s & kSerial) {
      serial_.push_back(key);
    } else if (s & kExport) {
      keys_[t].push_back(key);
    } else if (s & kContested) {
      keys_[threads + t].push_back(key);
    } else if (contested[t] + moved[t] + weight[key] <= phase2) {
      keys_[threads + t].push_back(key);
      moved[t] += weight[key];
    } else {
      keys_[t].push_back(key);
    }
  }
}

std::size_t ThreadPhases::bytes() const {
  std::size_t b = serial_.capacity() * sizeof(std::uint32_t) + owner_.capacity() * sizeof(std::int16_t) +
                  state_.capacity() + stamp_.capacity() * sizeof(std::int16_t) + writes_.capacity() * sizeof(std::uint32_t);
  for (const auto& k : keys_) b += k.capacity() * sizeof(std::uint32_t);
  return b;
}

}  // namespace sphnl
