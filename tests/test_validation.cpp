// Validation against hydrostatics and experiment (docs/PHYSICS.md items 8 and 9).
// Both run at coarse resolutions and small sizes so that each takes about half
// a minute; the tolerances are the ones docs/PHYSICS.md states.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include "sphnl/case.hpp"
#include "sphnl/simulation.hpp"

using namespace sphnl;

namespace sphnl {
// How googletest names a precision in test output ("double", "mixed").
void PrintTo(Precision p, std::ostream* os) { *os << to_string(p); }
}  // namespace sphnl

namespace {

constexpr double kHcoef = 0.866025;

struct Point {
  double t, z;
};

/// Reads a T,Z table (lines starting with '#' are comments, first data line a header).
std::vector<Point> read_table(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << "cannot read " << path;
  std::vector<Point> out;
  std::string line;
  bool header = true;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (header) { header = false; continue; }
    std::stringstream ss(line);
    Point p{};
    char comma = 0;
    ss >> p.t >> comma >> p.z;
    out.push_back(p);
  }
  return out;
}

/// Linear interpolation of a monotone-in-t series.
double interpolate(const std::vector<Point>& s, double t) {
  const auto it = std::lower_bound(s.begin(), s.end(), t, [](const Point& p, double v) { return p.t < v; });
  if (it == s.begin()) return it->z;
  if (it == s.end()) return s.back().z;
  const Point& b = *it;
  const Point& a = *(it - 1);
  return a.z + (b.z - a.z) * (t - a.t) / (b.t - a.t);
}

Simulation make_sim(const CaseGeometry& g, double dx, int threads, Precision precision,
                    double alpha = RunConfig{}.viscosity_alpha) {
  RunConfig c;
  c.progress = false;
  c.threads = threads;
  c.precision = precision;
  c.viscosity_alpha = alpha;
  const double h = kHcoef * std::sqrt(3.0) * dx;
  const PhysicsParams phys = PhysicsParams::make(h, g.still_water_depth, c.sound_speed_coef, c.viscosity_alpha,
                                                 c.xsph_epsilon, c.cfl, c.clamp_boundary_density);
  return Simulation(c, make_case(g, dx, Lattice::bcc, kHcoef, phys), phys);
}

/// Both validations run in each precision of the pair kernel (README.md,
/// "Configuration"), with the same tolerances.
class Validation : public ::testing::TestWithParam<Precision> {};

std::string precision_name(const ::testing::TestParamInfo<Precision>& info) { return to_string(info.param); }

}  // namespace

