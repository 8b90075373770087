#pragma once
// DomainExchange: one rank's side of the distributed solver (docs/DESIGN.md,
// "The parallel layer"). The rank owns the particles of a contiguous range of
// cell keys (KeyPartition, along the cell order's curve) and holds after them,
// as ghosts, copies of the particles of the cells next to its own (one layer:
// cells are 2h for CLL, 2H = 2h + dh for Verlet lists). Pairs across a rank
// boundary are computed on both sides; each rank integrates only its own
// particles, so the forces are the serial ones up to summation order.
//   at a build      ghosts dropped; rebalanced when the busiest rank's work
//                   (balance_by: estimated candidate pairs, or particles) is
//                   more than (1 + rebalance_threshold) x the mean, or the
//                   cell size changed;
//                   particles that left the rank's cells migrate (CLL: every
//                   step); the new ghosts arrive (x, v, rho, mass, type, id)
//   between builds  the same ghosts, only x, v, rho travel (Verlet lists)
//   with KGC        L_a of the ghosts after the pre-pass
// Out particles stay with the rank that last owned them (they are not gridded).
#include <cstdint>
#include <span>
#include <memory>
#include <vector>

#include "sphnl/grid.hpp"
#include "sphnl/kinds.hpp"
#include "sphnl/orderings/cell_order.hpp"
#include "sphnl/parallel/communicator.hpp"
#include "sphnl/parallel/decomposition.hpp"
#include "sphnl/parallel/distributed_neighbours.hpp"
#include "sphnl/physics.hpp"

namespace sphnl {

class DomainExchange final : public DistributedNeighbours {
 public:
  DomainExchange(Communicator& comm, const PhysicsParams& phys, const Box& domain, double period_y,
                 CellOrderKind order, double rebalance_threshold, BalanceBy balance = BalanceBy::interactions);

  /// Keeps of the full particle set (the same on every rank) the particles of
  /// this rank's share of cells of side `cell`, balanced by work. Throws
  /// ConfigError when there are more ranks than cells.
  void distribute(ParticleSet& ps, double cell);

  bool any_rank(bool local) override;
  void exchange_particles(ParticleSet& ps, double cell) override;
  std::size_t owned() const override { return owned_; }
  void built(const ParticleGrid& grid, bool permuted, ParticleSet& ps) override;
  void refresh_ghosts(ParticleSet& ps) override;
  /// L_a of the ghosts (KGC), after the pre-pass inverted the owned ones.
  void refresh_kgc(ParticleSet& ps);

  /// Reductions over ranks, timed as communication.
  double max(double v);
  void max(std::span<double> v);
  double sum(double v);
  void sum(std::span<double> v);

  Communicator& comm() { return comm_; }
  const Communicator& comm() const { return comm_; }
  std::size_t ghosts() const { return ghosts_; }
  /// Seconds spent in communication calls (exchanges and reductions).
  double comm_seconds() const { return comm_seconds_; }
  /// Payload bytes this rank sent to other ranks, in total.
  std::uint64_t bytes_sent() const { return bytes_sent_; }
  /// Times the key ranges were recomputed (the first distribution included).
  std::uint64_t partitions() const { return partitions_; }
  const KeyPartition& partition() const { return partition_; }
  /// Particles that arrived from other ranks (migration), in total.
  std::uint64_t migrated() const { return migrated_; }
  /// This rank's estimated pair work at the last build (interaction_weights
  /// over its own cells, counting its ghosts); 0 when balancing by particles.
  double work_estimate() const { return work_estimate_; }
  /// The ranks this rank exchanges ghosts with (see Decomposition::partners).
  const std::vector<int>& partners() const { return partners_; }
  /// VL_X rebuilds this rank took only because another rank's particles moved more than dh/2.
  std::uint64_t remote_rebuilds() const { return remote_rebuilds_; }

  /// Work weight of a particle (CellSweep's thread split uses the same): a
  /// fluid particle meets every neighbour, a boundary one only fluid ones.
  static double weight(ParticleType t) { return t == ParticleType::fluid ? 1.0 : t == ParticleType::boundary ? 0.25 : 0.0; }

 private:
  void set_cell_size(double cell);
  void compute_keys(const ParticleSet& ps);
  void check_cells() const;
  /// Work of every key of the domain; `reduce`: the particles are this rank's
  /// own (counts summed over ranks), else every rank holds all of them.
  std::vector<double> key_weights(const ParticleSet& ps, bool reduce);
  /// This rank's interaction_weights, from its own particles and its ghosts.
  double local_work_estimate(const ParticleSet& ps);
  /// Adds the fluid and boundary particles among n (key, type) to type_counts_.
  void count_types(const std::uint32_t* keys, const ParticleType* type, std::size_t n);
  void repartition(const ParticleSet& ps);
  void migrate(ParticleSet& ps);
  void send_ghosts(ParticleSet& ps);
  /// All-to-all (migration: after a re-cut a particle may go to any rank), or,
  /// with `neighbours`, with partners_ only (ghosts and their refreshes).
  void exchange(const std::vector<std::vector<double>>& send, std::vector<std::vector<double>>& recv,
                bool neighbours = false);
  /// Sends `fields` of the particles in send_index_ and writes them to the ghosts of recv_index_.
  void refresh(std::span<std::vector<double>* const> fields);

  Communicator& comm_;
  const PhysicsParams& phys_;
  Box domain_;
  double period_y_;
  double threshold_;
  BalanceBy balance_;
  double work_estimate_ = 0;
  // balance_by interactions: fluid then boundary particles per key, and each key's estimated work
  std::vector<double> type_counts_, key_work_;
  std::vector<std::uint32_t> ghost_keys_;
  std::vector<int> partners_;   // Decomposition::partners of this rank, for partition_ on grid_
  bool partners_stale_ = true;  // partition_ or grid_ changed since partners_ was made
  int rank_, ranks_;
  CellGrid grid_;
  std::unique_ptr<CellOrder> order_;
  KeyPartition partition_;
  std::size_t owned_ = 0, ghosts_ = 0;
  std::vector<std::uint32_t> keys_;                        // of the owned particles
  std::vector<std::vector<std::uint32_t>> send_index_;     // per rank: particles whose copies it holds
  std::vector<std::vector<std::uint32_t>> recv_index_;     // per rank: ghosts it sends, in its order
  std::vector<std::vector<double>> send_, recv_;
  std::vector<std::uint32_t> inverse_;
  double comm_seconds_ = 0;
  std::uint64_t bytes_sent_ = 0, partitions_ = 0, migrated_ = 0, remote_rebuilds_ = 0;
};

}  // namespace sphnl
