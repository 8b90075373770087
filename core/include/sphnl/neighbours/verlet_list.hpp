#pragma once
// Verlet list (VL, paper §2.5): for every particle a, the candidates b with
// r_ab < 2H = 2h + dh found at a build; the interaction loop of the following
// steps tests only those candidates against 2h. VL_C and VL_X differ only in
// when the list is rebuilt (Simulation decides); this class builds and walks it.
//
// Storage is compressed sparse rows (count, prefix sum, fill) in the order the
// build sweep visits the particles: a particle's whole forward list comes out
// of the one visit of its home cell, so one sweep builds the list (no counting
// pass). With reordering, visit order is index order. Each unordered pair is
// stored once (in the list of the particle whose home cell the half-stencil
// sweep visits first), as the cell-linked list evaluates each pair once;
// boundary-boundary pairs are never stored. Indices are global particle
// indices: particles are reordered only at builds, so they stay valid for the
// life of the list.
#include <omp.h>

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "sphnl/neighbours/cell_sweep.hpp"
#include "sphnl/neighbours/home_candidates.hpp"
#include "sphnl/neighbours/pair_counts.hpp"
#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/neighbours/pair_loop_options.hpp"
#include "sphnl/neighbours/pair_operation.hpp"
#include "sphnl/neighbours/particle_grid.hpp"
#include "sphnl/neighbours/thread_accumulators.hpp"
#include "sphnl/neighbours/thread_phases.hpp"
#include "sphnl/neighbours/uninit_buffer.hpp"
#include "sphnl/particle_view.hpp"

namespace sphnl {

class VerletList {
 public:
  /// Builds the list from `pg`, gridded with cells of side >= sqrt(list_radius2):
  /// every pair (not boundary-boundary) with r^2 < list_radius2. `options`:
  /// simd and skip_boundary_pairs of the build sweep's filter; updates =
  /// phased (threads > 1) plans the loop's phases on the build's cells.
  void build(const ParticleGrid& pg, ParticleSet& ps, double list_radius2, int threads,
             const PairLoopOptions& options = {});

  /// Runs ops[thread].interact on every listed pair with 1e-18 < r^2 < support2,
  /// on the global particle arrays (once per pair). Threads take contiguous
  /// ranges of particles with equal shares of the list; threads > 0 accumulate
  /// privately and are summed in a fixed order (deterministic for a fixed count).
  /// When the list was built with thread_updates=phased for this thread count,
  /// the rows run instead in the phases of ThreadPhases planned on the build's
  /// cells (a row's pairs lie in its home cell's write set), without copies.
  /// `simd` = false: the scalar distance filter (decided once per pass).
  /// `masked` (pair_loop=masked): a row's stored candidates go to the
  /// operation's interact_candidates whole, the distance test a lane mask in
  /// its vector loop (PairCounts::idle_lanes counts the lanes that are not
  /// pairs); an operation without it takes the filter's survivors.
  template <PairOperation Op>
  PairCounts for_each_pair(ParticleSet& ps, std::vector<Op>& ops, double support2, bool simd = true,
                           bool masked = false) {
    if (masked) return simd ? loop<true, true>(ps, ops, support2) : loop<false, true>(ps, ops, support2);
    return simd ? loop<true, false>(ps, ops, support2) : loop<false, false>(ps, ops, support2);
  }

  /// Stored pairs (each unordered pair once).
  std::uint64_t pairs() const { return offsets_.empty() ? 0 : offsets_.back(); }
  /// Bytes of the list itself: offsets, visit order and neighbour indices in
  /// use (the spare capacity of the growable buffer is in bytes()).
  std::size_t list_bytes() const;
  /// Everything this pair source allocated: the list, build sweep buffers,
  /// loop scratch and private accumulators of threads > 0.
  std::size_t bytes() const;

 private:
  template <bool Simd, bool Masked, PairOperation Op>
  PairCounts loop(ParticleSet& ps, std::vector<Op>& ops, double support2);
  template <bool Simd, bool SkipBoundaryPairs>
  void build_sweep(const ParticleGrid& pg, ParticleSet& ps, double list_radius2, int threads);
  void prepare_loop(ParticleSet& ps, unsigned outputs, int threads, bool phased);
  /// updates=phased: the rows of each thread's home cells per phase (key ranges of equal list work).
  void plan_phases(const ParticleGrid& pg, int threads);
  void reduce(ParticleSet& ps, unsigned outputs, int threads);