// docs/PHYSICS.md item 8: a tank of water at rest stays at rest; the time-averaged
// pressure away from walls and surface is hydrostatic.
//
// What is measured, and why (each choice checked against the run):
// - Pressure is read the way a pressure gauge reads it in SPH (SPHysics and
//   DualSPHysics gauges): the Shepard-normalised kernel interpolant
//   P(r) = sum_b V_b P_b W / sum_b V_b W at FIXED points, time-averaged. The
//   pressure of an individual particle is not a point value of the field: the
//   continuity equation (eq. 4) without any density filter leaves a frozen
//   particle-scale pressure pattern (layers alternately +-30 % of rho0 g d at
//   dx = 0.02) that the symmetric pressure gradient of eq. 2 cannot see (a
//   zero-energy mode: sum_b V_b grad W = 0 over each sub-lattice), so it is
//   not damped and does not average out in time; the field through it is
//   hydrostatic to about 1 %.
// - d is measured from the actual free surface: the mean height of the top
//   particle layer plus dx/4 (on the BCC lattice each layer carries a slab
//   dx/2 thick; the kernel sum sum_b V_b W is 1/2 exactly there), averaged over
//   the samples. The fluid settles by about 3 mm first: the walls start at rho0
//   (P = 0, docs/PHYSICS.md) while the fluid beside them is at rho0 g H.
// - That start is an acoustic transient (whole-column fall, up to 0.29 m/s at
//   t = 0.04 s, decaying below 0.05 m/s by t = 0.6 s): max |v| < 0.05 sqrt(gH)
//   is a steady-state criterion and is checked over the second half, like the
//   time average. The whole-run maximum is printed.
// Geometry: a 0.3 x 0.2 x 0.3 m tank for 1.0 s at dx = 0.02 (6288 particles,
// ~2050 steps, about 30 s on one thread), smaller and shorter than
// docs/PHYSICS.md's 0.4 m, 1.5 s, dx = 0.01 to fit the test suite's time. The
// 1.5 s, 0.4 m run passed with worst gauge error 1.5 % and max |v| 0.051 m/s
// over its second half; this one gives 0.6 % and 0.061 m/s (limit 0.086):
// the transient has decayed below the limit well before t = 0.5 s. The
// gauges sit >= 3h = 0.09 m from walls, floor and surface.
TEST_P(Validation, HydrostaticTank) {
  const double dx = 0.02, depth = 0.3, duration = 1.0, lx = 0.3, ly = 0.2;
  CaseGeometry g;
  g.tank = Box{{0, 0, 0}, {lx, ly, depth + 2 * dx}};
  g.water = {Box{{0, 0, 0}, {lx, ly, depth}}};
  g.still_water_depth = depth;
  // One thread: with two OpenMP threads on two cores shared with other jobs the
  // per-step barriers made this run ten times slower (20 min instead of 1.5).
  Simulation sim = make_sim(g, dx, 1, GetParam());
  const ParticleSet& ps = sim.particles();
  const CubicSpline& kernel = sim.physics().kernel;
  const double h = sim.physics().h(), rho0 = sim.physics().rho0, gravity = sim.physics().gravity;
  const double margin = 3 * h, v_limit = 0.05 * std::sqrt(gravity * depth);
  // Gauges: two verticals (x = 0.1, 0.2; y = 0.1), dx/2 apart in z,
  // from 3h above the floor to 3h below the initial surface (checked against
  // the measured surface below).
  struct Gauge {
    double x, y, z, p_sum = 0;
  };
  std::vector<Gauge> gauges;
  for (double x : {0.1, 0.2})
    for (double z = margin; z <= depth - margin + 1e-9; z += 0.5 * dx) gauges.push_back({x, 0.5 * ly, z});
  const std::size_t n = ps.size();
  double max_speed_all = 0, max_speed_late = 0, surface_sum = 0, p_particle_min = 1e300, p_particle_max = -1e300;
  long samples = 0;
  bool crossed = false;
  while (sim.time() < duration) {
    sim.step();
    max_speed_all = std::max(max_speed_all, sim.max_speed());
    // Nobody crosses a wall (checked every step): fluid stays inside the inner faces.
    for (std::size_t i = 0; i < n; ++i)
      if (ps.type[i] == ParticleType::fluid && !(ps.x[i] > 0 && ps.x[i] < lx && ps.y[i] > 0 && ps.y[i] < ly && ps.z[i] > 0))
        crossed = true;
    if (sim.time() < 0.5 * duration) continue;  // second half: after the start-up transient
    max_speed_late = std::max(max_speed_late, sim.max_speed());
    if (sim.steps_done() % 5 != 0) continue;
    double z_max = -1e300;
    for (std::size_t i = 0; i < n; ++i)
      if (ps.type[i] == ParticleType::fluid) z_max = std::max(z_max, ps.z[i]);
    double z_top = 0;
    int top = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (ps.type[i] == ParticleType::fluid && ps.z[i] > z_max - 0.25 * dx) z_top += ps.z[i], ++top;
    surface_sum += z_top / top + 0.25 * dx;
    for (Gauge& gauge : gauges) {
      double pw = 0, w_sum = 0;
      for (std::size_t i = 0; i < n; ++i) {
        if (ps.type[i] != ParticleType::fluid) continue;
        const double rx = gauge.x - ps.x[i], ry = gauge.y - ps.y[i], rz = gauge.z - ps.z[i];
        const double r2 = rx * rx + ry * ry + rz * rz;
        if (r2 >= kernel.support2) continue;
        const double w = kernel.w(std::sqrt(r2)) * ps.mass[i] / ps.rho[i];
        pw += w * ps.pressure[i];
        w_sum += w;
      }
      gauge.p_sum += pw / w_sum;
    }
    // Spread of single-particle pressures in the same region, for the record.
    for (std::size_t i = 0; i < n; ++i) {
      if (ps.type[i] != ParticleType::fluid || ps.x[i] < margin || ps.x[i] > lx - margin || ps.y[i] < margin ||
          ps.y[i] > ly - margin || ps.z[i] < margin || ps.z[i] > depth - margin)
        continue;
      const double ratio = ps.pressure[i] / (rho0 * gravity * (z_top / top + 0.25 * dx - ps.z[i]));
      p_particle_min = std::min(p_particle_min, ratio), p_particle_max = std::max(p_particle_max, ratio);
    }
    ++samples;
  }
  EXPECT_EQ(sim.lost(), 0u);
  EXPECT_FALSE(crossed) << "a fluid particle crossed a wall";
  EXPECT_LT(max_speed_late, v_limit);
  ASSERT_GT(samples, 10);
  const double surface = surface_sum / static_cast<double>(samples);
  double worst = 0;
  std::size_t checked = 0;
  for (const Gauge& gauge : gauges) {
    if (surface - gauge.z < margin) continue;
    const double p = gauge.p_sum / static_cast<double>(samples), expected = rho0 * gravity * (surface - gauge.z);
    worst = std::max(worst, std::fabs(p / expected - 1));
    EXPECT_NEAR(p, expected, 0.05 * expected) << "gauge x " << gauge.x << " z " << gauge.z;
    ++checked;
  }
  EXPECT_GE(checked, 20u);
  std::printf("hydrostatic tank, precision %s: %zu particles, %ld steps, surface %.4f m (initial %.4f)\n"
              "  max |v| %.4f m/s over the second half, %.4f over the whole run (limit %.4f)\n"
              "  %zu gauges, %ld samples: worst |P/(rho0 g d) - 1| = %.4f (tolerance 0.05)\n"
              "  single-particle P/(rho0 g d) in the same region ranges over [%.2f, %.2f] (not asserted)\n",
              to_string(GetParam()), n, sim.steps_done(), surface, depth + 0.25 * dx, max_speed_late, max_speed_all, v_limit, checked, samples,
              worst, p_particle_min, p_particle_max);
}

