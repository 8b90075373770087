#include "sphnl/neighbours/verlet_list.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <stdexcept>
#include <string>

namespace sphnl {

std::uint32_t* VerletList::IndexBuffer::room(std::size_t more) {
  if (size + more > data.capacity())
    data.grow(std::max(size + more, data.capacity() + data.capacity() / 2 + 1024), size);
  return data.data() + size;
}

template <bool Simd, bool SkipBoundaryPairs>
void VerletList::build_sweep(const ParticleGrid& pg, ParticleSet& ps, double list_radius2, int threads) {
  // One sweep: each home particle's candidates with r < 2H (coincident pairs
  // kept) are appended to its thread's chunk as one row. One thread writes
  // straight into the list: one buffer, which the next build reuses (two
  // alternating buffers would double the list's memory, and the second
  // would be first touched, page by page, at the second build).
  sweep_.run(pg.grid(), pg.order(), pg.gridder(), ps, fields::position, threads,
             [&](int t, CellSweep::Scratch& s, std::uint32_t n_home) {
               Chunk& c = chunks_[t];
               IndexBuffer& list = threads == 1 ? neighbours_ : c.neighbours;
               const ParticleView v = s.buffer.view();
               const std::uint32_t total = s.buffer.size();
               const std::uint32_t* global = s.buffer.index();
               HomeCandidates<Simd, SkipBoundaryPairs> home(v, total, s.fluid_slots, s.first_partner);
               std::uint64_t tested = 0;
               for (std::uint32_t i = 0; i < n_home; ++i) {
                 std::uint32_t* out = list.room(total - i - 1 + kFilterSlack);
                 const int m = home.filter(i, list_radius2, out, tested, -1.0);
                 for (int k = 0; k < m; ++k) out[k] = global[out[k]];
                 list.size += static_cast<std::size_t>(m);
                 c.rows.push_back(global[i]);
                 c.counts.push_back(static_cast<std::uint32_t>(m));
               }
             },
             ThreadUpdates::private_accumulators, pg.ghost_begin());
}

void VerletList::build(const ParticleGrid& pg, ParticleSet& ps, double list_radius2, int threads,
                       const PairLoopOptions& options) {
  const std::size_t n = ps.size();
  if (static_cast<int>(chunks_.size()) < threads) chunks_.resize(threads);
  neighbours_.size = 0;
  for (auto& c : chunks_) {
    c.neighbours.size = 0;
    c.rows.clear();
    c.counts.clear();
  }
  // The build sweep always gathers (pair_loop applies to the cell-linked
  // list's pair pass; the list's own loop reads the particles in place).
  if (options.skip_boundary_pairs) {
    if (options.simd) build_sweep<true, true>(pg, ps, list_radius2, threads);
    else build_sweep<false, true>(pg, ps, list_radius2, threads);
  } else {
    if (options.simd) build_sweep<true, false>(pg, ps, list_radius2, threads);
    else build_sweep<false, false>(pg, ps, list_radius2, threads);
  }
  // Rows in visit order: threads swept contiguous ranges of cells, so their
  // chunks concatenate in thread order. Particles not gridded (out) get empty rows.
  std::size_t pairs = neighbours_.size;  // one thread: the sweep filled the list itself
  if (threads > 1)
    for (int t = 0; t < threads; ++t) pairs += chunks_[t].neighbours.size;
  if (pairs > std::numeric_limits<std::uint32_t>::max())
    throw std::runtime_error("Verlet list holds more than 2^32 candidate pairs (" + std::to_string(n) +
                             " particles); use list=cll or a smaller list_steps / skin_factor");
  if (threads > 1) {
    std::uint32_t* dst = neighbours_.room(pairs);
    for (int t = 0; t < threads; ++t)
      dst = std::copy(chunks_[t].neighbours.data.data(), chunks_[t].neighbours.data.data() + chunks_[t].neighbours.size, dst);
    neighbours_.size = pairs;
  }
  offsets_.resize(n + 1);
  visit_.resize(n);
  visited_.assign(n, 0);
  std::size_t row = 0;
  std::uint32_t sum = 0, longest = 0;
  for (int t = 0; t < threads; ++t)
    for (std::size_t k = 0; k < chunks_[t].rows.size(); ++k, ++row) {
      offsets_[row] = sum;
      visit_[row] = chunks_[t].rows[k];
      visited_[chunks_[t].rows[k]] = 1;
      sum += chunks_[t].counts[k];
      longest = std::max(longest, chunks_[t].counts[k]);
    }
  for (std::size_t i = 0; i < n; ++i)
    if (!visited_[i]) {
      offsets_[row] = sum;
      visit_[row++] = static_cast<std::uint32_t>(i);
    }
  offsets_[n] = sum;
  max_count_ = longest;
  phased_threads_ = 0;
  if (options.updates == ThreadUpdates::phased && threads > 1) plan_phases(pg, threads);
}

void VerletList::plan_phases(const ParticleGrid& pg, int threads) {
  // The build sweep visited the home cells in key order and gave every
  // gridded particle one row, so the rows of cell `key` start at the count of
  // the particles in the cells before it.
  const std::uint32_t num_keys = pg.order().num_keys();
  std::vector<std::uint32_t> idx(pg.gridder().max_cell_count());
  key_row_.resize(static_cast<std::size_t>(num_keys) + 1);
  std::uint32_t row = 0;
  for (std::uint32_t key = 0; key < num_keys; ++key) {
    key_row_[key] = row;
    row += pg.gridder().gather_cell(key, idx.data());
  }
  key_row_[num_keys] = row;
  // The loop's work of a home cell: its list entries, plus one per row (a
  // row is a filter call); > 0 exactly where the cell holds particles, which
  // is what marks the cells a home cell writes. Threads take key ranges of
  // equal work, as the private loop takes row ranges of equal entries.
  loop_weight_.resize(num_keys);
  for (std::uint32_t key = 0; key < num_keys; ++key) {
    const std::uint32_t begin = key_row_[key], end = key_row_[key + 1];
    loop_weight_[key] = static_cast<double>(end - begin) + static_cast<double>(offsets_[end] - offsets_[begin]);
  }
  cut_key_ranges(loop_weight_, threads, loop_begin_);
  phases_.plan(pg.grid(), pg.order(), loop_begin_, loop_weight_, threads);
  auto add = [&](RowRanges& ranges, std::uint32_t key) {
    const std::uint32_t begin = key_row_[key], end = key_row_[key + 1];
    if (!ranges.empty() && ranges.back().second == begin) ranges.back().second = end;
    else ranges.emplace_back(begin, end);
  };
  phase_rows_.resize(static_cast<std::size_t>(ThreadPhases::kParallelPhases * threads));
  for (int p = 0; p < ThreadPhases::kParallelPhases; ++p)
    for (int t = 0; t < threads; ++t) {
      RowRanges& ranges = phase_rows_[static_cast<std::size_t>(p * threads + t)];
      ranges.clear();
      for (const std::uint32_t key : phases_.keys(p, t)) add(ranges, key);
    }
  serial_rows_.clear();
  for (const std::uint32_t key : phases_.serial()) add(serial_rows_, key);
  phased_threads_ = threads;
}

void VerletList::prepare_loop(ParticleSet& ps, unsigned outputs, int threads, bool phased) {
  if (static_cast<int>(scratch_.size()) < threads) scratch_.resize(threads);
  const std::uint32_t n = offsets_.empty() ? 0 : static_cast<std::uint32_t>(offsets_.size() - 1);
  if (n != ps.size()) throw std::logic_error("VerletList used before build() for the current particle set");
  const std::uint64_t total = pairs();
  for (int t = 0; t < threads; ++t) {
    Scratch& s = scratch_[t];
    // room for a whole SIMD store past the last survivor (filter_list compacts 8 lanes at a time)
    if (s.survivors.size() < max_count_ + 16u) s.survivors.resize(max_count_ + 16u);
    // Thread t takes the particles whose lists start in its share of the pairs.
    auto split = [&](int k) {
      const std::uint64_t target = total * static_cast<std::uint64_t>(k) / static_cast<std::uint64_t>(threads);
      if (k == threads) return n;
      return static_cast<std::uint32_t>(std::lower_bound(offsets_.begin(), offsets_.end() - 1, target) - offsets_.begin());
    };
    s.begin = split(t);
    s.end = split(t + 1);
    s.view = ParticleView::of(ps);
    if (t > 0 && outputs && !phased) s.private_acc.attach(s.view, ps.size(), outputs);
  }
}

void VerletList::reduce(ParticleSet& ps, unsigned outputs, int threads) {
  for (int t = 1; t < threads; ++t) scratch_[t].private_acc.add_into(ps, outputs);
}

std::size_t VerletList::list_bytes() const {
  // Entries in use, not capacity: the buffer grows in 1.5x steps and keeps its
  // largest size, so its capacity tells the history of the run (and hides
  // VL_X's smaller skin) rather than what the list needs (Figs. 13, 15).
  return (offsets_.size() + visit_.size() + neighbours_.size) * sizeof(std::uint32_t);
}

std::size_t VerletList::bytes() const {
  std::size_t b = list_bytes() + (neighbours_.data.capacity() - neighbours_.size) * sizeof(std::uint32_t) +
                  sweep_.bytes() + visited_.capacity() + phases_.bytes() +
                  (key_row_.capacity() + loop_begin_.capacity() + serial_rows_.capacity() * 2) * sizeof(std::uint32_t) +
                  loop_weight_.capacity() * sizeof(double);
  for (const auto& r : phase_rows_) b += r.capacity() * 2 * sizeof(std::uint32_t);
  for (const auto& c : chunks_)
    b += (c.neighbours.data.capacity() + c.rows.capacity() + c.counts.capacity()) * sizeof(std::uint32_t);
  for (const auto& s : scratch_) {
    b += s.survivors.capacity() * sizeof(std::uint32_t) + s.private_acc.bytes();
  }
  return b;
}

}  // namespace sphnl
