#include "sphnl/simulation.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
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

RebuildSettings rebuild_settings(const RunConfig& c) {
  RebuildSettings r;
  r.list = c.list;
  r.list_steps = c.list_steps;
  r.skin_factor = c.effective_skin_factor();
  r.reorder = c.reorder;
  r.reorder_every = c.reorder_every;
  r.threads = c.threads;
  r.build.simd = c.simd;
  r.build.skip_boundary_pairs = c.skip_boundary_pairs;
  r.build.updates = c.thread_updates;
  return r;
}

}  // namespace

Simulation::Simulation(const RunConfig& config, Communicator* comm)
    : config_(config), case_(dam_break_case(config, phys_)), ps_(case_.particles), policy_(rebuild_settings(config)) {
  init(comm);
}

Simulation::Simulation(const RunConfig& config, Case c, const PhysicsParams& phys, Communicator* comm)
    : config_(config), phys_(phys), case_(std::move(c)), ps_(case_.particles), policy_(rebuild_settings(config)) {
  init(comm);
}

void Simulation::init(Communicator* comm) {
  // The pair loops gather with signed 32-bit indices (gather_index).
  if (ps_.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    throw ConfigError("the case has " + std::to_string(ps_.size()) + " particles; at most " +
                      std::to_string(std::numeric_limits<std::int32_t>::max()) +
                      " are supported (32-bit pair indices); use a coarser dp or split it over MPI ranks");
  if (config_.list_steps < 1)
    throw ConfigError("list_steps must be >= 1 (n_s, the steps a Verlet list is meant to live); got " +
                      std::to_string(config_.list_steps));
  if (case_.period_y > 0 && config_.list != ListKind::cll)
    throw ConfigError("list = " + std::string(to_string(config_.list)) +
                      ": this case has a periodic y, which only the cell-linked list handles (its cell sweep "
                      "wraps across the seam; Verlet lists store pairs without the image shift); use list = cll");
  if (config_.pair_loop == PairLoopKind::direct && config_.list != ListKind::cll)
    throw ConfigError("pair_loop = direct applies to the cell-linked list (list = cll); a Verlet list's loop "
                      "already reads the particles in place and its build uses the gather sweep; use pair_loop = gather");
  if (config_.pair_loop != PairLoopKind::gather && config_.skip_boundary_pairs)
    throw ConfigError("skip_boundary_pairs = true needs pair_loop = gather (it picks the fluid entries of the "
                      "gathered cells); use one of the two");
  if (config_.pair_loop == PairLoopKind::direct && case_.period_y > 0)
    throw ConfigError("pair_loop = direct: this case has a periodic y, whose image shift needs the gathered "
                      "copies of the cells; use pair_loop = gather");
  if (config_.thread_split == ThreadSplit::dynamic && config_.thread_updates == ThreadUpdates::phased)
    throw ConfigError("thread_split = dynamic needs thread_updates = private (the phases of phased updates are "
                      "planned on fixed key ranges per thread); use thread_split = interactions with phased updates");
  if (config_.inner_order != InnerOrder::index && !config_.reorder)
    throw ConfigError("inner_order = " + std::string(to_string(config_.inner_order)) +
                      " orders each cell's particles when the arrays are reordered, and reorder = false never "
                      "reorders them; set reorder = true, or leave inner_order = index");
  if (config_.precision == Precision::mixed && !config_.simd)
    throw ConfigError("precision = mixed has only the vectorised pair kernel (simd = off is an ablation of the "
                      "double kernel); use simd = on, or precision = double");
  pair_options_.loop = config_.pair_loop;
  pair_options_.simd = config_.simd;
  pair_options_.skip_boundary_pairs = config_.skip_boundary_pairs;
  pair_options_.updates = config_.thread_updates;
  pair_options_.split = config_.thread_split;
  if (config_.initial_order == InitialOrder::shuffled) shuffle_memory_order();
  grid_ = make_particle_grid();
  force_ops_.assign(config_.threads, ForceOp<false>{&phys_, 0});
  force_ops_kgc_.assign(config_.threads, ForceOp<true>{&phys_, 0});
  kgc_ops_.assign(config_.threads, KgcMatrixOp{&phys_});
  force_ops_scalar_.assign(config_.threads, ForceOp<false, false>{&phys_, 0});
  force_ops_kgc_scalar_.assign(config_.threads, ForceOp<true, false>{&phys_, 0});
  force_ops_mixed_.assign(config_.threads, ForceOp<false, true, float>{&phys_, 0});
  force_ops_kgc_mixed_.assign(config_.threads, ForceOp<true, true, float>{&phys_, 0});
  kgc_ops_scalar_.assign(config_.threads, KgcMatrixPass<false>{&phys_});
  if (config_.verify_lists && config_.list != ListKind::cll)
    verify_grid_ = make_particle_grid();
  update_derived(phys_, ps_, 0, ps_.size());
  if (comm && comm->size() > 1) {
    domain_ = std::make_unique<DomainExchange>(*comm, phys_, case_.domain, case_.period_y, config_.cell_order,
                                               config_.rebalance_threshold, config_.balance_by);
    domain_->distribute(ps_, 2.0 * phys_.h());
  }
}

std::unique_ptr<ParticleGrid> Simulation::make_particle_grid() const {
  auto grid = std::make_unique<ParticleGrid>(case_.domain, config_.cell_order, config_.gridder, gridder_options(),
                                             case_.period_y);
  grid->set_threads(config_.threads);
  grid->set_inner_order(config_.inner_order);
  return grid;
}

GridderOptions Simulation::gridder_options() const {
  GridderOptions options;
  options.max_parts_in_cell = config_.max_parts_in_cell;
  options.dx = case_.dx;
  options.h = phys_.h();
  options.particles_per_dx3 = config_.lattice == Lattice::bcc ? 2.0 : 1.0;
  options.sliding_variant = config_.gridder_a_variant;
  return options;
}

FlowState Simulation::flow_state() const {
  FlowState f;
  f.h = phys_.h();
  f.dt = dt_;
  f.max_speed = max_speed_;
  f.cfl = phys_.cfl;
  f.c0 = phys_.c0;
  f.gravity = phys_.gravity;
  f.lost = lost_;
  return f;
}

// The phase functions of Table I are kept out of line: called once per step,
// the call costs nothing, and callgrind can then attribute instructions and
// cache misses to each phase (the counters kind, harness/valgrind.py).
[[gnu::noinline]] void Simulation::build_neighbours() {
  neighbours_ready_ = true;
  policy_.prepare(ps_, *grid_, verlet_, flow_state(), stats_, domain_.get());
}

std::uint64_t Simulation::count_list_misses() {
  if (config_.list == ListKind::cll) return 0;
  if (!verify_grid_) verify_grid_ = make_particle_grid();
  return policy_.count_misses(ps_, *verify_grid_, verlet_, phys_.h(), phys_.kernel.support2);
}

[[gnu::noinline]] void Simulation::compute_forces() {
  // One run-time choice per step: the vectorised or the scalar pair kernels,
  // in double or mixed precision. precision=mixed changes the main loop's
  // kernel only: KGC's matrix pass M_a (and so L_a) is double in both.
  if (config_.precision == Precision::mixed) compute_forces_with(force_ops_mixed_, force_ops_kgc_mixed_, kgc_ops_);
  else if (config_.simd) compute_forces_with(force_ops_, force_ops_kgc_, kgc_ops_);
  else compute_forces_with(force_ops_scalar_, force_ops_kgc_scalar_, kgc_ops_scalar_);
}

template <class ForcePlain, class ForceKgc, class KgcMatrix>
void Simulation::compute_forces_with(std::vector<ForcePlain>& force_ops, std::vector<ForceKgc>& force_ops_kgc,
                                     std::vector<KgcMatrix>& kgc_ops) {
  ps_.clear_accumulators();
  PairCounts counts;
  double mu = 0;
  if (config_.kgc) {
    // Second loop (Bonet & Lok 1999): M_a over the same pairs (CLL searches the
    // cells again; a Verlet list is walked again), L_a = M_a^-1, then the main
    // loop with corrected gradients.
    clear_kgc_matrices(ps_);
    for_each_pair(kgc_ops);
    stats_.kgc_fallbacks += invert_kgc_matrices(ps_, owned());
    if (domain_) domain_->refresh_kgc(ps_);
    for (auto& op : force_ops_kgc) op.max_mu = 0;
    counts = for_each_pair(force_ops_kgc);
    for (const auto& op : force_ops_kgc) mu = std::max(mu, op.max_mu);
  } else {
    for (auto& op : force_ops) op.max_mu = 0;
    counts = for_each_pair(force_ops);
    for (const auto& op : force_ops) mu = std::max(mu, op.max_mu);
  }
  max_mu_ = mu;
  stats_.candidates += counts.candidates;
  stats_.interactions += counts.interactions;
  stats_.idle_lanes += counts.idle_lanes;
  stats_.pair_busy_seconds += counts.busy_seconds;
  stats_.pair_region_seconds += counts.region_seconds;
  stats_.pair_reduce_seconds += counts.reduce_seconds;
  // extra_loops (README.md, "Ablations"): more passes over the same pairs
  // doing real work whose result is kept but not applied, after the main loop
  // so that L_a of KGC is already in use and the physics is unchanged.
  for (int k = 0; k < config_.extra_loops; ++k) {
    stats_.extra_loop_checksum += extra_loop_pass(kgc_ops);
    ++stats_.extra_loop_passes;
  }
}

template <class KgcMatrix>
double Simulation::extra_loop_pass(std::vector<KgcMatrix>& kgc_ops) {
  clear_kgc_matrices(ps_);
  for_each_pair(kgc_ops);
  // The owned particles' traces, summed over ranks: P ranks give the serial
  // checksum up to summation order (ghosts hold partial M_a, and are counted
  // by their owners).
  const double local = kgc_trace_sum(ps_, owned());
  return domain_ ? domain_->sum(local) : local;
}

double Simulation::extra_loop_pass() {
  return config_.simd ? extra_loop_pass(kgc_ops_) : extra_loop_pass(kgc_ops_scalar_);
}

void Simulation::shuffle_memory_order() {
  // A fixed seed and our own Fisher-Yates (std::shuffle's algorithm is the
  // library's choice), so every build gives the same order.
  const std::size_t n = ps_.size();
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::mt19937_64 rng(kShuffleSeed);
  for (std::size_t k = n; k > 1; --k) std::swap(order[k - 1], order[rng() % k]);
  std::vector<double> scratch;
  std::vector<std::uint32_t> scratch_u32;
  ps_.permute(order, scratch, scratch_u32);
}

[[gnu::noinline]] double Simulation::time_step() const {
  // eq. 7: dt = CFL min(dt_f, dt_cv). dt_cv uses the largest sound speed and
  // the largest |h v.r/(r^2+eta^2)| over all pairs (as SPHysics codes it).
  double max_f2 = 0, max_c = 0;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(owned());
  const int threads = config_.threads;
  // Maxima: the same for any split over threads.
#pragma omp parallel for num_threads(threads) schedule(static) reduction(max : max_f2, max_c) if (threads > 1)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    if (ps_.type[i] == ParticleType::out) continue;
    max_c = std::max(max_c, ps_.sound_speed[i]);
    if (ps_.type[i] != ParticleType::fluid) continue;
    const double az = ps_.az[i] - phys_.gravity;
    max_f2 = std::max(max_f2, ps_.ax[i] * ps_.ax[i] + ps_.ay[i] * ps_.ay[i] + az * az);
  }
  double max_mu = max_mu_;
  if (domain_) {  // the serial maxima exactly: dt is the same on every rank
    double m[3] = {max_f2, max_c, max_mu};
    domain_->max(m);
    max_f2 = m[0]; max_c = m[1]; max_mu = m[2];
  }
  const double h = phys_.h();
  const double dt_f = max_f2 > 0 ? std::sqrt(h / std::sqrt(max_f2)) : std::numeric_limits<double>::infinity();
  const double dt_cv = h / (max_c + max_mu);
  return phys_.cfl * std::min(dt_f, dt_cv);
}

