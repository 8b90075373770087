// Hilbert cell order (paper §2.4): Skilling's transpose algorithm on the
// padded cube, real cells ranked along the curve.
#include "sphnl/orderings/hilbert.hpp"

#include <algorithm>
#include <utility>
#include <vector>

#include "sphnl/orderings/morton.hpp"

namespace sphnl {

namespace hilbert {

std::uint64_t index(std::uint32_t x, std::uint32_t y, std::uint32_t z, int bits) {
  // Skilling's AxestoTranspose: undo the excess work of the inverse, then Gray-encode.
  std::uint32_t X[3] = {x, y, z};
  const std::uint32_t M = 1u << (bits - 1);
  for (std::uint32_t Q = M; Q > 1; Q >>= 1) {
    const std::uint32_t P = Q - 1;
    for (int i = 0; i < 3; ++i) {
      if (X[i] & Q) {
        X[0] ^= P;
      } else {
        const std::uint32_t t = (X[0] ^ X[i]) & P;
        X[0] ^= t;
        X[i] ^= t;
      }
    }
  }
  for (int i = 1; i < 3; ++i) X[i] ^= X[i - 1];
  std::uint32_t t = 0;
  for (std::uint32_t Q = M; Q > 1; Q >>= 1)
    if (X[2] & Q) t ^= Q - 1;
  for (int i = 0; i < 3; ++i) X[i] ^= t;
  // The transposed index: bit q of X[i] is bit 3q + (2 - i) of the index.
  std::uint64_t h = 0;
  for (int q = bits - 1; q >= 0; --q)
    for (int i = 0; i < 3; ++i) h = (h << 1) | ((X[i] >> q) & 1u);
  return h;
}

}  // namespace hilbert

std::uint32_t Hilbert::prepare(const CellGrid& grid) {
  const int bits = std::max({1, morton::bits_for(grid.n[0]), morton::bits_for(grid.n[1]), morton::bits_for(grid.n[2])});
  ncx_ = static_cast<std::size_t>(grid.n[0]);
  ncxy_ = ncx_ * static_cast<std::size_t>(grid.n[1]);
  const std::size_t cells = static_cast<std::size_t>(grid.num_cells());
  // Sort the real cells by their index on the padded cube; rank = key.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> curve(cells);
  for (int cz = 0; cz < grid.n[2]; ++cz)
    for (int cy = 0; cy < grid.n[1]; ++cy)
      for (int cx = 0; cx < grid.n[0]; ++cx) {
        const std::size_t c = static_cast<std::size_t>(cz) * ncxy_ + static_cast<std::size_t>(cy) * ncx_ + static_cast<std::size_t>(cx);
        curve[c] = {hilbert::index(static_cast<std::uint32_t>(cx), static_cast<std::uint32_t>(cy),
                                   static_cast<std::uint32_t>(cz), bits),
                    static_cast<std::uint32_t>(c)};
      }
  std::sort(curve.begin(), curve.end());
  rank_.resize(cells);
  for (std::size_t r = 0; r < cells; ++r) rank_[curve[r].second] = static_cast<std::uint32_t>(r);
  return static_cast<std::uint32_t>(cells);
}
}  // namespace sphnl
