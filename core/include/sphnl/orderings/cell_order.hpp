#pragma once
// CellOrder: how the cells of a CellGrid are numbered (paper §2.4). The number
// of a cell is its position in the sweep of the pair loop and in the particle
// order after reordering, so it decides memory locality.
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/kinds.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

inline constexpr std::uint32_t kNoCell = 0xFFFFFFFFu;  // particle not gridded (out)

class CellOrder {
 public:
  virtual ~CellOrder() = default;
  virtual const char* name() const = 0;
  /// Prepares for a grid; after it, keys lie in [0, num_keys()).
  void setup(const CellGrid& grid);
  /// Number of distinct keys, padded cells included (Z-order pads to powers of two).
  std::uint32_t num_keys() const { return num_keys_; }
  /// Key of the cell at integer coordinates (all in range).
  virtual std::uint32_t key(int cx, int cy, int cz) const = 0;
  /// Key of the cell of every point (x[i], y[i], z[i]) (all inside the grid's
  /// box); kNoCell where `type` is given and type[i] is `out`. The loop lives
  /// in each ordering so the key computation inlines (its cost is the "~100x"
  /// claim of Fig. 9). The one key computation of every neighbour path.
  virtual void compute_keys(const CellGrid& grid, std::span<const double> x, std::span<const double> y,
                            std::span<const double> z, const ParticleType* type, std::span<std::uint32_t> keys) const = 0;
  /// Keys of a particle set's particles (out particles get kNoCell).
  void compute_keys(const CellGrid& grid, const ParticleSet& ps, std::span<std::uint32_t> keys) const {
    compute_keys(grid, ps.x, ps.y, ps.z, ps.type.data(), keys);
  }
  /// Integer coordinates of every key that is a real cell (packed cx | cy<<21 |
  /// cz<<42), kNoCellCoords for padding keys: lets pair sources sweep cells in
  /// key order without each ordering having to invert its key.
  std::span<const std::uint64_t> key_coords() const { return key_coords_; }
  static constexpr std::uint64_t kNoCellCoords = ~std::uint64_t{0};
  static std::uint64_t pack_coords(int cx, int cy, int cz) {
    return static_cast<std::uint64_t>(cx) | (static_cast<std::uint64_t>(cy) << 21) | (static_cast<std::uint64_t>(cz) << 42);
  }
  struct Coords { int x, y, z; };
  static Coords unpack_coords(std::uint64_t c) {
    return {static_cast<int>(c & 0x1FFFFF), static_cast<int>((c >> 21) & 0x1FFFFF), static_cast<int>(c >> 42)};
  }
  /// Bytes of this ordering's own tables (the padded key space included).
  std::size_t bytes() const { return key_coords_.capacity() * sizeof(std::uint64_t) + table_bytes(); }

 protected:
  /// Stores what key() needs for this grid; returns the number of keys.
  virtual std::uint32_t prepare(const CellGrid& grid) = 0;
  /// Bytes of an ordering's own lookup tables (Hilbert's rank table).
  virtual std::size_t table_bytes() const { return 0; }

 private:
  std::uint32_t num_keys_ = 0;
  std::vector<std::uint64_t> key_coords_;
};

std::unique_ptr<CellOrder> make_cell_order(CellOrderKind kind);

/// Shared loop for compute_keys: applies an inlinable key function to every
/// point; `type` null means every point is gridded.
template <class KeyFn>
void compute_keys_with(const CellGrid& grid, std::span<const double> xs, std::span<const double> ys,
                       std::span<const double> zs, const ParticleType* type, std::span<std::uint32_t> keys, KeyFn key) {
  const std::size_t n = xs.size();
  const double* x = xs.data();
  const double* y = ys.data();
  const double* z = zs.data();
  if (type == nullptr) {
    for (std::size_t i = 0; i < n; ++i) keys[i] = key(grid.coord(x[i], 0), grid.coord(y[i], 1), grid.coord(z[i], 2));
    return;
  }
  for (std::size_t i = 0; i < n; ++i) {
    keys[i] = type[i] == ParticleType::out
                  ? kNoCell
                  : key(grid.coord(x[i], 0), grid.coord(y[i], 1), grid.coord(z[i], 2));
  }
}

/// Base of every ordering: implements key() and compute_keys() from
/// Derived::inline_key(cx, cy, cz), so that the per-particle loop inlines the
/// ordering's own key function (one virtual call per pass, not per particle).
template <class Derived>
class CellOrderWithKey : public CellOrder {
 public:
  std::uint32_t key(int cx, int cy, int cz) const final { return self().inline_key(cx, cy, cz); }
  using CellOrder::compute_keys;
  void compute_keys(const CellGrid& grid, std::span<const double> x, std::span<const double> y,
                    std::span<const double> z, const ParticleType* type, std::span<std::uint32_t> keys) const final {
    compute_keys_with(grid, x, y, z, type, keys, [this](int cx, int cy, int cz) { return self().inline_key(cx, cy, cz); });
  }

 private:
  const Derived& self() const { return static_cast<const Derived&>(*this); }
};

}  // namespace sphnl