[[gnu::noinline]] void Simulation::update(double dt) {
  // Verlet (docs/PHYSICS.md), with an Euler step every `euler_every` steps (the
  // first step included, which also starts the v^{n-1} history cleanly).
  const bool euler = steps_ % config_.euler_every == 0;
  const std::size_t n = owned();
  const double g = phys_.gravity, rho0 = phys_.rho0;
  const Box& dom = case_.domain;
  double vmax2 = 0;
  std::size_t newly_lost = 0;
  const int threads = config_.threads;
  // Every particle is integrated on its own and the reductions are a maximum
  // and a count, so any split over threads gives the same bits.
#pragma omp parallel for num_threads(threads) schedule(static) reduction(max : vmax2) reduction(+ : newly_lost) \
    if (threads > 1)
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
    if (case_.period_y > 0) {  // back into [lo, lo + period): the cell sweep finds its images
      double& y = ps_.y[i];
      const double lo = dom.lo[1], hi = lo + case_.period_y;
      if (y < lo) y += case_.period_y;
      else if (y >= hi) y -= case_.period_y;
      if (y >= hi || y < lo) y = lo;  // -1e-18 + period rounds to period itself
    }
    // A particle that left the domain or whose density left [700, 1300] is
    // parked: flagged out, at rest, excluded from the neighbour search.
    const double rho = ps_.rho[i];
    if (!dom.contains(ps_.x[i], ps_.y[i], ps_.z[i]) || !(rho >= 700.0 && rho <= 1300.0)) {
      ps_.type[i] = ParticleType::out;
      ps_.vx[i] = ps_.vy[i] = ps_.vz[i] = ps_.vx_prev[i] = ps_.vy_prev[i] = ps_.vz_prev[i] = 0;
      ps_.rho[i] = ps_.rho_prev[i] = rho0;
      ++newly_lost;
      continue;
    }
    vmax2 = std::max(vmax2, vx * vx + vy * vy + vz * vz);
  }
  if (domain_) {
    vmax2 = domain_->max(vmax2);
    newly_lost = static_cast<std::size_t>(domain_->sum(static_cast<double>(newly_lost)));
  }
  lost_ += newly_lost;
  max_speed_ = std::sqrt(vmax2);
