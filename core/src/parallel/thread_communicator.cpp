#include "sphnl/parallel/thread_communicator.hpp"

#include <algorithm>
#include <barrier>

namespace sphnl {

struct ThreadCommunicator::Group {
  explicit Group(int n) : ranks(n), barrier(n), slots(n), mail(n, std::vector<std::vector<double>>(n)) {}
  int ranks;
  std::barrier<> barrier;
  std::vector<std::vector<double>> slots;              // reductions, gather: one per rank
  std::vector<std::vector<std::vector<double>>> mail;  // mail[from][to]
};

std::vector<std::unique_ptr<ThreadCommunicator>> ThreadCommunicator::make_group(int ranks) {
  auto group = std::make_shared<Group>(ranks);
  std::vector<std::unique_ptr<ThreadCommunicator>> comms;
  for (int r = 0; r < ranks; ++r) comms.push_back(std::make_unique<ThreadCommunicator>(group, r));
  return comms;
}

int ThreadCommunicator::size() const { return group_->ranks; }

template <class Combine>
void ThreadCommunicator::reduce(std::span<double> values, Combine combine) {
  Group& g = *group_;
  g.slots[rank_].assign(values.begin(), values.end());
  g.barrier.arrive_and_wait();
  // Every rank combines the slots in rank order: the same bits everywhere.
  for (std::size_t k = 0; k < values.size(); ++k) {
    double v = g.slots[0][k];
    for (int r = 1; r < g.ranks; ++r) v = combine(v, g.slots[r][k]);
    values[k] = v;
  }
  g.barrier.arrive_and_wait();  // slots are free again
}

void ThreadCommunicator::max(std::span<double> values) {
  reduce(values, [](double a, double b) { return std::max(a, b); });
}

void ThreadCommunicator::sum(std::span<double> values) {
  reduce(values, [](double a, double b) { return a + b; });
}

void ThreadCommunicator::exchange(const std::vector<std::vector<double>>& send,
                                  std::vector<std::vector<double>>& recv) {
  Group& g = *group_;
  for (int q = 0; q < g.ranks; ++q) g.mail[rank_][q] = send[q];
  g.barrier.arrive_and_wait();
  recv.resize(g.ranks);
  for (int q = 0; q < g.ranks; ++q) recv[q] = g.mail[q][rank_];
  g.barrier.arrive_and_wait();
}

void ThreadCommunicator::gather(std::span<const double> mine, std::vector<std::vector<double>>& at_root) {
  Group& g = *group_;
  g.slots[rank_].assign(mine.begin(), mine.end());
  g.barrier.arrive_and_wait();
  at_root.clear();
  if (rank_ == 0) at_root = g.slots;
  g.barrier.arrive_and_wait();
}

}  // namespace sphnl
