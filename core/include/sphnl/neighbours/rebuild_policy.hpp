#pragma once
// RebuildPolicy: when the neighbour structures are rebuilt (paper §2.5), for
// the three pair sources:
//   CLL   grids again at every step (no list);
//   VL_C  a Verlet list with skin dh rebuilt every C = list_steps steps;
//   VL_X  a Verlet list rebuilt when some particle has moved more than dh/2
//         since the build (the max-displacement check: no pair can then have
//         closed from beyond 2H = 2h + dh to below 2h).
// The skin is dh = nu 2 Vmax n_s dt. A particle that leaves the domain forces a
// rebuild (the paper's criteria only watch motion). With verify_lists, the
// miss check counts the pairs with r < 2h that the current list lacks.
// Simulation calls prepare() once per step (phase 1 of Table I) and asks
// nothing else of the decision.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "sphnl/kinds.hpp"
#include "sphnl/neighbours/cell_linked_list.hpp"
#include "sphnl/neighbours/neighbour_stats.hpp"
#include "sphnl/neighbours/particle_grid.hpp"
#include "sphnl/neighbours/verlet_list.hpp"
#include "sphnl/parallel/distributed_neighbours.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

struct RebuildSettings {
  ListKind list = ListKind::cll;
  int list_steps = 1;        // n_s: C of VL_C, X of VL_X (>= 1)
  double skin_factor = 1.0;  // nu of dh (the effective value, > 0)
  bool reorder = true;
  int reorder_every = 1;     // reorder at every k-th build
  int threads = 1;
  PairLoopOptions build;     // simd, skip_boundary_pairs of the Verlet-list build sweep
};

/// What the policy needs to know of the flow at the start of a step.
struct FlowState {
  double h = 0;          // smoothing length
  double dt = 0;         // last time step; <= 0 before the first step
  double max_speed = 0;  // largest fluid |v| after the last step
  double cfl = 0, c0 = 0, gravity = 0;
  std::size_t lost = 0;  // particles out so far
};

class RebuildPolicy {
 public:
  explicit RebuildPolicy(const RebuildSettings& settings);

  /// Phase 1 of a step: grids `ps` into `grid` (CLL) or decides whether the
  /// Verlet list `verlet` is still valid and rebuilds it when not. Counts
  /// builds, list steps, forced rebuilds and the list's size into `stats`.
  /// A distributed run passes `dist`: the decision is taken on every rank alike
  /// (flow.lost is the global count), particles and ghosts are exchanged before
  /// each build and the ghosts refreshed between builds.
  void prepare(ParticleSet& ps, ParticleGrid& grid, VerletList& verlet, const FlowState& flow, NeighbourStats& stats,
               DistributedNeighbours* dist = nullptr);

  /// dh of a Verlet list that should live list_steps steps (§2.5).
  double skin(const FlowState& flow) const;

  /// Pairs with r^2 < support2 that `verlet` misses, by a cell-linked search of
  /// the same positions in `verify_grid` (cells of 2h, never reordering).
  /// 0 for CLL.
  std::uint64_t count_misses(ParticleSet& ps, ParticleGrid& verify_grid, VerletList& verlet, double h,
                             double support2);

  /// Particle indices and positions changed (a restored state): the next
  /// prepare() rebuilds.
  void invalidate() { list_valid_ = false; }

  /// Bytes the policy keeps: VL_X's positions at the build.
  std::size_t bytes() const;

 private:
  bool reorder_now(const NeighbourStats& stats) const;
  bool moved_more_than_half_skin(const ParticleSet& ps) const;

  RebuildSettings settings_;
  std::vector<double> x_build_, y_build_, z_build_;  // VL_X: positions at the build
  bool list_valid_ = false;
  std::uint64_t list_age_ = 0;
  std::size_t lost_at_build_ = 0;
  double skin_ = 0;
  CellLinkedList verify_cll_;
  struct NoOp {
    static constexpr unsigned kFields = fields::position;
    void interact(const ParticleView&, std::uint32_t, const std::uint32_t*, int) {}
  };
  std::vector<NoOp> no_ops_;
};

}  // namespace sphnl
