#pragma once
// Z-order (Morton 1966) cell orders of paper §2.4: SortXY interleaves the bits
// of cx and cy and stacks the XY planes along z; SortXYZ interleaves all three.
// "The number of cells in each direction should be a power of two. Thus,
// additional cells must be added in each direction" (§3.2): every interleaved
// axis is padded to the next power of two, and the padded cells are real keys
// (they cost memory in every key-indexed array, which Figs. 7 and 11 count).
//
// Axes with different power-of-two sizes: the low bits all axes share are
// interleaved, then the bits only the longer axes have, then the rest of the
// longest one. The key space is then exactly the padded box (prod 2^bits), a
// bijection, and for a cube it is the classic Morton code.
//
// Bits are spread with magic-number masks (no loop over bits, no BMI2 pdep, so
// the code also runs under valgrind and on any x86-64).
#include <cstdint>
#include <stdexcept>
#include <string>

#include "sphnl/orderings/cell_order.hpp"

namespace sphnl {

namespace morton {

/// Bits needed to number n cells: the smallest b with 2^b >= n.
inline int bits_for(int n) {
  int b = 0;
  while ((1L << b) < n) ++b;
  return b;
}

/// 0b...dcba -> 0b...0d0c0b0a (16 input bits).
inline std::uint32_t spread2(std::uint32_t v) {
  v &= 0x0000FFFFu;
  v = (v | (v << 8)) & 0x00FF00FFu;
  v = (v | (v << 4)) & 0x0F0F0F0Fu;
  v = (v | (v << 2)) & 0x33333333u;
  v = (v | (v << 1)) & 0x55555555u;
  return v;
}

/// 0b...cba -> 0b...00c00b00a (10 input bits).
inline std::uint32_t spread3(std::uint32_t v) {
  v &= 0x000003FFu;
  v = (v | (v << 16)) & 0x030000FFu;
  v = (v | (v << 8)) & 0x0300F00Fu;
  v = (v | (v << 4)) & 0x030C30C3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

/// Where each bit group of one axis goes in the key; precomputed per grid so
/// the key is branch-free: key = sum over axes of
///   spread3(c & mask3) << shift3 | spread2((c >> low) & mask2) << shift2 | ((c >> mid) & mask1) << shift1.
struct AxisLayout {
  std::uint32_t mask3 = 0, mask2 = 0, mask1 = 0;
  int shift3 = 0, shift2 = 0, shift1 = 0;
  int low = 0, mid = 0;  // bits below the 2-way part, bits below the 1-way part
};

inline std::uint32_t axis_bits(std::uint32_t c, const AxisLayout& a) {
  return (spread3(c & a.mask3) << a.shift3) | (spread2((c >> a.low) & a.mask2) << a.shift2) |
         (((c >> a.mid) & a.mask1) << a.shift1);
}

/// Layouts of `dims` (2 or 3) axes with the given bit counts; returns the total bits.
int make_layouts(const int* bits, int dims, AxisLayout* out);

}  // namespace morton

/// Z-order in the XY plane, then z (paper §2.4 "SortXY"): icell = cz * PX * PY + Z(cx, cy),
/// with PX, PY the padded power-of-two cell counts of x and y.
class SortXY final : public CellOrderWithKey<SortXY> {
  friend class CellOrderWithKey<SortXY>;
 public:
  const char* name() const override { return "sort_xy"; }
  /// Padded cells per axis (x, y are powers of two; z is not padded).
  const int* padded() const { return padded_; }

 protected:
  std::uint32_t prepare(const CellGrid& grid) override;

 private:
  std::uint32_t inline_key(int cx, int cy, int cz) const {
    return static_cast<std::uint32_t>(cz) * plane_ + morton::axis_bits(static_cast<std::uint32_t>(cx), layout_[0]) +
           morton::axis_bits(static_cast<std::uint32_t>(cy), layout_[1]);
  }
  morton::AxisLayout layout_[2];
  std::uint32_t plane_ = 0;  // PX * PY
  int padded_[3] = {0, 0, 0};
};

/// 3-D Z-order (paper §2.4 "SortXYZ") on the grid padded to powers of two per axis.
class SortXYZ final : public CellOrderWithKey<SortXYZ> {
  friend class CellOrderWithKey<SortXYZ>;
 public:
  const char* name() const override { return "sort_xyz"; }
  const int* padded() const { return padded_; }

 protected:
  std::uint32_t prepare(const CellGrid& grid) override;

 private:
  std::uint32_t inline_key(int cx, int cy, int cz) const {
    return morton::axis_bits(static_cast<std::uint32_t>(cx), layout_[0]) +
           morton::axis_bits(static_cast<std::uint32_t>(cy), layout_[1]) +
           morton::axis_bits(static_cast<std::uint32_t>(cz), layout_[2]);
  }
  morton::AxisLayout layout_[3];
  int padded_[3] = {0, 0, 0};
};

}  // namespace sphnl
