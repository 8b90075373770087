#include "sphnl/parallel/domain_exchange.hpp"

#include <algorithm>
#include <numeric>
#include <string>

#include "sphnl/input_error.hpp"
#include "sphnl/timer.hpp"

namespace sphnl {

namespace {

// A migrating particle carries its whole state (both Verlet levels); the
// derived fields (eq. 5) are recomputed from rho on arrival, bit for bit.
constexpr std::size_t kMigrateFields = 14;
void pack_particle(const ParticleSet& ps, std::size_t i, std::vector<double>& out) {
  out.insert(out.end(), {ps.x[i], ps.y[i], ps.z[i], ps.vx[i], ps.vy[i], ps.vz[i], ps.rho[i], ps.vx_prev[i],
                         ps.vy_prev[i], ps.vz_prev[i], ps.rho_prev[i], ps.mass[i], static_cast<double>(ps.type[i]),
                         static_cast<double>(ps.id[i])});
}
void unpack_particle(const double* r, ParticleSet& ps, std::size_t i) {
  ps.x[i] = r[0]; ps.y[i] = r[1]; ps.z[i] = r[2];
  ps.vx[i] = r[3]; ps.vy[i] = r[4]; ps.vz[i] = r[5]; ps.rho[i] = r[6];
  ps.vx_prev[i] = r[7]; ps.vy_prev[i] = r[8]; ps.vz_prev[i] = r[9]; ps.rho_prev[i] = r[10];
  ps.mass[i] = r[11];
  ps.type[i] = static_cast<ParticleType>(static_cast<int>(r[12]));
  ps.id[i] = static_cast<std::uint32_t>(r[13]);
}

// A ghost carries what the pair passes read (ForceOp, KgcMatrixOp, the
// distance filter): position, velocity, density, mass, type; its id is kept
// for outputs and tests.
constexpr std::size_t kGhostFields = 10;
void pack_ghost(const ParticleSet& ps, std::size_t i, std::vector<double>& out) {
  out.insert(out.end(), {ps.x[i], ps.y[i], ps.z[i], ps.vx[i], ps.vy[i], ps.vz[i], ps.rho[i], ps.mass[i],
                         static_cast<double>(ps.type[i]), static_cast<double>(ps.id[i])});
}
void unpack_ghost(const double* r, ParticleSet& ps, std::size_t i) {
  ps.x[i] = r[0]; ps.y[i] = r[1]; ps.z[i] = r[2];
  ps.vx[i] = r[3]; ps.vy[i] = r[4]; ps.vz[i] = r[5]; ps.rho[i] = r[6];
  ps.mass[i] = r[7];
  ps.type[i] = static_cast<ParticleType>(static_cast<int>(r[8]));
  ps.id[i] = static_cast<std::uint32_t>(r[9]);
}

}  // namespace

DomainExchange::DomainExchange(Communicator& comm, const PhysicsParams& phys, const Box& domain, double period_y,
                               CellOrderKind order, double rebalance_threshold, BalanceBy balance)
    : comm_(comm), phys_(phys), domain_(domain), period_y_(period_y), threshold_(rebalance_threshold), balance_(balance),
      rank_(comm.rank()), ranks_(comm.size()), order_(make_cell_order(order)),
      send_index_(comm.size()), recv_index_(comm.size()), send_(comm.size()), recv_(comm.size()) {}

void DomainExchange::set_cell_size(double cell) {
  grid_ = CellGrid(domain_, cell, period_y_);
  order_->setup(grid_);
  partners_stale_ = true;
}

void DomainExchange::compute_keys(const ParticleSet& ps) {
  keys_.resize(owned_);
  order_->compute_keys(grid_, std::span<const double>(ps.x.data(), owned_), std::span<const double>(ps.y.data(), owned_),
                       std::span<const double>(ps.z.data(), owned_), ps.type.data(), keys_);
}

void DomainExchange::check_cells() const {
  if (grid_.num_cells() < ranks_)
    throw ConfigError(std::to_string(ranks_) + " ranks for a grid of " + std::to_string(grid_.num_cells()) +
                      " cells of " + std::to_string(grid_.cell_size) +
                      " m: every rank must own at least one cell; run with fewer ranks (mpirun -np) or more particles");
}

void DomainExchange::count_types(const std::uint32_t* keys, const ParticleType* type, std::size_t n) {
  const std::size_t boundary = order_->num_keys();  // fluid counts first, then boundary counts
  for (std::size_t i = 0; i < n; ++i)
    if (keys[i] != kNoCell && type[i] != ParticleType::out)
      type_counts_[keys[i] + (type[i] == ParticleType::fluid ? 0 : boundary)] += 1;
}

std::vector<double> DomainExchange::key_weights(const ParticleSet& ps, bool reduce) {
  const std::size_t keys = order_->num_keys();
  std::vector<double> w(keys, 0.0);
  if (balance_ == BalanceBy::particles) {
    for (std::size_t i = 0; i < owned_; ++i)
      if (keys_[i] != kNoCell) w[keys_[i]] += weight(ps.type[i]);
    if (reduce) sum(w);  // exact: sums of 1 and 1/4
    return w;
  }
  type_counts_.assign(2 * keys, 0.0);
  count_types(keys_.data(), ps.type.data(), owned_);
  if (reduce) sum(type_counts_);  // exact: integer counts; both halves in one reduction
  const std::span<const double> counts(type_counts_);
  interaction_weights(grid_, *order_, counts.first(keys), counts.subspan(keys), 0, static_cast<std::uint32_t>(keys), w);
  return w;
}

double DomainExchange::local_work_estimate(const ParticleSet& ps) {
  const std::size_t keys = order_->num_keys();
  type_counts_.assign(2 * keys, 0.0);
  ghost_keys_.resize(ghosts_);
  order_->compute_keys(grid_, std::span<const double>(ps.x.data() + owned_, ghosts_),
                       std::span<const double>(ps.y.data() + owned_, ghosts_),
                       std::span<const double>(ps.z.data() + owned_, ghosts_), ps.type.data() + owned_, ghost_keys_);
  count_types(keys_.data(), ps.type.data(), owned_);
  count_types(ghost_keys_.data(), ps.type.data() + owned_, ghosts_);
  // The ghosts fill this rank's halo, so its own cells see every neighbour the global counts would give them.
  const std::uint32_t begin = partition_.begin(rank_), end = partition_.end(rank_);
  key_work_.resize(keys);  // interaction_weights writes every key of the range
  const std::span<const double> counts(type_counts_);
  interaction_weights(grid_, *order_, counts.first(keys), counts.subspan(keys), begin, end, key_work_);
  return std::accumulate(key_work_.begin() + begin, key_work_.begin() + end, 0.0);
}

void DomainExchange::repartition(const ParticleSet& ps) {
  check_cells();
  partition_ = KeyPartition::balanced(key_weights(ps, true), ranks_);
  partners_stale_ = true;
  ++partitions_;
}

void DomainExchange::distribute(ParticleSet& ps, double cell) {
  owned_ = ps.size();
  set_cell_size(cell);
  compute_keys(ps);
  check_cells();
  // Every rank holds the same full set here: the weights need no reduction.
  partition_ = KeyPartition::balanced(key_weights(ps, false), ranks_);
  partners_stale_ = true;
  ++partitions_;
  std::size_t kept = 0;
  std::vector<double> record;
  for (std::size_t i = 0; i < owned_; ++i) {
    if ((keys_[i] == kNoCell ? 0 : partition_.owner(keys_[i])) != rank_) continue;  // out ones: rank 0
    record.clear();
    pack_particle(ps, i, record);
    unpack_particle(record.data(), ps, kept++);
  }
  ps.resize(kept);
  owned_ = kept;
  update_derived(phys_, ps, 0, owned_);
}

bool DomainExchange::any_rank(bool local) {
  Stopwatch sw;
  const bool any = comm_.any(local);
  comm_seconds_ += sw.lap();
  remote_rebuilds_ += any && !local;
  return any;
}

void DomainExchange::exchange_particles(ParticleSet& ps, double cell) {
  ps.resize(owned_);  // the ghosts of the last build go
  ghosts_ = 0;
  const bool new_grid = cell != grid_.cell_size;
  if (new_grid) set_cell_size(cell);
  compute_keys(ps);
  bool rebalance = new_grid;
  if (!rebalance) {
    // The work each rank's range holds now: a vector of P, not of keys. By
    // interactions it is each rank's estimate at the last build (its ghosts
    // are gone by now), one build late.
    std::vector<double> w(ranks_, 0.0);
    if (balance_ == BalanceBy::interactions) {
      w[rank_] = work_estimate_;
    } else {
      for (std::size_t i = 0; i < owned_; ++i)
        if (keys_[i] != kNoCell) w[partition_.owner(keys_[i])] += weight(ps.type[i]);
    }
    sum(w);
    rebalance = imbalance(w) > threshold_;
  }
  if (rebalance) repartition(ps);
  migrate(ps);
  compute_keys(ps);
  send_ghosts(ps);
  if (balance_ == BalanceBy::interactions) work_estimate_ = local_work_estimate(ps);
}

void DomainExchange::migrate(ParticleSet& ps) {
  for (auto& s : send_) s.clear();
  std::size_t kept = 0;
  std::vector<double> record;
  for (std::size_t i = 0; i < owned_; ++i) {
    const int to = keys_[i] == kNoCell ? rank_ : partition_.owner(keys_[i]);
    if (to != rank_) {
      pack_particle(ps, i, send_[to]);
      continue;
    }
    if (kept != i) {
      record.clear();
      pack_particle(ps, i, record);
      unpack_particle(record.data(), ps, kept);
    }
    ++kept;
  }
  exchange(send_, recv_);
  std::size_t arriving = 0;
  for (const auto& r : recv_) arriving += r.size() / kMigrateFields;
  ps.resize(kept + arriving);
  std::size_t at = kept;
  for (const auto& r : recv_)
    for (std::size_t k = 0; k < r.size(); k += kMigrateFields) unpack_particle(r.data() + k, ps, at++);
  owned_ = ps.size();
  migrated_ += arriving;
  update_derived(phys_, ps, 0, owned_);  // the kept ones moved down too
}

void DomainExchange::send_ghosts(ParticleSet& ps) {
  const Decomposition dec(grid_, *order_, partition_);
  if (partners_stale_) {
    partners_ = dec.partners(rank_);
    partners_stale_ = false;
  }
  for (int q = 0; q < ranks_; ++q) {
    send_[q].clear();
    send_index_[q].clear();
  }
  std::vector<int> dest;
  std::uint32_t last_key = kNoCell;
  for (std::size_t i = 0; i < owned_; ++i) {
    const std::uint32_t k = keys_[i];
    if (k == kNoCell) continue;
    if (k != last_key) {  // particles come mostly in cell order: one stencil walk per cell
      dec.ghost_destinations(k, dest);
      last_key = k;
    }
    for (const int q : dest) {
      pack_ghost(ps, i, send_[q]);
      send_index_[q].push_back(static_cast<std::uint32_t>(i));
    }
  }
  exchange(send_, recv_, true);
  for (const auto& r : recv_) ghosts_ += r.size() / kGhostFields;
  ps.resize(owned_ + ghosts_);
  std::size_t at = owned_;
  for (int q = 0; q < ranks_; ++q) {
    recv_index_[q].clear();
    const auto& r = recv_[q];
    for (std::size_t k = 0; k < r.size(); k += kGhostFields) {
      unpack_ghost(r.data() + k, ps, at);
      recv_index_[q].push_back(static_cast<std::uint32_t>(at++));
    }
  }
  update_derived(phys_, ps, owned_, ps.size());
}

void DomainExchange::built(const ParticleGrid& grid, bool permuted, ParticleSet&) {
  if (!permuted) return;
  // Old index -> new index; owned particles stay [0, owned_) (ParticleGrid::build).
  const auto& perm = grid.permutation();
  inverse_.resize(perm.size());
  for (std::size_t k = 0; k < perm.size(); ++k) inverse_[perm[k]] = static_cast<std::uint32_t>(k);
  for (auto* lists : {&send_index_, &recv_index_})
    for (auto& list : *lists)
      for (auto& i : list) i = inverse_[i];
}

void DomainExchange::refresh(std::span<std::vector<double>* const> fields) {
  const std::size_t nf = fields.size();
  for (int q = 0; q < ranks_; ++q) {
    send_[q].clear();
    for (const std::uint32_t i : send_index_[q])
      for (const auto* f : fields) send_[q].push_back((*f)[i]);
  }
  exchange(send_, recv_, true);
  for (int q = 0; q < ranks_; ++q) {
    const double* r = recv_[q].data();
    for (const std::uint32_t i : recv_index_[q]) {
      for (std::size_t f = 0; f < nf; ++f) (*fields[f])[i] = r[f];
      r += nf;
    }
  }
}

void DomainExchange::refresh_ghosts(ParticleSet& ps) {
  std::vector<double>* fields[] = {&ps.x, &ps.y, &ps.z, &ps.vx, &ps.vy, &ps.vz, &ps.rho};
  refresh(fields);
  update_derived(phys_, ps, owned_, ps.size());
}

void DomainExchange::refresh_kgc(ParticleSet& ps) {
  std::vector<double>* fields[] = {&ps.kgc[0], &ps.kgc[1], &ps.kgc[2], &ps.kgc[3], &ps.kgc[4], &ps.kgc[5]};
  refresh(fields);
}

void DomainExchange::exchange(const std::vector<std::vector<double>>& send, std::vector<std::vector<double>>& recv,
                              bool neighbours) {
  for (int q = 0; q < ranks_; ++q)
    if (q != rank_) bytes_sent_ += send[q].size() * sizeof(double);
  Stopwatch sw;
  if (neighbours)
    comm_.exchange_with(partners_, send, recv);
  else
    comm_.exchange(send, recv);
  comm_seconds_ += sw.lap();
}

double DomainExchange::max(double v) { max(std::span<double>(&v, 1)); return v; }
double DomainExchange::sum(double v) { sum(std::span<double>(&v, 1)); return v; }
void DomainExchange::max(std::span<double> v) {
  Stopwatch sw;
  comm_.max(v);
  comm_seconds_ += sw.lap();
}
void DomainExchange::sum(std::span<double> v) {
  Stopwatch sw;
  comm_.sum(v);
  comm_seconds_ += sw.lap();
}

}  // namespace sphnl