// docs/PHYSICS.md item 9: collapse of a water column of width a and height 2a in a
// narrow slab, front Z = x/a (foremost fluid particle) against Martin & Moyce
// (1952) within 15 % for 0.5 <= T = t sqrt(2g/a) <= 3.
//
// The slab is periodic in y (CaseGeometry::periodic_y), 10 dx wide: the
// flow is two-dimensional, as in Martin & Moyce's wide channel. With
// dynamic-boundary side walls instead, a slab narrow enough for a test is
// held back by them (measured at dx = a/40: a one-sheet slab does not move;
// a 4 dx slab, 85 077 particles, is within 15 % up to T = 2.25, then falls
// behind, -14 % at T = 2.5 and -23 % at T = 3, front speed dZ/dT = 0.75
// against 1.5): the walls act through the artificial viscosity (alpha = 0.1
// against v = 0 walls) and the corrugated pressure of the wall lattice.
namespace {
void check_martin_moyce(int dx_divisor, double alpha, Precision precision) {
  const double a = 2.25 * 0.0254, dx = a / dx_divisor, width = 10 * dx;  // >= 3 cells of 2h = 3 dx
  CaseGeometry g;
  g.tank = Box{{0, 0, 0}, {4.5 * a, width, 2 * a + 2 * dx}};
  g.water = {Box{{0, 0, 0}, {a, width, 2 * a}}};
  g.still_water_depth = 2 * a;
  g.periodic_y = true;
  Simulation sim = make_sim(g, dx, 2, precision, alpha);
  const ParticleSet& ps = sim.particles();
  const double t_scale = std::sqrt(2 * sim.physics().gravity / a);
  std::vector<Point> front;  // (T, Z)
  while (sim.time() * t_scale < 3.0) {
    sim.step();
    double x_max = 0;
    for (std::size_t i = 0; i < ps.size(); ++i)
      if (ps.type[i] == ParticleType::fluid) x_max = std::max(x_max, ps.x[i]);
    front.push_back({sim.time() * t_scale, x_max / a});
  }
  EXPECT_LE(sim.lost(), sim.case_info().n_fluid / 1000);
  std::printf("Martin & Moyce, precision %s, dx = a/%d, alpha %g, periodic slab of 10 dx: %zu particles (%zu fluid), %ld steps\n",
              to_string(precision), dx_divisor, alpha, ps.size(), sim.case_info().n_fluid, sim.steps_done());
  int compared = 0;
  for (const char* file : {"martin_moyce_1952_a2.25in.csv", "martin_moyce_1952_a1.125in.csv"}) {
    for (const Point& e : read_table(std::string(SPHNL_SOURCE_DIR) + "/tests/data/" + file)) {
      if (e.t < 0.5 || e.t > 3.0) continue;
      const double z = interpolate(front, e.t);
      std::printf("  %s T %.3f  Z experiment %.3f  SPH %.3f  (%+.1f %%)\n", file, e.t, e.z, z, 100 * (z / e.z - 1));
      EXPECT_NEAR(z, e.z, 0.15 * e.z) << file << " T = " << e.t;
      ++compared;
    }
  }
  EXPECT_GE(compared, 6);
}
}  // namespace