  /// Indices appended row by row into an UninitBuffer.
  struct IndexBuffer {
    UninitBuffer<std::uint32_t> data;
    std::size_t size = 0;
    std::uint32_t* room(std::size_t more);  // pointer to `more` writable entries past size
  };

  std::vector<std::uint32_t> offsets_;  // size N + 1: row r is neighbours_[offsets_[r], offsets_[r+1])
  std::vector<std::uint32_t> visit_;    // size N: particle whose list is row r
  IndexBuffer neighbours_;              // candidate indices, rows in visit order
  std::uint32_t max_count_ = 0;         // longest list, sizes the survivor buffers
  CellSweep sweep_;
  struct Chunk {                        // what one thread's share of the build sweep produced
    IndexBuffer neighbours;
    std::vector<std::uint32_t> rows, counts;
  };
  std::vector<Chunk> chunks_;
  std::vector<std::uint8_t> visited_;
  struct Scratch {
    std::vector<std::uint32_t> survivors;
    ThreadAccumulators private_acc;  // threads > 0
    ParticleView view;
    std::uint32_t begin = 0, end = 0;  // rows of this thread
  };
  std::vector<Scratch> scratch_;
  std::vector<PairCounts> counts_;
  // thread_updates=phased: row ranges [first, second) per phase and thread
  // ([phase * threads + thread]), then the serial ones; planned for phased_threads_.
  using RowRanges = std::vector<std::pair<std::uint32_t, std::uint32_t>>;
  ThreadPhases phases_;
  std::vector<RowRanges> phase_rows_;
  RowRanges serial_rows_;
  std::vector<std::uint32_t> key_row_;  // per key: the first row of its home cell
  std::vector<double> loop_weight_;      // per key: rows + list entries of its home cell
  std::vector<std::uint32_t> loop_begin_;  // key ranges of the threads (equal loop_weight_)
  int phased_threads_ = 0;
};

template <bool Simd, bool Masked, PairOperation Op>
PairCounts VerletList::loop(ParticleSet& ps, std::vector<Op>& ops, double support2) {
  const int threads = static_cast<int>(ops.size());
  constexpr unsigned outputs = Op::kFields & (fields::force_out | fields::kgc_m_out);
  const bool phased = outputs != 0 && threads > 1 && phased_threads_ == threads;
  prepare_loop(ps, outputs, threads, phased);
  counts_.assign(threads, PairCounts{});
  const double region_start = omp_get_wtime();
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_get_thread_num();
    Scratch& s = scratch_[t];
    std::uint32_t* survivors = s.survivors.data();
    PairCounts c;
    double start = omp_get_wtime();
    const std::uint32_t* off = offsets_.data();
    const std::uint32_t* nb = neighbours_.data.data();
    auto rows = [&](std::uint32_t begin, std::uint32_t end) {
      for (std::uint32_t r = begin; r < end; ++r) {
        const int n = static_cast<int>(off[r + 1] - off[r]);
        if (n == 0) continue;
        const std::uint32_t i = visit_[r];
        int m = 0;
        if constexpr (Masked && CandidatePairOperation<Op, ParticleView>) {
          m = ops[t].interact_candidates(s.view, i, nb + off[r], n, support2);
          c.idle_lanes += static_cast<std::uint64_t>(n - m);
        } else {
          m = filter_list<Simd>(s.view, i, nb + off[r], n, support2, survivors);
          if (m > 0) ops[t].interact(s.view, i, survivors, m);
        }
        c.candidates += static_cast<std::uint64_t>(n);
        c.interactions += static_cast<std::uint64_t>(m);
      }
    };
    if (phased) {
      for (int p = 0; p < ThreadPhases::kParallelPhases; ++p) {
        for (const auto& [begin, end] : phase_rows_[static_cast<std::size_t>(p * threads + t)]) rows(begin, end);
        c.busy_seconds += omp_get_wtime() - start;
#pragma omp barrier
        start = omp_get_wtime();
      }
      if (t == 0)
        for (const auto& [begin, end] : serial_rows_) rows(begin, end);
    } else {
      rows(s.begin, s.end);
    }
    if (!phased || t == 0) c.busy_seconds += omp_get_wtime() - start;
    counts_[t] = c;
  }
  PairCounts sum;
  for (const auto& c : counts_) sum += c;
  sum.region_seconds = omp_get_wtime() - region_start;
  if (outputs && threads > 1 && !phased) {
    const double start = omp_get_wtime();
    reduce(ps, outputs, threads);
    sum.reduce_seconds = omp_get_wtime() - start;
  }
  return sum;
}

}  // namespace sphnl
