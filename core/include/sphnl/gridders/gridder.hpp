#pragma once
// Gridder: which particles are in each cell (paper §2.3, "particles in cells").
// Four algorithms implement it, each in its own header: A SlidingVector,
// B PreconditionedVector, C StaticMatrix, D LinkedList. Pair sources only ask
// a gridder for the particles of a cell, so every gridder yields the same pairs.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "sphnl/kinds.hpp"

namespace sphnl {

class Gridder {
 public:
  virtual ~Gridder() = default;
  virtual const char* name() const = 0;
  /// Places every particle i with cell_key[i] != kNoCell into cell cell_key[i];
  /// keys lie in [0, num_keys).
  virtual void build(std::span<const std::uint32_t> cell_key, std::uint32_t num_keys) = 0;
  /// Writes the particle indices of cell `key` to `out` (room for
  /// max_cell_count() entries) and returns how many.
  virtual std::uint32_t gather_cell(std::uint32_t key, std::uint32_t* out) const = 0;
  /// The particle indices of cell `key` read in place from the gridder's own
  /// structure where it stores them contiguously (A, B: a CellsBegin range of
  /// PartsSorted; C: a PartsInCell row); gridder D walks next[] into
  /// `scratch` (room for max_cell_count() entries). Increasing indices. The
  /// cell-linked list's `pair_loop=direct` reads cells through this.
  virtual std::span<const std::uint32_t> cell_members(std::uint32_t key, std::uint32_t* scratch) const {
    return {scratch, gather_cell(key, scratch)};
  }
  /// CellsBegin where the gridder keeps one (A, B: the first slot of each
  /// cell in cell-key order, num_keys + 1 entries, which is also where each
  /// cell's particles start after reordering); empty for C and D.
  virtual std::span<const std::uint32_t> cells_begin() const { return {}; }
  /// Threads a build may use (gridder B splits its counting and placing
  /// passes; the others build on one). Every count gives the same cells,
  /// each in increasing particle index.
  void set_threads(int threads) { threads_ = threads < 1 ? 1 : threads; }
  /// Largest number of particles in one cell after the last build.
  std::uint32_t max_cell_count() const { return max_cell_count_; }
  /// Every gridded particle, in cell-key order (the reordering permutation).
  virtual void cell_order_permutation(std::vector<std::uint32_t>& order) const;
  /// After the particle arrays were permuted, replaces every stored particle
  /// index i by new_index_of_old[i]: O(N), where gridding again would cost a
  /// second build (for gridder A, a second round of insertions).
  virtual void renumber(std::span<const std::uint32_t> new_index_of_old) = 0;
  /// Bytes allocated for this gridder's structures (capacity x element size).
  virtual std::size_t bytes() const = 0;

 protected:
  std::uint32_t num_keys_ = 0;
  std::uint32_t max_cell_count_ = 0;
  int threads_ = 1;
};

struct GridderOptions {
  int max_parts_in_cell = 0;  // gridder C row length; 0 = default_max_parts_in_cell()
  // The particle lattice, from which gridder C sizes its default row length
  // (dx = 0: unknown; C then sizes its rows from the first build).
  double dx = 0, h = 0;
  double particles_per_dx3 = 1;  // lattice density: 2 for bcc, 1 for simple cubic
  SlidingVariant sliding_variant = SlidingVariant::occupied;  // gridder A only
};

/// MaxPartsInCell when the config leaves it 0: the fullest a cell of side 2.2h
/// (2h, plus room for a Verlet skin) can be on the lattice when it is cut
/// worst ((floor(side/dx) + 1)^3 nodes), compressed to the density limit of
/// 1300/1000. About 3x the mean fill; 0 when options.dx is 0.
int default_max_parts_in_cell(const GridderOptions& options);

std::unique_ptr<Gridder> make_gridder(GridderKind kind, const GridderOptions& options = {});

}  // namespace sphnl