// dx = a/16 by default: a coarse resolution for the test suite's time budget
// (13 070 particles, 1 292 steps, ~30 s on 2 cores). The work grows as the
// cube of the divisor (particles in a slab 10 dx wide as its square, steps as
// the divisor): a/20 is twice the work, a/40 (docs/PHYSICS.md's) 16 times;
// docs/FINDINGS.md gives the front at each: it moves ahead of the experiment
// as dx shrinks, and at a/40 one point (+16.9 % at T = 1.212, a = 1.125 in)
// is outside the 15 %, so this coarse check passes partly by its coarseness
// (about three fifths of the shift is the artificial viscosity alpha h c0
// falling with h: a/40 with alpha = 0.25, a/16's alpha h, passes).
// SPHNL_MARTIN_MOYCE_DX_DIVISOR=40 runs docs/PHYSICS.md's resolution;
// SPHNL_MARTIN_MOYCE_ALPHA sets the artificial viscosity's alpha (eq. 3;
// default 0.1), the ablation that separates viscosity from resolution.
TEST_P(Validation, MartinMoyceDamBreakFront) {
  const char* divisor = std::getenv("SPHNL_MARTIN_MOYCE_DX_DIVISOR");
  const int n = divisor ? std::atoi(divisor) : 16;
  ASSERT_GE(n, 10) << "SPHNL_MARTIN_MOYCE_DX_DIVISOR must be an integer >= 10, got '" << divisor << "'";
  const char* alpha_text = std::getenv("SPHNL_MARTIN_MOYCE_ALPHA");
  char* end = nullptr;
  const double alpha = alpha_text ? std::strtod(alpha_text, &end) : RunConfig{}.viscosity_alpha;
  ASSERT_TRUE(!alpha_text || (end != alpha_text && *end == '\0' && std::isfinite(alpha) && alpha >= 0))
      << "SPHNL_MARTIN_MOYCE_ALPHA must be a finite number >= 0, got '" << alpha_text << "'";
  check_martin_moyce(n, alpha, GetParam());
}

INSTANTIATE_TEST_SUITE_P(Precision, Validation, ::testing::Values(Precision::double_precision, Precision::mixed),
                         precision_name);