#pragma omp parallel num_threads(threads) if (threads > 1)
  {
    const std::size_t t = static_cast<std::size_t>(omp_get_thread_num()), team = static_cast<std::size_t>(omp_get_num_threads());
    update_derived(phys_, ps_, n * t / team, n * (t + 1) / team);
  }
  const double limit = config_.max_lost_fraction * static_cast<double>(case_.n_fluid);
  if (static_cast<double>(lost_) > limit)
    throw std::runtime_error("simulation stopped at t = " + std::to_string(time_) + " s: " + std::to_string(lost_) +
                             " fluid particles left the domain or the density window [700, 1300] kg/m^3, more than "
                             "max_lost_fraction = " + std::to_string(config_.max_lost_fraction) +
                             " of the fluid; the run is unstable (try a smaller cfl or a finer dx)");
}

void Simulation::step() {
  Stopwatch sw;
  // A distributed run's exchanges and reductions are timed apart: each phase
  // keeps its own work, `communication` the rest.
  double comm_mark = domain_ ? domain_->comm_seconds() : 0;
  auto phase_done = [&](double& phase) {
    const double lap = sw.lap(), comm = domain_ ? domain_->comm_seconds() - comm_mark : 0;
    comm_mark += comm;
    phase += lap - comm;
    times_.communication += comm;
  };
  if (!neighbours_ready_) build_neighbours();
  phase_done(times_.neighbour_list);
  if (config_.verify_lists && config_.list != ListKind::cll) {  // a check, not part of any phase
    stats_.vl_misses += count_list_misses();
    ++stats_.verified_steps;
    sw.lap();
  }
  compute_forces();
  phase_done(times_.force);
  dt_ = time_step();
  update(dt_);
  phase_done(times_.update);
  time_ += dt_;
  ++steps_;
  neighbours_ready_ = false;
}

