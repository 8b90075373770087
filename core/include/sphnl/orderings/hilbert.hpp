#pragma once
// Hilbert: cells numbered along a 3-D Hilbert curve (not in the paper; an
// extension of §2.4). Unlike Z-order, consecutive cells of the curve are
// always face neighbours, so a sweep in key order never jumps.
//
// The Hilbert index of every real cell is computed once per grid with
// Skilling's transpose algorithm (AIP Conf. Proc. 707, 381, 2004) on the grid
// padded to a power-of-two cube; the real cells are then ranked by that index,
// and key(cx, cy, cz) is a lookup of the rank. The key space is therefore
// dense (no padded keys: the cube can be many times larger than a flat
// domain), and the per-particle key costs one load, like eq. 8 plus a gather.
#include <cstdint>
#include <vector>

#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

namespace hilbert {
/// Hilbert index of the cell (x, y, z) on a 2^bits cube (bits in [1, 21]):
/// 3*bits bits, consecutive indices are face-adjacent cells.
std::uint64_t index(std::uint32_t x, std::uint32_t y, std::uint32_t z, int bits);
}  // namespace hilbert

class Hilbert final : public CellOrderWithKey<Hilbert> {
  friend class CellOrderWithKey<Hilbert>;
 public:
  const char* name() const override { return "hilbert"; }

 protected:
  std::uint32_t prepare(const CellGrid& grid) override;
  std::size_t table_bytes() const override { return rank_.capacity() * sizeof(std::uint32_t); }

 private:
  std::uint32_t inline_key(int cx, int cy, int cz) const {
    return rank_[static_cast<std::size_t>(cz) * ncxy_ + static_cast<std::size_t>(cy) * ncx_ + static_cast<std::size_t>(cx)];
  }
  std::size_t ncx_ = 0, ncxy_ = 0;
  std::vector<std::uint32_t> rank_;  // eq. 8 cell index -> position on the Hilbert curve
};

}  // namespace sphnl
