// The distributed scenarios of test_distributed.cpp as MPI processes: run by
// ctest as `mpirun -np P test_mpi_ranks` (case mpi.scenarios). Every rank runs
// every test; rank 0 also runs the serial reference and checks.
#include <gtest/gtest.h>

#include <memory>

#include "sphnl/ranks.hpp"
#include "support/distributed_runs.hpp"

namespace sphnl::test {
namespace {

Communicator* g_comm = nullptr;

TEST(MpiRanks, ParticlesCrossRanksAndLeaveTheDomain) {
  for (const ListKind list : {ListKind::cll, ListKind::vlx}) {
    SCOPED_TRACE(to_string(list));
    Scenario sc = scenario_with(list);
    sc.push_out = true;
    sc.steps = 30;
    const Outcome dist = run_scenario(sc, g_comm);
    if (g_comm->rank() != 0) continue;
    const Outcome serial = run_scenario(sc, nullptr);
    ASSERT_GT(serial.lost, 0u);
    expect_same_run(serial, dist);
    EXPECT_GT(dist.migrated, 0);
  }
}

TEST(MpiRanks, VerletListXRebuildTriggeredByOneRank) {
  const Scenario sc = scenario_with(ListKind::vlx);
  const Outcome dist = run_scenario(sc, g_comm);
  if (g_comm->rank() != 0) return;
  const Outcome serial = run_scenario(sc, nullptr);
  expect_same_run(serial, dist);
  EXPECT_GT(dist.remote_rebuilds, 0);
  EXPECT_EQ(dist.builds, serial.builds);
}

}  // namespace
}  // namespace sphnl::test

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  std::unique_ptr<sphnl::Communicator> comm = sphnl::start_ranks();
  if (!comm) {
    std::fprintf(stderr, "test_mpi_ranks: needs mpirun with at least 2 ranks (mpirun -np 3 %s)\n", argv[0]);
    return 77;
  }
  sphnl::test::g_comm = comm.get();
  // Only rank 0 checks; the others would print empty successes.
  if (comm->rank() != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  const int rc = RUN_ALL_TESTS();
  // Rank 0's verdict for everyone (the others checked nothing).
  return comm->max(static_cast<double>(rc)) > 0 ? 1 : 0;
}
