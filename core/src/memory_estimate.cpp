#include "sphnl/memory_estimate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <numeric>
#include <sstream>
#include <vector>

#include "sphnl/case.hpp"

namespace sphnl {

namespace {
// Peak resident bytes per particle of `sphnl run`, measured on the dam break
// (3 steps at N = 19 806 and 80 059; the slope between them, so the fixed
// cost of the process drops out): CLL 541, VL_C 1277, VL_X 1308. The
// figures used are rounded up, as the Verlet lists grow with the fluid
// fraction (0.35 at N = 2e4, 0.5 at 8e4, towards 1 at large N).
constexpr double kBytesPerParticleCll = 650;
constexpr double kBytesPerParticleVl = 1600;
// KGC: 12 more doubles per particle (the matrix and its inverse), rounded up.
constexpr double kBytesPerParticleKgc = 150;
constexpr double kProcessBytes = 8.0 * 1024 * 1024;  // libraries, OpenMP pools, output buffers (measured intercept: 4.8 MB)
}  // namespace

double available_memory_bytes() {
  if (const char* env = std::getenv("SPHNL_MEMORY_AVAILABLE")) return std::strtod(env, nullptr);
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kib = 0;
  std::string unit;
  while (in >> key >> kib >> unit)
    if (key == "MemAvailable:") return kib * 1024.0;
  return 0;
}

double peak_resident_bytes() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::strtod(line.c_str() + 6, nullptr) * 1024.0;  // kB
  return 0;
}

std::string format_bytes(double bytes) {
  char buf[48];
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024 && u < 4) {
    bytes /= 1024;
    ++u;
  }
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.2f %s", bytes, units[u]);
  return buf;
}

MemoryEstimate estimate_run_memory(const RunConfig& c) {
  // With dx the count is the case's own (counted, not created).
  const double n = c.dx > 0 ? static_cast<double>(count_particles(dam_break_geometry(), c.dx, c.lattice))
                            : static_cast<double>(c.particles);
  const double per = (c.list == ListKind::cll ? kBytesPerParticleCll : kBytesPerParticleVl) +
                     (c.kgc ? kBytesPerParticleKgc : 0.0);
  std::ostringstream os;
  os << static_cast<long long>(n) << " particles x " << per << " B (" << to_string(c.list) << (c.kgc ? " + KGC" : "")
     << ") + " << format_bytes(kProcessBytes);
  return {kProcessBytes + n * per, os.str()};
}

MemoryEstimate estimate_search_memory(std::uint64_t points, std::uint64_t entries) {
  // Per point: x, y, z in and reordered (48), keys, cell and row offsets
  // (~40), counts (4); per entry: 4 B in the list and at most 16 B of
  // --pairs output text per pair, i.e. 8 per entry, written through a 1 MiB
  // buffer, so only the list is resident.
  const double per_point = 100, per_entry = 4;
  std::ostringstream os;
  os << points << " points x " << per_point << " B + " << entries << " list entries x " << per_entry << " B";
  return {kProcessBytes + static_cast<double>(points) * per_point + static_cast<double>(entries) * per_entry, os.str()};
}

