#pragma once
// Simulation: the integrator of the case and the phase timing of the paper's
// Table I. It holds one of each part chosen at run time from a RunConfig
// (particle grid, pair source, pair kernel) and asks the RebuildPolicy once per
// step whether the neighbour structures must be rebuilt.
#include <cstdint>
#include <memory>
#include <vector>

#include "sphnl/case.hpp"
#include "sphnl/config.hpp"
#include "sphnl/neighbours/cell_linked_list.hpp"
#include "sphnl/neighbours/neighbour_stats.hpp"
#include "sphnl/neighbours/pair_counts.hpp"
#include "sphnl/neighbours/particle_grid.hpp"
#include "sphnl/neighbours/rebuild_policy.hpp"
#include "sphnl/neighbours/verlet_list.hpp"
#include "sphnl/kgc.hpp"
#include "sphnl/pair_kernel.hpp"
#include "sphnl/parallel/communicator.hpp"
#include "sphnl/parallel/domain_exchange.hpp"
#include "sphnl/physics.hpp"

namespace sphnl {

/// Wall seconds spent in each phase of Table I, summed over steps.
struct PhaseTimes {
  double neighbour_list = 0;  // cells division, particles in cells, reordering, Verlet list builds
  double force = 0;           // pair loops (KGC pre-pass included)
  double update = 0;          // time step, integration, equation of state
  double communication = 0;   // distributed runs: exchanges and reductions (taken out of the three above)
  double total() const { return neighbour_list + force + update + communication; }
};

class Simulation {
 public:
  /// The dam break of paper §2.2 at the size the config asks for. With a
  /// communicator of more than one rank, this Simulation is one rank of a
  /// distributed run (parallel/domain_exchange.hpp): every rank builds the
  /// case, keeps its share of the cells and integrates only its particles.
  explicit Simulation(const RunConfig& config, Communicator* comm = nullptr);
  /// Any case (tests: tanks, blobs, single particles).
  Simulation(const RunConfig& config, Case c, const PhysicsParams& phys, Communicator* comm = nullptr);

  /// Advances one time step.
  void step();
  /// Replaces the particle state (positions, velocities, densities, both
  /// Verlet levels, masses, types, ids) with `state`, in `state`'s order, and
  /// sets the clock; timers and counters restart from zero and every
  /// neighbour structure is rebuilt at the next step.
  void restore(const ParticleSet& state, double time, long steps, std::size_t lost);

  const RunConfig& config() const { return config_; }
  const PhysicsParams& physics() const { return phys_; }
  /// This rank's particles [0, owned()), then its ghosts (distributed runs).
  const ParticleSet& particles() const { return ps_; }
  ParticleSet& particles() { return ps_; }
  const Case& case_info() const { return case_; }
  double time() const { return time_; }
  double last_dt() const { return dt_; }
  long steps_done() const { return steps_; }
  /// Particles lost so far, over all ranks.
  std::size_t lost() const { return lost_; }
  /// Particles this rank integrates: all of them in a serial run.
  std::size_t owned() const { return domain_ ? domain_->owned() : ps_.size(); }
  /// The distributed run's exchange (null in a serial run).
  const DomainExchange* domain() const { return domain_.get(); }
  const PhaseTimes& phase_times() const { return times_; }
  const NeighbourStats& neighbour_stats() const { return stats_; }
  /// Bytes of the neighbour structures (gridding, ordering, reordering, lists).
  std::size_t neighbour_bytes() const;
  /// Total mass, summed in id order: reordering permutes memory, and a sum in
  /// memory order would change its last bits from step to step (masses never
  /// change, so this sum is exactly the same at every step). Distributed: over
  /// all ranks, the same bits as the serial run (every rank must call it).
  double total_mass() const;
  /// Sum of m v over fluid particles (distributed: over all ranks; every rank must call it).
  std::array<double, 3> momentum() const;
  /// Largest |v| over fluid particles (after the last step).
  double max_speed() const { return max_speed_; }

