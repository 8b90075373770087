#include "sphnl/case.hpp"

#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace sphnl {

CaseGeometry dam_break_geometry() {
  CaseGeometry g;
  g.tank = Box{{0, 0, 0}, {1.6, 0.61, 0.75}};
  g.water = {Box{{0, 0, 0}, {0.4, 0.61, 0.3}}};
  g.obstacles = {Box{{0.9, 0.24, 0}, {1.02, 0.36, 0.75}}};
  g.still_water_depth = 0.3;
  return g;
}

namespace {

enum class Node { none, fluid, boundary };

/// Lattice in half-spacing units: node (a, b, c) sits at tank.lo + (a, b, c) dx/2.
/// BCC nodes have a, b, c all even or all odd; cubic nodes all even.
struct Lattice3 {
  double dx;
  bool bcc;
  int layer;          // boundary thickness in half units beyond the wall plane: 1 (BCC, two layers) or 0
  bool periodic_y;    // no y walls; y nodes 0 <= b < hi[1] (b = hi[1] is the image of b = 0)
  long hi[3];         // tank inner faces (half units), snapped to even = lattice planes
  struct SolidBox { long lo[3], hi[3]; };
  std::vector<SolidBox> obstacles;
  struct WaterBox { double hi[3]; double lo[3]; };
  std::vector<WaterBox> water;
  const CaseGeometry* g;

  Lattice3(const CaseGeometry& geo, double spacing, Lattice lattice)
      : dx(spacing), bcc(lattice == Lattice::bcc), periodic_y(geo.periodic_y), g(&geo) {
    layer = bcc ? 1 : 0;
    auto snap = [&](double v) { return 2 * std::lround(v / dx); };  // nearest lattice plane
    for (int d = 0; d < 3; ++d) hi[d] = snap(geo.tank.hi[d] - geo.tank.lo[d]);
    for (const Box& o : geo.obstacles) {
      SolidBox s;
      for (int d = 0; d < 3; ++d) {
        s.lo[d] = snap(o.lo[d] - geo.tank.lo[d]);
        s.hi[d] = snap(o.hi[d] - geo.tank.lo[d]);
      }
      obstacles.push_back(s);
    }
    for (const Box& w : geo.water) {
      WaterBox b;
      for (int d = 0; d < 3; ++d) { b.lo[d] = w.lo[d] - geo.tank.lo[d]; b.hi[d] = w.hi[d] - geo.tank.lo[d]; }
      water.push_back(b);
    }
  }

  bool is_node(long a, long b, long c) const {
    const bool even = (a % 2 == 0) && (b % 2 == 0) && (c % 2 == 0);
    const bool odd = (a % 2 != 0) && (b % 2 != 0) && (c % 2 != 0);
    return even || (bcc && odd);
  }

  Node classify(long a, long b, long c) const {
    // Tank walls: the wall plane and `layer` half units outward, up to the wall top.
    const bool in_tank_shell = a >= -layer && a <= hi[0] + layer && (periodic_y || (b >= -layer && b <= hi[1] + layer)) &&
                               c >= -layer && c <= hi[2];
    const bool inside_tank = a > 0 && a < hi[0] && (periodic_y ? b >= 0 && b < hi[1] : b > 0 && b < hi[1]) && c > 0;
    if (in_tank_shell && !inside_tank) return Node::boundary;
    if (!inside_tank || c > hi[2]) return Node::none;
    for (const SolidBox& o : obstacles) {
      const bool in_box = a >= o.lo[0] && a <= o.hi[0] && b >= o.lo[1] && b <= o.hi[1] && c <= o.hi[2];
      if (!in_box) continue;
      // Faces (and top) of the obstacle, `layer` half units inward; the rest is solid.
      const bool shell = a <= o.lo[0] + layer || a >= o.hi[0] - layer || b <= o.lo[1] + layer ||
                         b >= o.hi[1] - layer || c >= o.hi[2] - layer;
      return shell ? Node::boundary : Node::none;
    }
    const double x = static_cast<double>(a) * 0.5 * dx, y = static_cast<double>(b) * 0.5 * dx,
                 z = static_cast<double>(c) * 0.5 * dx, eps = 1e-9 * dx;
    for (const WaterBox& w : water)
      if (x >= w.lo[0] - eps && x <= w.hi[0] + eps && y >= w.lo[1] - eps && y <= w.hi[1] + eps &&
          z >= w.lo[2] - eps && z <= w.hi[2] + eps)
        return Node::fluid;
    return Node::none;
  }

  template <class F>
  void for_each_node(F&& f) const {
    for (long c = -layer; c <= hi[2]; ++c)
      for (long b = periodic_y ? 0 : -layer; b <= (periodic_y ? hi[1] - 1 : hi[1] + layer); ++b)
        for (long a = -layer; a <= hi[0] + layer; ++a)
          if (is_node(a, b, c)) {
            const Node k = classify(a, b, c);
            if (k != Node::none) f(k, a, b, c);
          }
  }
};

void check_spacing(const CaseGeometry& g, double dx) {
  if (!(dx > 0)) throw std::invalid_argument("lattice spacing dx must be positive");
  const double cells = (g.tank.hi[0] - g.tank.lo[0]) * (g.tank.hi[1] - g.tank.lo[1]) * (g.tank.hi[2] - g.tank.lo[2]) / (dx * dx * dx);
  if (cells > 4e9) throw std::invalid_argument("lattice spacing dx too small for this tank (more than 4e9 lattice cells)");
}

}  // namespace