std::uint64_t count_neighbour_entries(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                                      double radius, std::uint64_t stop_above, bool exact) {
  const std::size_t n = x.size();
  if (n < 2) return 0;
  double lo[3] = {x[0], y[0], z[0]};
  for (std::size_t i = 0; i < n; ++i) {
    lo[0] = std::min(lo[0], x[i]);
    lo[1] = std::min(lo[1], y[i]);
    lo[2] = std::min(lo[2], z[i]);
  }
  // Cells of side `radius`, keyed by their integer coordinates; points sorted by cell.
  auto cell_of = [&](std::size_t i) {
    std::int64_t c[3];
    const double p[3] = {x[i], y[i], z[i]};
    // Clamped: far-off cells may merge, which the exact distance test below
    // still counts correctly; neighbouring cells stay neighbours.
    for (int d = 0; d < 3; ++d) c[d] = static_cast<std::int64_t>(std::min(std::floor((p[d] - lo[d]) / radius), 4e18));
    return std::array<std::int64_t, 3>{c[0], c[1], c[2]};
  };
  std::vector<std::array<std::int64_t, 3>> cell(n);
  for (std::size_t i = 0; i < n; ++i) cell[i] = cell_of(i);
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return cell[a] < cell[b]; });
  struct Cell {
    std::array<std::int64_t, 3> key;
    std::size_t begin, end;
    double bmin[3], bmax[3];
  };
  std::vector<Cell> cells;
  for (std::size_t k = 0; k < n;) {
    Cell c{cell[order[k]], k, k, {}, {}};
    for (int d = 0; d < 3; ++d) c.bmin[d] = INFINITY, c.bmax[d] = -INFINITY;
    while (k < n && cell[order[k]] == c.key) {
      const std::uint32_t i = order[k];
      const double p[3] = {x[i], y[i], z[i]};
      for (int d = 0; d < 3; ++d) c.bmin[d] = std::min(c.bmin[d], p[d]), c.bmax[d] = std::max(c.bmax[d], p[d]);
      ++k;
    }
    c.end = k;
    cells.push_back(c);
  }
  const double r2 = radius * radius;
  std::uint64_t entries = 0;
  for (std::size_t a = 0; a < cells.size(); ++a) {
    const Cell& ca = cells[a];
    for (std::int64_t dz = -1; dz <= 1; ++dz)
      for (std::int64_t dy = -1; dy <= 1; ++dy)
        for (std::int64_t dx = -1; dx <= 1; ++dx) {
          const std::array<std::int64_t, 3> want{ca.key[0] + dx, ca.key[1] + dy, ca.key[2] + dz};
          const auto it = std::lower_bound(cells.begin(), cells.end(), want,
                                           [](const Cell& c, const std::array<std::int64_t, 3>& k) { return c.key < k; });
          if (it == cells.end() || it->key != want) continue;
          const Cell& cb = *it;
          const std::uint64_t na = ca.end - ca.begin, nb = cb.end - cb.begin;
          // Farthest corners of the two boxes closer than the radius: every
          // pair counts (each point's own pair excluded in the same cell).
          double far2 = 0;
          for (int d = 0; d < 3; ++d) {
            const double e = std::max(cb.bmax[d] - ca.bmin[d], ca.bmax[d] - cb.bmin[d]);
            far2 += e * e;
          }
          if (far2 < r2 || !exact) {
            entries += &ca == &cb ? na * (na - 1) : na * nb;
          } else {
            for (std::size_t p = ca.begin; p < ca.end; ++p) {
              const std::uint32_t i = order[p];
              for (std::size_t q = cb.begin; q < cb.end; ++q) {
                const std::uint32_t j = order[q];
                const double ex = x[i] - x[j], ey = y[i] - y[j], ez = z[i] - z[j];
                entries += (i != j) & (ex * ex + ey * ey + ez * ez < r2);
              }
              if (entries > stop_above) return entries;
            }
          }
          if (entries > stop_above) return entries;
        }
  }
  return entries;
}

void check_memory(const MemoryEstimate& e, const std::string& what, const std::string& override_hint) {
  const double available = available_memory_bytes();
  if (available <= 0 || e.bytes <= available) return;
  const char* source = std::getenv("SPHNL_MEMORY_AVAILABLE") ? "SPHNL_MEMORY_AVAILABLE" : "MemAvailable of /proc/meminfo";
  throw MemoryError(what + " needs about " + format_bytes(e.bytes) + " (" + e.detail + ") but only " +
                    format_bytes(available) + " is available (" + source + "); make the case smaller, or pass " +
                    override_hint + " to run anyway");
}

}  // namespace sphnl