  /// Runs the pair source of the config with one op per thread (the one
  /// run-time dispatch per pass); public for tests of pair sources.
  template <PairOperation Op>
  PairCounts for_each_pair(std::vector<Op>& ops);
  /// Prepares the pair source for the current positions (phase 1) as the
  /// RebuildPolicy decides. step() calls it unless it was already called since
  /// the last step (tests inspect the pairs first).
  void build_neighbours();
  /// Counts the pairs with r < 2h that the current Verlet list misses, by a
  /// cell-linked search of the same positions (verify_lists; 0 for CLL).
  std::uint64_t count_list_misses();
  /// dh of VL_C / VL_X for a list that should live `list_steps` steps
  /// (paper §2.5): nu 2 Vmax n_s dt, with Vmax and dt of the last step.
  double list_skin() const { return policy_.skin(flow_state()); }
  /// One pass of `extra_loops` over the pairs of the current neighbour
  /// structures: M_a of KGC (KgcMatrixOp) into the particles' kgc_m, not
  /// applied; returns the sum of the traces of M_a over the owned particles
  /// of every rank (the checksum that NeighbourStats::extra_loop_checksum
  /// adds up; collective in a distributed run). Public for its test.
  double extra_loop_pass();
  /// Seed of `initial_order=shuffled`.
  static constexpr std::uint64_t kShuffleSeed = 20111;

 private:
  void init(Communicator* comm);
  /// What the gridders need to know of the case (gridder C sizes its rows from it).
  GridderOptions gridder_options() const;
  /// A ParticleGrid over this case's domain (and periodic y) with the configured order and gridder.
  std::unique_ptr<ParticleGrid> make_particle_grid() const;
  /// The flow as the rebuild policy sees it at the start of a step.
  FlowState flow_state() const;
  void compute_forces();
  template <class ForcePlain, class ForceKgc, class KgcMatrix>
  void compute_forces_with(std::vector<ForcePlain>& force_ops, std::vector<ForceKgc>& force_ops_kgc,
                           std::vector<KgcMatrix>& kgc_ops);
  template <class KgcMatrix>
  double extra_loop_pass(std::vector<KgcMatrix>& kgc_ops);
  /// initial_order=shuffled: permutes the particle arrays by a fixed random permutation.
  void shuffle_memory_order();
  void update(double dt);
  double time_step() const;

  RunConfig config_;
  PhysicsParams phys_;
  Case case_;
  ParticleSet& ps_;
  std::unique_ptr<DomainExchange> domain_;  // distributed runs only
  std::unique_ptr<ParticleGrid> grid_;
  CellLinkedList cll_;
  VerletList verlet_;
  RebuildPolicy policy_;
  bool neighbours_ready_ = false;
  std::unique_ptr<ParticleGrid> verify_grid_;  // verify_lists: the miss check's own grid
  std::vector<KgcMatrixOp> kgc_ops_;
  std::vector<ForceOp<false>> force_ops_;
  std::vector<ForceOp<true>> force_ops_kgc_;
  // simd=off: the same operations with their neighbour loops kept scalar
  std::vector<KgcMatrixPass<false>> kgc_ops_scalar_;
  std::vector<ForceOp<false, false>> force_ops_scalar_;
  std::vector<ForceOp<true, false>> force_ops_kgc_scalar_;
  // precision=mixed: the pair's arithmetic in float (pair_kernel.hpp)
  std::vector<ForceOp<false, true, float>> force_ops_mixed_;
  std::vector<ForceOp<true, true, float>> force_ops_kgc_mixed_;
  PairLoopOptions pair_options_;
  PhaseTimes times_;
  NeighbourStats stats_;
  double time_ = 0, dt_ = 0, max_speed_ = 0, max_mu_ = 0;
  long steps_ = 0;
  std::size_t lost_ = 0;
};

template <PairOperation Op>
PairCounts Simulation::for_each_pair(std::vector<Op>& ops) {
  switch (config_.list) {
    case ListKind::cll: return cll_.for_each_pair(*grid_, ps_, ops, phys_.kernel.support2, pair_options_);
    case ListKind::vlc:
    case ListKind::vlx: return verlet_.for_each_pair(ps_, ops, phys_.kernel.support2, pair_options_.simd,
                                                         pair_options_.loop == PairLoopKind::masked);
  }
  throw ConfigError("unknown list kind");
}

}  // namespace sphnl
