#pragma once
// Communicator: the few collective operations the distributed solver needs
// (docs/DESIGN.md, "The parallel layer"). The library computes against this
// interface only; the MPI implementation lives in core/mpi (library sphnl_mpi,
// built when CMake finds MPI) and ThreadCommunicator runs P ranks as threads
// of one process, so the whole parallel path is tested without MPI.
// Every payload is doubles: particle fields, and ids and types stored exactly
// as doubles (integers below 2^53).
#include <cstdint>
#include <stdexcept>
#include <string>
#include <span>
#include <vector>

namespace sphnl {

class Communicator {
 public:
  virtual ~Communicator() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  /// Element-wise maximum / sum over ranks, in place on every rank. Sums are
  /// taken in rank order, so every rank gets the same bits.
  virtual void max(std::span<double> values) = 0;
  virtual void sum(std::span<double> values) = 0;
  /// Personalised all-to-all: send[q] goes to rank q (send has size() entries,
  /// most of them empty); recv[q] is what rank q sent to this rank.
  virtual void exchange(const std::vector<std::vector<double>>& send, std::vector<std::vector<double>>& recv) = 0;
  /// Neighbour exchange: as exchange(), but with the ranks in `partners` only
  /// (sorted, without this rank, and symmetric: q lists this rank whenever
  /// this rank lists q). send[q] must be empty for every other q; recv[q] is
  /// empty for every other q. The default runs exchange() and checks both
  /// (std::logic_error), so ThreadCommunicator tests the partner lists; MPI
  /// sends point to point to the partners alone.
  virtual void exchange_with(std::span<const int> partners, const std::vector<std::vector<double>>& send,
                             std::vector<std::vector<double>>& recv) {
    check_partners(partners, send, "sends to");
    exchange(send, recv);
    check_partners(partners, recv, "received from");
  }
  /// Every rank's `mine` at rank 0, in rank order; `at_root` is left empty elsewhere.
  virtual void gather(std::span<const double> mine, std::vector<std::vector<double>>& at_root) = 0;

  double max(double v) { max(std::span<double>(&v, 1)); return v; }
  double sum(double v) { sum(std::span<double>(&v, 1)); return v; }
  /// True on every rank when `local` is true on any rank.
  bool any(bool local) { return max(local ? 1.0 : 0.0) > 0; }

 protected:
  /// Throws std::logic_error when `per_rank` holds data for a rank outside `partners`.
  void check_partners(std::span<const int> partners, const std::vector<std::vector<double>>& per_rank,
                      const char* what) const {
    std::size_t k = 0;
    for (int q = 0; q < static_cast<int>(per_rank.size()); ++q) {
      while (k < partners.size() && partners[k] < q) ++k;
      const bool partner = k < partners.size() && partners[k] == q;
      if (!partner && q != rank() && !per_rank[q].empty())
        throw std::logic_error("rank " + std::to_string(rank()) + " " + what + " rank " + std::to_string(q) +
                               ", which is not one of its exchange partners");
    }
  }
};

}  // namespace sphnl