void Simulation::restore(const ParticleSet& state, double time, long steps, std::size_t lost) {
  if (domain_) throw std::logic_error("Simulation::restore is for serial runs; a distributed run cannot restore a state");
  const std::size_t n = state.size();
  for (auto [dst, src] : {std::pair{&ps_.x, &state.x}, {&ps_.y, &state.y}, {&ps_.z, &state.z}, {&ps_.vx, &state.vx},
                          {&ps_.vy, &state.vy}, {&ps_.vz, &state.vz}, {&ps_.rho, &state.rho},
                          {&ps_.vx_prev, &state.vx_prev}, {&ps_.vy_prev, &state.vy_prev},
                          {&ps_.vz_prev, &state.vz_prev}, {&ps_.rho_prev, &state.rho_prev}, {&ps_.mass, &state.mass}})
    dst->assign(src->begin(), src->begin() + static_cast<std::ptrdiff_t>(n));
  ps_.type.assign(state.type.begin(), state.type.end());
  ps_.id.assign(state.id.begin(), state.id.end());
  if (config_.initial_order == InitialOrder::shuffled) shuffle_memory_order();
  update_derived(phys_, ps_, 0, n);
  double vmax2 = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (ps_.type[i] == ParticleType::fluid)
      vmax2 = std::max(vmax2, ps_.vx[i] * ps_.vx[i] + ps_.vy[i] * ps_.vy[i] + ps_.vz[i] * ps_.vz[i]);
  max_speed_ = std::sqrt(vmax2);
  time_ = time;
  steps_ = steps;
  lost_ = lost;
  dt_ = 0;
  times_ = PhaseTimes{};
  stats_ = NeighbourStats{};
  policy_.invalidate();  // indices and positions changed: Verlet lists are rebuilt
  neighbours_ready_ = false;
}

