#include "sphnl/neighbours/thread_phases.hpp"

#include <algorithm>

#include "sphnl/neighbours/stencil.hpp"

namespace sphnl {

namespace {
constexpr std::uint8_t kExport = 1, kForeign = 2, kContested = 4, kSerial = 8;
}  // namespace

void cut_key_ranges(std::span<const double> weight, int threads, std::vector<std::uint32_t>& begin) {
  const auto num_keys = static_cast<std::uint32_t>(weight.size());
  begin.assign(static_cast<std::size_t>(threads) + 1, num_keys);
  begin[0] = 0;
  double total = 0;
  for (double w : weight) total += w;
  double running = 0;
  int t = 1;
  for (std::uint32_t key = 0; key < num_keys && t < threads; ++key) {
    running += weight[key];
    while (t < threads && running >= total * t / threads) begin[t++] = key + 1;
  }
}

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
  occupied_.clear();
  for (int t = 0; t < threads; ++t)
    for (std::uint32_t key = thread_begin[t]; key < thread_begin[t + 1]; ++key)
      if (weight[key] > 0) {
        owner_[key] = static_cast<std::int16_t>(t);
        occupied_.push_back(key);
      }
  // The write set of every occupied home cell, walked once: itself and its
  // occupied forward cells. Exports, and the foreign cells they write.
  write_begin_.resize(occupied_.size() + 1);
  writes_.clear();
  for (std::size_t o = 0; o < occupied_.size(); ++o) {
    const std::uint32_t key = occupied_[o];
    write_begin_[o] = static_cast<std::uint32_t>(writes_.size());
    writes_.push_back(key);
    for_each_stencil_cell(grid, order, CellOrder::unpack_coords(coords[key]), kHalfStencil,
                          [&](std::uint32_t k, double) {
                            if (owner_[k] < 0) return;
                            writes_.push_back(k);
                            if (owner_[k] != owner_[key]) {
                              state_[key] |= kExport;
                              state_[k] |= kForeign;
                            }
                          });
  }
  write_begin_[occupied_.size()] = static_cast<std::uint32_t>(writes_.size());
  auto writes_of = [&](std::size_t o) {
    return std::span<const std::uint32_t>(writes_.data() + write_begin_[o], write_begin_[o + 1] - write_begin_[o]);
  };
  // Phase 1 must hold no two exports of different threads writing one cell;
  // an export that would meet one goes to the serial list. Contested cells:
  // own-only cells that write a foreign cell.
  std::vector<double> contested(threads, 0.0);
  for (std::size_t o = 0; o < occupied_.size(); ++o) {
    const std::uint32_t key = occupied_[o];
    const std::int16_t t = owner_[key];
    const auto w = writes_of(o);
    if (state_[key] & kExport) {
      const bool clash = std::any_of(w.begin(), w.end(), [&](std::uint32_t c) { return stamp_[c] >= 0 && stamp_[c] != t; });
      if (clash) state_[key] |= kSerial;
      else
        for (std::uint32_t c : w) stamp_[c] = t;
    } else if (std::any_of(w.begin(), w.end(), [&](std::uint32_t c) { return (state_[c] & kForeign) != 0; })) {
      state_[key] |= kContested;
      contested[t] += weight[key];
    }
  }
  // Even out the phases: every thread fills phase 2 up to the largest
  // contested load with its first free own-only cells (free: neither export
  // nor contested, so it may run in either phase).
  const double phase2 = *std::max_element(contested.begin(), contested.end());
  std::vector<double> moved(threads, 0.0);
  for (const std::uint32_t key : occupied_) {
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
  std::size_t b = (serial_.capacity() + occupied_.capacity() + write_begin_.capacity() + writes_.capacity()) *
                      sizeof(std::uint32_t) +
                  (owner_.capacity() + stamp_.capacity()) * sizeof(std::int16_t) + state_.capacity();
  for (const auto& k : keys_) b += k.capacity() * sizeof(std::uint32_t);
  return b;
}

}  // namespace sphnl
