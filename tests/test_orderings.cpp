// Cell orders sort_x / sort_xy / sort_xyz / hilbert (paper §2.4): Z-order bit
// layouts and the Hilbert curve's ranks of the real cells.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <set>
#include <vector>

#include "sphnl/orderings/hilbert.hpp"
#include "sphnl/orderings/morton.hpp"
#include "sphnl/orderings/sort_x.hpp"

using namespace sphnl;

TEST(Morton, SpreadsBitsWithMasks) {
  EXPECT_EQ(morton::spread2(0b1011u), 0b1000101u);
  EXPECT_EQ(morton::spread3(0b1011u), 0b1000001001u);
  EXPECT_EQ(morton::spread2(0xFFFFu), 0x55555555u);
  EXPECT_EQ(morton::spread3(0x3FFu), 0x09249249u);
}

TEST(Morton, CubeIsClassicZOrder) {
  CellGrid grid(Box{{0, 0, 0}, {8, 8, 8}}, 1.0);
  SortXYZ o;
  o.setup(grid);
  EXPECT_EQ(o.num_keys(), 512u);
  EXPECT_EQ(o.key(1, 0, 0), 1u);
  EXPECT_EQ(o.key(0, 1, 0), 2u);
  EXPECT_EQ(o.key(0, 0, 1), 4u);
  EXPECT_EQ(o.key(2, 0, 0), 8u);
  EXPECT_EQ(o.key(7, 7, 7), 511u);
}

TEST(Morton, PaddedKeySpaceIsABijectionOnPowersOfTwo) {
  // Unequal axes: 5 x 3 x 9 cells -> 8 x 4 x 16 padded keys.
  CellGrid grid(Box{{0, 0, 0}, {5, 3, 9}}, 1.0);
  SortXYZ xyz;
  xyz.setup(grid);
  EXPECT_EQ(xyz.padded()[0], 8);
  EXPECT_EQ(xyz.padded()[1], 4);
  EXPECT_EQ(xyz.padded()[2], 16);
  EXPECT_EQ(xyz.num_keys(), 8u * 4u * 16u);
  std::set<std::uint32_t> seen;
  for (int z = 0; z < 16; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 8; ++x) {
        const std::uint32_t k = xyz.key(x, y, z);
        EXPECT_LT(k, xyz.num_keys());
        seen.insert(k);
      }
  EXPECT_EQ(seen.size(), 8u * 4u * 16u);  // every padded cell has its own key
  // Real cells have coordinates; padding keys are marked and skipped by sweeps.
  std::size_t padding = 0;
  for (std::uint32_t k = 0; k < xyz.num_keys(); ++k) {
    const std::uint64_t c = xyz.key_coords()[k];
    if (c == CellOrder::kNoCellCoords) { ++padding; continue; }
    EXPECT_EQ(xyz.key(static_cast<int>(c & 0x1FFFFF), static_cast<int>((c >> 21) & 0x1FFFFF), static_cast<int>(c >> 42)), k);
  }
  EXPECT_EQ(padding, 8u * 4u * 16u - 5u * 3u * 9u);

  SortXY xy;
  xy.setup(grid);
  EXPECT_EQ(xy.padded()[0], 8);
  EXPECT_EQ(xy.padded()[1], 4);
  EXPECT_EQ(xy.num_keys(), 8u * 4u * 9u);  // z is stacked, not padded
  EXPECT_EQ(xy.key(0, 0, 1), 32u);
  EXPECT_EQ(xy.key(1, 1, 0), 3u);
  EXPECT_GT(xy.bytes(), SortX().bytes());
}

TEST(Hilbert, ConsecutiveIndicesAreFaceNeighbours) {
  for (int bits : {1, 2, 3}) {
    const std::uint32_t side = 1u << bits;
    std::vector<std::array<int, 3>> at(std::size_t{side} * side * side, {-1, -1, -1});
    for (std::uint32_t z = 0; z < side; ++z)
      for (std::uint32_t y = 0; y < side; ++y)
        for (std::uint32_t x = 0; x < side; ++x) {
          const std::uint64_t h = hilbert::index(x, y, z, bits);
          ASSERT_LT(h, at.size());
          ASSERT_EQ(at[h][0], -1) << "index " << h << " used twice";
          at[h] = {static_cast<int>(x), static_cast<int>(y), static_cast<int>(z)};
        }
    for (std::size_t h = 1; h < at.size(); ++h) {
      const int d = std::abs(at[h][0] - at[h - 1][0]) + std::abs(at[h][1] - at[h - 1][1]) + std::abs(at[h][2] - at[h - 1][2]);
      EXPECT_EQ(d, 1) << "bits " << bits << ", index " << h;
    }
  }
}

TEST(Hilbert, KeysRankTheRealCellsWithoutPadding) {
  CellGrid grid(Box{{0, 0, 0}, {6, 3, 5}}, 1.0);
  Hilbert o;
  o.setup(grid);
  EXPECT_EQ(o.num_keys(), 90u);
  std::set<std::uint32_t> seen;
  for (int z = 0; z < 5; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 6; ++x) seen.insert(o.key(x, y, z));
  EXPECT_EQ(seen.size(), 90u);
  EXPECT_EQ(*seen.rbegin(), 89u);
  EXPECT_GT(o.bytes(), 90 * sizeof(std::uint64_t));  // coordinates plus the rank table
}
