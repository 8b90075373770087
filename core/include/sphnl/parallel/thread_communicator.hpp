#pragma once
// ThreadCommunicator: P ranks as P threads of one process, exchanging through
// shared mailboxes between barriers. It lets tests run the distributed solver
// (DomainExchange, Simulation with P ranks) where MPI is not installed, and
// compare it with the serial run in the same process.
#include <memory>

#include "sphnl/parallel/communicator.hpp"

namespace sphnl {

class ThreadCommunicator final : public Communicator {
 public:
  /// The mailboxes and the barrier the `ranks` threads of one group share.
  struct Group;
  /// One communicator per rank of a new group; hand entry r to the thread of rank r.
  static std::vector<std::unique_ptr<ThreadCommunicator>> make_group(int ranks);

  ThreadCommunicator(std::shared_ptr<Group> group, int rank) : group_(std::move(group)), rank_(rank) {}
  int rank() const override { return rank_; }
  int size() const override;
  void max(std::span<double> values) override;
  void sum(std::span<double> values) override;
  void exchange(const std::vector<std::vector<double>>& send, std::vector<std::vector<double>>& recv) override;
  void gather(std::span<const double> mine, std::vector<std::vector<double>>& at_root) override;
  using Communicator::max;
  using Communicator::sum;

 private:
  template <class Combine>
  void reduce(std::span<double> values, Combine combine);
  std::shared_ptr<Group> group_;
  int rank_;
};

}  // namespace sphnl
