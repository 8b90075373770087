#pragma once
// The point clouds of the `search` family: a simple cubic lattice of unit
// spacing, or as many points uniformly at random in the same cube (the same
// density, one point per unit volume), each either in the memory order it was
// generated in (the lattice x fastest: already nearly in cell order) or
// shuffled by a fixed-seed permutation (every neighbour far away in memory).
// Deterministic on every platform: std::mt19937_64 is specified bit for bit,
// and the conversions below are explicit (no std:: distributions, whose
// output the standard leaves to the library).
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace sphnl::peers {

enum class CloudKind { lattice, random };
enum class MemoryOrder { generated, shuffled };

struct Cloud {
  std::vector<double> x, y, z;
  std::size_t size() const { return x.size(); }
};

inline CloudKind cloud_kind(const std::string& s) {
  if (s == "lattice") return CloudKind::lattice;
  if (s == "random") return CloudKind::random;
  throw std::invalid_argument("cloud: '" + s + "'; allowed: lattice, random");
}

inline MemoryOrder memory_order(const std::string& s) {
  if (s == "generated") return MemoryOrder::generated;
  if (s == "shuffled") return MemoryOrder::shuffled;
  throw std::invalid_argument("memory_order: '" + s + "'; allowed: generated, shuffled");
}

/// Points along one side of the cube for about `n` points: round(cbrt(n)).
inline long cloud_side(long n) { return std::max(1L, std::lround(std::cbrt(static_cast<double>(n)))); }

/// side^3 points (side = cloud_side(n)) in [0, side)^3: the lattice at integer
/// coordinates, x fastest, or uniform random points (seed 1); then shuffled
/// with a Fisher-Yates permutation of seed 2 when asked.
inline Cloud make_cloud(CloudKind kind, MemoryOrder order, long n) {
  const long side = cloud_side(n);
  const std::size_t count = static_cast<std::size_t>(side) * static_cast<std::size_t>(side) * static_cast<std::size_t>(side);
  Cloud c;
  c.x.reserve(count);
  c.y.reserve(count);
  c.z.reserve(count);
  std::mt19937_64 rng(1);
  const double scale = static_cast<double>(side) / 9007199254740992.0;  // 53 random bits -> [0, side)
  auto uniform = [&] { return static_cast<double>(rng() >> 11) * scale; };
  for (long k = 0; k < side; ++k)
    for (long j = 0; j < side; ++j)
      for (long i = 0; i < side; ++i) {
        if (kind == CloudKind::lattice) {
          c.x.push_back(static_cast<double>(i));
          c.y.push_back(static_cast<double>(j));
          c.z.push_back(static_cast<double>(k));
        } else {
          c.x.push_back(uniform());
          c.y.push_back(uniform());
          c.z.push_back(uniform());
        }
      }
  if (order == MemoryOrder::shuffled) {
    std::mt19937_64 shuffle(2);
    for (std::size_t i = count; i > 1; --i) {
      const std::size_t j = static_cast<std::size_t>(shuffle() % i);
      std::swap(c.x[i - 1], c.x[j]);
      std::swap(c.y[i - 1], c.y[j]);
      std::swap(c.z[i - 1], c.z[j]);
    }
  }
  return c;
}

}  // namespace sphnl::peers
