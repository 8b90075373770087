#include "sphnl/neighbours/rebuild_policy.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace sphnl {

RebuildPolicy::RebuildPolicy(const RebuildSettings& settings)
    : settings_(settings), no_ops_(static_cast<std::size_t>(settings.threads)) {}

bool RebuildPolicy::reorder_now(const NeighbourStats& stats) const {
  return settings_.reorder && stats.builds % static_cast<std::uint64_t>(settings_.reorder_every) == 0;
}

void RebuildPolicy::prepare(ParticleSet& ps, ParticleGrid& grid, VerletList& verlet, const FlowState& flow,
                            NeighbourStats& stats, DistributedNeighbours* dist) {
  auto build_grid = [&](double cell) {
    if (dist) dist->exchange_particles(ps, cell);
    const bool permuted = grid.build(ps, cell, reorder_now(stats), dist ? dist->owned() : ParticleGrid::kAllOwned);
    if (dist) dist->built(grid, permuted, ps);
  };
  if (settings_.list == ListKind::cll) {
    build_grid(2.0 * flow.h);
    ++stats.builds;
    stats.max_steps_per_list = 1;
    return;
  }
  // A particle that went out must leave every list at once (the paper's
  // criteria only watch motion): rebuild, and count it apart.
  const bool forced = list_valid_ && flow.lost != lost_at_build_;
  bool rebuild = !list_valid_ || forced;
  if (!rebuild && settings_.list == ListKind::vlc)
    rebuild = list_age_ >= static_cast<std::uint64_t>(settings_.list_steps);  // VL_C: exactly C steps
  else if (!rebuild)
    rebuild = dist ? dist->any_rank(moved_more_than_half_skin(ps)) : moved_more_than_half_skin(ps);  // VL_X
  if (rebuild) {
    skin_ = skin(flow);
    const double cell = 2.0 * flow.h + skin_;  // 2H = 2h + dh
    build_grid(cell);
    verlet.build(grid, ps, cell * cell, settings_.threads, settings_.build);
    if (settings_.list == ListKind::vlx) {  // positions after any reordering: indices match the list's
      x_build_.assign(ps.x.begin(), ps.x.end());
      y_build_.assign(ps.y.begin(), ps.y.end());
      z_build_.assign(ps.z.begin(), ps.z.end());
    }
    list_valid_ = true;
    list_age_ = 0;
    lost_at_build_ = flow.lost;
    ++stats.builds;
    stats.skin = skin_;
    stats.list_pairs = verlet.pairs();
    stats.list_pairs_built += stats.list_pairs;
    stats.list_bytes = verlet.list_bytes();
    stats.max_list_bytes = std::max(stats.max_list_bytes, stats.list_bytes);
    if (forced) ++stats.forced_rebuilds;
  } else if (dist) {
    dist->refresh_ghosts(ps);
  }
  ++list_age_;
  ++stats.list_steps;
  stats.max_steps_per_list = std::max(stats.max_steps_per_list, list_age_);
}

bool RebuildPolicy::moved_more_than_half_skin(const ParticleSet& ps) const {
  // VL_X (§2.5): valid while no particle has moved more than dh/2 since the
  // build (then no pair can have closed from beyond 2H = 2h + dh to below 2h).
  const double limit2 = 0.25 * skin_ * skin_;
  const std::size_t n = ps.size();
  const double *x = ps.x.data(), *y = ps.y.data(), *z = ps.z.data();
  const double *x0 = x_build_.data(), *y0 = y_build_.data(), *z0 = z_build_.data();
  double max_d2 = 0;
#pragma omp simd reduction(max : max_d2)
  for (std::size_t i = 0; i < n; ++i) {
    const double dx = x[i] - x0[i], dy = y[i] - y0[i], dz = z[i] - z0[i];
    max_d2 = std::max(max_d2, dx * dx + dy * dy + dz * dz);
  }
  return max_d2 > limit2;
}

double RebuildPolicy::skin(const FlowState& flow) const {
  // dh = nu (2 Vmax n_s dt) (§2.5). Before any step (or after restore) there is
  // no dt yet: use eq. 7 without forces or viscosity, CFL h / c0, and at least
  // the speed that free fall reaches over the list's life, g n_s dt (a flow
  // starting at rest has Vmax = 0, which would give a list with no skin).
  const double ns = static_cast<double>(settings_.list_steps);
  const bool first = flow.dt <= 0;
  const double dt = first ? flow.cfl * flow.h / flow.c0 : flow.dt;
  const double vmax = first ? std::max(flow.max_speed, flow.gravity * ns * dt) : flow.max_speed;
  return settings_.skin_factor * 2.0 * vmax * ns * dt;
}

std::uint64_t RebuildPolicy::count_misses(ParticleSet& ps, ParticleGrid& verify_grid, VerletList& verlet, double h,
                                          double support2) {
  if (settings_.list == ListKind::cll) return 0;
  verify_grid.build(ps, 2.0 * h, false);
  const std::uint64_t truth = verify_cll_.for_each_pair(verify_grid, ps, no_ops_, support2).interactions;
  // Every listed pair that passes the 2h filter is a true pair and is listed
  // once, so the shortfall is exactly the pairs the list misses.
  const std::uint64_t found = verlet.for_each_pair(ps, no_ops_, support2).interactions;
  if (found > truth)
    throw std::logic_error("Verlet list yields " + std::to_string(found) + " pairs, more than the " +
                           std::to_string(truth) + " pairs within 2h: a pair is listed twice");
  return truth - found;
}

std::size_t RebuildPolicy::bytes() const {
  return (x_build_.capacity() + y_build_.capacity() + z_build_.capacity()) * sizeof(double);
}

}  // namespace sphnl
