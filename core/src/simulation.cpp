#include "sphnl/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "sphnl/timer.hpp"

namespace sphnl {

namespace {

PhysicsParams physics_for(const RunConfig& c, double h, double depth) {
  return PhysicsParams::make(h, depth, c.sound_speed_coef, c.viscosity_alpha, c.xsph_epsilon, c.cfl,
                             c.clamp_boundary_density);
}

Case dam_break_case(const RunConfig& c, PhysicsParams& phys) {
  const CaseGeometry g = dam_break_geometry();
  const double dx = c.dx > 0 ? c.dx : dx_for_particles(g, static_cast<std::size_t>(c.particles), c.lattice);
  // c0 and B depend on the depth only, so the hydrostatic densities can be set
  // before h is known.
  phys = physics_for(c, c.h_coefficient * std::sqrt(3.0) * dx, g.still_water_depth);
  return make_case(g, dx, c.lattice, c.h_coefficient, phys);
}

}  // namespace

Simulation::Simulation(const RunConfig& config) : config_(config), case_(dam_break_case(config, phys_)), ps_(case_.particles) {
  init();
}

Simulation::Simulation(const RunConfig& config, Case c, const PhysicsParams& phys)
    : config_(config), phys_(phys), case_(std::move(c)), ps_(case_.particles) {
  init();
}

void Simulation::init() {
  if (config_.list != ListKind::cll)
    throw ConfigError(std::string("list '") + to_string(config_.list) + "' is not implemented yet; use cll");
  GridderOptions options;
  options.max_parts_in_cell = config_.max_parts_in_cell;
  grid_ = std::make_unique<ParticleGrid>(case_.domain, config_.cell_order, config_.gridder, options);
  force_ops_.assign(config_.threads, ForceOp<false>{&phys_, 0});
  force_ops_kgc_.assign(config_.threads, ForceOp<true>{&phys_, 0});
  update_derived(phys_, ps_, 0, ps_.size());
}

void Simulation::build_neighbours() {
  const bool reorder = config_.reorder && stats_.builds % static_cast<std::uint64_t>(config_.reorder_every) == 0;
  grid_->build(ps_, 2.0 * phys_.h(), reorder);
  ++stats_.builds;
  stats_.max_steps_per_list = 1;
}

void Simulation::compute_forces() {
  ps_.clear_accumulators();
  PairCounts counts;
  double mu = 0;
  if (config_.kgc) {
    throw ConfigError("kgc is not implemented yet");
  } else {
    for (auto& op : force_ops_) op.max_mu = 0;
    counts = for_each_pair(force_ops_);
    for (const auto& op : force_ops_) mu = std::max(mu, op.max_mu);
  }
  max_mu_ = mu;
  stats_.candidates += counts.candidates;
  stats_.interactions += counts.interactions;
}

double Simulation::time_step() const {
  // eq. 7: dt = CFL min(dt_f, dt_cv). dt_cv uses the largest sound speed and
  // the largest |h v.r/(r^2+eta^2)| over all pairs (as SPHysics codes it).
  double max_f2 = 0, max_c = 0;
  const std::size_t n = ps_.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (ps_.type[i] == ParticleType::out) continue;
    max_c = std::max(max_c, ps_.sound_speed[i]);
    if (ps_.type[i] != ParticleType::fluid) continue;
    const double az = ps_.az[i] - phys_.gravity;
    max_f2 = std::max(max_f2, ps_.ax[i] * ps_.ax[i] + ps_.ay[i] * ps_.ay[i] + az * az);
  }
  const double h = phys_.h();
  const double dt_f = max_f2 > 0 ? std::sqrt(h / std::sqrt(max_f2)) : std::numeric_limits<double>::infinity();
  const double dt_cv = h / (max_c + max_mu_);
  return phys_.cfl * std::min(dt_f, dt_cv);
}

