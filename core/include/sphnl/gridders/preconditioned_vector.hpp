#pragma once
// Gridder B, "preconditioned dynamic vector" (paper §2.3): count the particles
// of every cell first, prefix-sum the counts into CellsBegin, then place each
// particle straight into its slot of PartsSorted — no shifting.
//
// With set_threads(T > 1) both passes are split: thread t counts and places
// its own contiguous range of particles, and its slots in each cell come
// after those of threads before it, so PartsSorted is the same as on one
// thread (each cell in increasing particle index).
#include <cstddef>
#include <vector>

#include "sphnl/gridders/cells_begin_gridder.hpp"

namespace sphnl {

class PreconditionedVector final : public CellsBeginGridder {
 public:
  const char* name() const override { return "B"; }

  void build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) override;

  std::size_t bytes() const override {
    return CellsBeginGridder::bytes() + cursor_.capacity() * sizeof(std::uint32_t);
  }

  /// Fewer particles than this per thread are counted on one: below it the
  /// threads' start-up and per-thread counts cost more than they save.
  static constexpr std::size_t kMinParticlesPerThread = 32768;

 private:
  void build_serial(std::span<const std::uint32_t> cell_key);
  void build_parallel(std::span<const std::uint32_t> cell_key, int threads);

  // Next free slot per cell while placing; with T threads, T rows of
  // num_keys (thread t's next slot in each cell).
  std::vector<std::uint32_t> cursor_;
};

}  // namespace sphnl
