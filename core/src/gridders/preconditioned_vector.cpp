#include "sphnl/gridders/preconditioned_vector.hpp"

#include <omp.h>

#include <algorithm>

#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

void PreconditionedVector::build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) {
  num_keys_ = num_keys;
  const std::size_t by_size = cell_key.size() / kMinParticlesPerThread;
  const int threads = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(threads_), by_size));
  if (threads > 1)
    build_parallel(cell_key, threads);
  else
    build_serial(cell_key);
}

void PreconditionedVector::build_serial(std::span<const std::uint32_t> cell_key) {
  const std::uint32_t num_keys = num_keys_;
  const std::size_t n = cell_key.size();
  cells_begin_.assign(std::size_t{num_keys} + 1, 0);
  // Pass 1: particles per cell (the "extra arrays" that precondition the vector).
  for (std::size_t i = 0; i < n; ++i)
    if (cell_key[i] != kNoCell) ++cells_begin_[cell_key[i] + 1];
  for (std::uint32_t k = 0; k < num_keys; ++k) cells_begin_[k + 1] += cells_begin_[k];
  // Pass 2: place particles; `cursor_` is where the next particle of a cell goes.
  cursor_.assign(cells_begin_.begin(), cells_begin_.end() - 1);
  parts_sorted_.resize(cells_begin_[num_keys]);
  for (std::size_t i = 0; i < n; ++i)
    if (cell_key[i] != kNoCell) parts_sorted_[cursor_[cell_key[i]]++] = static_cast<std::uint32_t>(i);
  finish_build(cells_begin_[num_keys]);
}

void PreconditionedVector::build_parallel(std::span<const std::uint32_t> cell_key, int threads) {
  const std::size_t keys = num_keys_;
  const std::size_t n = cell_key.size();
  // Sized before the threads start: an allocation failure throws here, not
  // inside the parallel region. PartsSorted has room for every particle;
  // `stored_` is the used length (out particles are not stored).
  cursor_.resize(static_cast<std::size_t>(threads) * keys);
  cells_begin_.resize(keys + 1);
  parts_sorted_.resize(n);
#pragma omp parallel num_threads(threads)
  {
    const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
    const std::size_t team = static_cast<std::size_t>(omp_get_num_threads());
    const std::size_t begin = n * t / team, end = n * (t + 1) / team;
    std::uint32_t* const mine = cursor_.data() + t * keys;
    // Pass 1: thread t's particles per cell.
    std::fill(mine, mine + keys, 0u);
    for (std::size_t i = begin; i < end; ++i)
      if (cell_key[i] != kNoCell) ++mine[cell_key[i]];
#pragma omp barrier
#pragma omp single
    {
      // CellsBegin, and each thread's first slot in each cell: after the
      // slots of the threads before it (lower particle indices).
      std::uint32_t slot = 0;
      for (std::size_t k = 0; k < keys; ++k) {
        cells_begin_[k] = slot;
        for (std::size_t u = 0; u < team; ++u) {
          const std::uint32_t count = cursor_[u * keys + k];
          cursor_[u * keys + k] = slot;
          slot += count;
        }
      }
      cells_begin_[keys] = slot;
    }  // the implicit barrier: every cursor row is set
    // Pass 2: thread t places its particles, in increasing index per cell.
    std::uint32_t* const parts = parts_sorted_.data();
    for (std::size_t i = begin; i < end; ++i)
      if (cell_key[i] != kNoCell) parts[mine[cell_key[i]]++] = static_cast<std::uint32_t>(i);
  }
  finish_build(cells_begin_[keys]);
}

}  // namespace sphnl