std::size_t count_particles(const CaseGeometry& g, double dx, Lattice lattice) {
  check_spacing(g, dx);
  std::size_t n = 0;
  Lattice3(g, dx, lattice).for_each_node([&](Node, long, long, long) { ++n; });
  return n;
}

double dx_for_particles(const CaseGeometry& g, std::size_t target, Lattice lattice) {
  if (target == 0) throw std::invalid_argument("particle count must be positive");
  // The count falls monotonically (up to lattice steps) with dx, roughly as
  // dx^-2.7 (boundary surface ~ dx^-2, fluid volume ~ dx^-3): guess a bracket
  // from one count, widen it until it holds, then bisect on log dx.
  const auto count = [&](double d) { return count_particles(g, d, lattice); };
  const double probe = 0.02;
  const double guess = probe * std::pow(static_cast<double>(count(probe)) / static_cast<double>(target), 1.0 / 2.7);
  double lo = guess / 1.1, hi = guess * 1.1;
  while (count(lo) <= target && lo > 1e-5) lo /= 1.5;
  while (count(hi) > target && hi < 1.0) hi *= 1.5;
  while (hi / lo > 1 + 1e-5) {
    const double mid = std::sqrt(lo * hi);
    if (count(mid) > target) lo = mid; else hi = mid;
  }
  const auto off = [&](double d) { return std::fabs(static_cast<double>(count(d)) - static_cast<double>(target)); };
  return off(lo) < off(hi) ? lo : hi;
}

Case make_case(const CaseGeometry& g, double dx, Lattice lattice, double h_coefficient, const PhysicsParams& phys) {
  check_spacing(g, dx);
  const Lattice3 lat(g, dx, lattice);
  const double per_volume = lattice == Lattice::bcc ? 0.5 : 1.0;  // dx^3 per particle
  struct Node4 { long a, b, c; };
  std::vector<Node4> fluid, boundary;
  lat.for_each_node([&](Node k, long a, long b, long c) { (k == Node::fluid ? fluid : boundary).push_back({a, b, c}); });

  Case cs;
  cs.dx = dx;
  cs.h = h_coefficient * std::sqrt(3.0) * dx;
  cs.n_fluid = fluid.size();
  cs.n_boundary = boundary.size();
  ParticleSet& ps = cs.particles;
  ps.resize(fluid.size() + boundary.size());
  const double dx3 = dx * dx * dx;
  std::size_t i = 0;
  auto place = [&](const Node4& n, ParticleType t) {
    ps.x[i] = g.tank.lo[0] + 0.5 * dx * static_cast<double>(n.a);
    ps.y[i] = g.tank.lo[1] + 0.5 * dx * static_cast<double>(n.b);
    ps.z[i] = g.tank.lo[2] + 0.5 * dx * static_cast<double>(n.c);
    double rho = phys.rho0;
    if (t == ParticleType::fluid) {
      // Hydrostatic: P = rho0 g (Z_top - z) with Z_top the top of the block holding the particle.
      double z_top = ps.z[i];
      for (const Box& w : g.water)
        if (ps.x[i] >= w.lo[0] - 1e-9 && ps.x[i] <= w.hi[0] + 1e-9 && ps.y[i] >= w.lo[1] - 1e-9 &&
            ps.y[i] <= w.hi[1] + 1e-9 && ps.z[i] <= w.hi[2] + 1e-9)
          z_top = w.hi[2];
      rho = phys.hydrostatic_density(z_top - ps.z[i]);
    }
    ps.rho[i] = ps.rho_prev[i] = rho;
    ps.mass[i] = per_volume * rho * dx3;
    ps.type[i] = t;
    ps.id[i] = static_cast<std::uint32_t>(i);
    ++i;
  };
  for (const auto& n : fluid) place(n, ParticleType::fluid);
  for (const auto& n : boundary) place(n, ParticleType::boundary);
  update_derived(phys, ps, 0, ps.size());

  // Domain: every particle (the walls enclose the fluid) plus a margin of 2h; the open top gets room
  // for splashes up to the height of the walls again.
  Box d{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}};
  for (std::size_t k = 0; k < ps.size(); ++k) {
    const double p[3] = {ps.x[k], ps.y[k], ps.z[k]};
    for (int a = 0; a < 3; ++a) { d.lo[a] = std::min(d.lo[a], p[a]); d.hi[a] = std::max(d.hi[a], p[a]); }
  }
  for (int a = 0; a < 3; ++a) { d.lo[a] -= 2 * cs.h; d.hi[a] += 2 * cs.h; }
  d.hi[2] += g.tank.hi[2] - g.tank.lo[2];
  if (g.periodic_y) {  // one period, the lattice's: y nodes at b dx/2 for 0 <= b < hi[1]
    cs.period_y = 0.5 * dx * static_cast<double>(lat.hi[1]);
    d.lo[1] = g.tank.lo[1];
    d.hi[1] = g.tank.lo[1] + cs.period_y;
  }
  cs.domain = d;
  return cs;
}

}  // namespace sphnl