std::size_t Simulation::neighbour_bytes() const {
  // Verlet lists add the list (offsets + indices) and VL_X's positions at the build.
  return grid_->bytes() + verlet_.list_bytes() + policy_.bytes();
}

double Simulation::total_mass() const {
  // Summed in id order, so that reordering (which permutes memory) cannot
  // change the last bits of the total; distributed, at rank 0 over the
  // gathered (id, mass) of every rank, then handed to all.
  std::vector<double> by_id(case_.n_fluid + case_.n_boundary);
  if (domain_) {
    std::vector<double> mine;
    for (std::size_t i = 0; i < owned(); ++i) mine.insert(mine.end(), {static_cast<double>(ps_.id[i]), ps_.mass[i]});
    std::vector<std::vector<double>> all;
    domain_->comm().gather(mine, all);
    for (const auto& r : all)
      for (std::size_t k = 0; k < r.size(); k += 2) by_id[static_cast<std::size_t>(r[k])] = r[k + 1];
  } else {
    by_id.resize(ps_.size());
    for (std::size_t i = 0; i < ps_.size(); ++i) by_id[ps_.id[i]] = ps_.mass[i];
  }
  double m = 0;
  for (double v : by_id) m += v;
  return domain_ ? domain_->comm().sum(domain_->comm().rank() == 0 ? m : 0.0) : m;
}

std::array<double, 3> Simulation::momentum() const {
  std::array<double, 3> p{0, 0, 0};
  for (std::size_t i = 0; i < owned(); ++i) {
    if (ps_.type[i] != ParticleType::fluid) continue;
    p[0] += ps_.mass[i] * ps_.vx[i];
    p[1] += ps_.mass[i] * ps_.vy[i];
    p[2] += ps_.mass[i] * ps_.vz[i];
  }
  if (domain_) domain_->comm().sum(p);
  return p;
}

}  // namespace sphnl