void Simulation::update(double dt) {
  // Verlet (PHYSICS.md), with an Euler step every `euler_every` steps (the
  // first step included, which also starts the v^{n-1} history cleanly).
  const bool euler = steps_ % config_.euler_every == 0;
  const std::size_t n = ps_.size();
  const double g = phys_.gravity, rho0 = phys_.rho0;
  const Box& dom = case_.domain;
  double vmax2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const ParticleType t = ps_.type[i];
    if (t == ParticleType::out) continue;
    const double rho_new = (euler ? ps_.rho[i] : ps_.rho_prev[i]) + (euler ? 1.0 : 2.0) * dt * ps_.drho[i];
    ps_.rho_prev[i] = ps_.rho[i];
    ps_.rho[i] = (t == ParticleType::boundary && phys_.clamp_boundary_density) ? std::max(rho_new, rho0) : rho_new;
    if (t != ParticleType::fluid) continue;
    const double ax = ps_.ax[i], ay = ps_.ay[i], az = ps_.az[i] - g;  // gravity on fluid only
    ps_.x[i] += dt * (ps_.vx[i] + ps_.ux[i]) + 0.5 * dt * dt * ax;
    ps_.y[i] += dt * (ps_.vy[i] + ps_.uy[i]) + 0.5 * dt * dt * ay;
    ps_.z[i] += dt * (ps_.vz[i] + ps_.uz[i]) + 0.5 * dt * dt * az;
    const double k = euler ? 1.0 : 2.0;
    const double vx = (euler ? ps_.vx[i] : ps_.vx_prev[i]) + k * dt * ax;
    const double vy = (euler ? ps_.vy[i] : ps_.vy_prev[i]) + k * dt * ay;
    const double vz = (euler ? ps_.vz[i] : ps_.vz_prev[i]) + k * dt * az;
    ps_.vx_prev[i] = ps_.vx[i]; ps_.vy_prev[i] = ps_.vy[i]; ps_.vz_prev[i] = ps_.vz[i];
    ps_.vx[i] = vx; ps_.vy[i] = vy; ps_.vz[i] = vz;
    // A particle that left the domain or whose density left [700, 1300] is
    // parked: flagged out, at rest, excluded from the neighbour search.
    const double rho = ps_.rho[i];
    if (!dom.contains(ps_.x[i], ps_.y[i], ps_.z[i]) || !(rho >= 700.0 && rho <= 1300.0)) {
      ps_.type[i] = ParticleType::out;
      ps_.vx[i] = ps_.vy[i] = ps_.vz[i] = ps_.vx_prev[i] = ps_.vy_prev[i] = ps_.vz_prev[i] = 0;
      ps_.rho[i] = ps_.rho_prev[i] = rho0;
      ++lost_;
      continue;
    }
    vmax2 = std::max(vmax2, vx * vx + vy * vy + vz * vz);
  }
  max_speed_ = std::sqrt(vmax2);
  update_derived(phys_, ps_, 0, n);
  const double limit = config_.max_lost_fraction * static_cast<double>(case_.n_fluid);
  if (static_cast<double>(lost_) > limit)
    throw std::runtime_error("simulation stopped at t = " + std::to_string(time_) + " s: " + std::to_string(lost_) +
                             " fluid particles left the domain or the density window [700, 1300] kg/m^3, more than "
                             "max_lost_fraction = " + std::to_string(config_.max_lost_fraction) +
                             " of the fluid; the run is unstable (try a smaller cfl or a finer dx)");
}

void Simulation::step() {
  Stopwatch sw;
  build_neighbours();
  times_.neighbour_list += sw.lap();
  compute_forces();
  times_.force += sw.lap();
  dt_ = time_step();
  update(dt_);
  times_.update += sw.lap();
  time_ += dt_;
  ++steps_;
}

std::size_t Simulation::neighbour_bytes() const { return grid_->bytes(); }

double Simulation::total_mass() const {
  double m = 0;
  for (double v : ps_.mass) m += v;
  return m;
}

std::array<double, 3> Simulation::momentum() const {
  std::array<double, 3> p{0, 0, 0};
  for (std::size_t i = 0; i < ps_.size(); ++i) {
    if (ps_.type[i] != ParticleType::fluid) continue;
    p[0] += ps_.mass[i] * ps_.vx[i];
    p[1] += ps_.mass[i] * ps_.vy[i];
    p[2] += ps_.mass[i] * ps_.vz[i];
  }
  return p;
}

}  // namespace sphnl
