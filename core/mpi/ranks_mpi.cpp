// sphnl_ranks of a build with MPI: MpiCommunicator over MPI_COMM_WORLD.
#include <mpi.h>

#include <numeric>
#include <stdexcept>
#include <string>

#include "sphnl/ranks.hpp"

namespace sphnl {

namespace {

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) throw std::runtime_error(std::string("MPI call failed: ") + what);
}

/// Only the main thread calls MPI (MPI_THREAD_FUNNELED); OpenMP threads compute.
class MpiCommunicator final : public Communicator {
 public:
  MpiCommunicator() {
    check(MPI_Comm_rank(MPI_COMM_WORLD, &rank_), "MPI_Comm_rank");
    check(MPI_Comm_size(MPI_COMM_WORLD, &size_), "MPI_Comm_size");
  }
  ~MpiCommunicator() override { MPI_Finalize(); }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  void max(std::span<double> v) override {
    check(MPI_Allreduce(MPI_IN_PLACE, v.data(), static_cast<int>(v.size()), MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD),
          "MPI_Allreduce(MAX)");
  }
  void sum(std::span<double> v) override {
    // Rank-order sums (the Communicator contract): gathered and summed at
    // every rank alike, since MPI_SUM may associate differently per rank.
    std::vector<double> all(v.size() * static_cast<std::size_t>(size_));
    check(MPI_Allgather(v.data(), static_cast<int>(v.size()), MPI_DOUBLE, all.data(), static_cast<int>(v.size()),
                        MPI_DOUBLE, MPI_COMM_WORLD),
          "MPI_Allgather");
    for (std::size_t k = 0; k < v.size(); ++k) {
      double s = all[k];
      for (int r = 1; r < size_; ++r) s += all[static_cast<std::size_t>(r) * v.size() + k];
      v[k] = s;
    }
  }
  void exchange(const std::vector<std::vector<double>>& send, std::vector<std::vector<double>>& recv) override {
    std::vector<int> scount(size_), rcount(size_), sdispl(size_), rdispl(size_);
    for (int q = 0; q < size_; ++q) scount[q] = static_cast<int>(send[q].size());
    check(MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, MPI_COMM_WORLD), "MPI_Alltoall");
    std::exclusive_scan(scount.begin(), scount.end(), sdispl.begin(), 0);
    std::exclusive_scan(rcount.begin(), rcount.end(), rdispl.begin(), 0);
    sbuf_.resize(static_cast<std::size_t>(sdispl.back() + scount.back()));
    rbuf_.resize(static_cast<std::size_t>(rdispl.back() + rcount.back()));
    for (int q = 0; q < size_; ++q) std::copy(send[q].begin(), send[q].end(), sbuf_.begin() + sdispl[q]);
    check(MPI_Alltoallv(sbuf_.data(), scount.data(), sdispl.data(), MPI_DOUBLE, rbuf_.data(), rcount.data(),
                        rdispl.data(), MPI_DOUBLE, MPI_COMM_WORLD),
          "MPI_Alltoallv");
    recv.resize(size_);
    for (int q = 0; q < size_; ++q) recv[q].assign(rbuf_.begin() + rdispl[q], rbuf_.begin() + rdispl[q] + rcount[q]);
  }
  void exchange_with(std::span<const int> partners, const std::vector<std::vector<double>>& send,
                     std::vector<std::vector<double>>& recv) override {
    check_partners(partners, send, "sends to");
    const std::size_t k = partners.size();
    count_out_.resize(k);
    count_in_.resize(k);
    requests_.resize(2 * k);
    for (std::size_t i = 0; i < k; ++i) count_out_[i] = static_cast<int>(send[partners[i]].size());
    for (std::size_t i = 0; i < k; ++i) {
      check(MPI_Irecv(&count_in_[i], 1, MPI_INT, partners[i], kCountTag, MPI_COMM_WORLD, &requests_[i]), "MPI_Irecv");
      check(MPI_Isend(&count_out_[i], 1, MPI_INT, partners[i], kCountTag, MPI_COMM_WORLD, &requests_[k + i]), "MPI_Isend");
    }
    check(MPI_Waitall(static_cast<int>(2 * k), requests_.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
    recv.resize(size_);
    for (auto& r : recv) r.clear();
    for (std::size_t i = 0; i < k; ++i) {
      auto& in = recv[partners[i]];
      in.resize(static_cast<std::size_t>(count_in_[i]));
      check(MPI_Irecv(in.data(), count_in_[i], MPI_DOUBLE, partners[i], kDataTag, MPI_COMM_WORLD, &requests_[i]),
            "MPI_Irecv");
      check(MPI_Isend(send[partners[i]].data(), count_out_[i], MPI_DOUBLE, partners[i], kDataTag, MPI_COMM_WORLD,
                      &requests_[k + i]),
            "MPI_Isend");
    }
    check(MPI_Waitall(static_cast<int>(2 * k), requests_.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  }
  void gather(std::span<const double> mine, std::vector<std::vector<double>>& at_root) override {
    int n = static_cast<int>(mine.size());
    std::vector<int> counts(size_), displ(size_);
    check(MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Gather");
    std::exclusive_scan(counts.begin(), counts.end(), displ.begin(), 0);
    if (rank_ == 0) rbuf_.resize(static_cast<std::size_t>(displ.back() + counts.back()));
    check(MPI_Gatherv(mine.data(), n, MPI_DOUBLE, rbuf_.data(), counts.data(), displ.data(), MPI_DOUBLE, 0,
                      MPI_COMM_WORLD),
          "MPI_Gatherv");
    at_root.clear();
    if (rank_ != 0) return;
    at_root.resize(size_);
    for (int q = 0; q < size_; ++q) at_root[q].assign(rbuf_.begin() + displ[q], rbuf_.begin() + displ[q] + counts[q]);
  }
  using Communicator::max;
  using Communicator::sum;

 private:
  static constexpr int kCountTag = 17, kDataTag = 18;
  int rank_ = 0, size_ = 1;
  std::vector<double> sbuf_, rbuf_;
  std::vector<int> count_out_, count_in_;
  std::vector<MPI_Request> requests_;
};

}  // namespace

bool mpi_built() { return true; }

std::unique_ptr<Communicator> start_ranks() {
  if (!started_by_launcher()) return nullptr;
  int provided = 0;
  check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  auto comm = std::make_unique<MpiCommunicator>();
  if (comm->size() == 1) return nullptr;  // one rank: exactly the serial run (MPI finalised here)
  return comm;
}

}  // namespace sphnl
