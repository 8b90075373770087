// Snapshots: a saved state restores bit-for-bit (in id order, whatever the
// memory order), a damaged file is refused with a message naming it, and a
// stored config matches the wanted one across keys added since.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "sphnl/snapshot.hpp"

namespace {

sphnl::RunConfig small_config() {
  sphnl::RunConfig c;
  c.particles = 1500;
  c.progress = false;
  return c;
}

std::string temp_path(const char* name) {
  return (std::filesystem::temp_directory_path() / (std::string("sphnl_test_") + name)).string();
}

TEST(Snapshot, RoundTripRestoresStateAndClock) {
  sphnl::Simulation a(small_config());
  for (int s = 0; s < 20; ++s) a.step();
  const std::string path = temp_path("roundtrip.snap");
  sphnl::save_snapshot(path, a);

  sphnl::Simulation b(small_config());
  const sphnl::SnapshotInfo info = sphnl::load_snapshot(path, b);
  EXPECT_EQ(info.n, a.particles().size());
  EXPECT_EQ(b.time(), a.time());
  EXPECT_EQ(b.steps_done(), a.steps_done());
  // Compare by id: a reorders particles in memory, the snapshot is in id order.
  const auto& pa = a.particles();
  const auto& pb = b.particles();
  std::vector<std::size_t> where(pa.size());
  for (std::size_t i = 0; i < pa.size(); ++i) where[pa.id[i]] = i;
  for (std::size_t k = 0; k < pb.size(); ++k) {
    const std::size_t i = where[pb.id[k]];
    ASSERT_EQ(pb.x[k], pa.x[i]);
    ASSERT_EQ(pb.vz[k], pa.vz[i]);
    ASSERT_EQ(pb.rho_prev[k], pa.rho_prev[i]);
    ASSERT_EQ(pb.type[k], pa.type[i]);
  }
  // Both continue identically from the same state.
  a.step();
  b.step();
  EXPECT_EQ(a.last_dt(), b.last_dt());
  std::filesystem::remove(path);
}

TEST(Snapshot, CorruptFileIsRefusedWithItsPath) {
  sphnl::Simulation a(small_config());
  const std::string path = temp_path("corrupt.snap");
  sphnl::save_snapshot(path, a);
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(200);
    f.put('\x7f');
  }
  try {
    sphnl::read_snapshot_info(path);
    FAIL() << "corrupt snapshot accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  }
  std::filesystem::resize_file(path, 100);
  EXPECT_THROW(sphnl::read_snapshot_info(path), std::runtime_error);
  std::filesystem::remove(path);
  EXPECT_THROW(sphnl::read_snapshot_info(path), std::runtime_error);
}

TEST(Snapshot, WrongSizeIsRefused) {
  sphnl::Simulation a(small_config());
  const std::string path = temp_path("size.snap");
  sphnl::save_snapshot(path, a);
  sphnl::RunConfig other = small_config();
  other.particles = 3000;
  sphnl::Simulation b(other);
  EXPECT_THROW(sphnl::load_snapshot(path, b), std::runtime_error);
  std::filesystem::remove(path);
}

// A stored state stays valid when a config key is added at its default (the
// old behaviour), and is stale when any stored or new key differs.
TEST(Snapshot, ConfigMatchToleratesKeysAddedAtTheirDefault) {
  const sphnl::RunConfig wanted = small_config();
  nlohmann::json stored = sphnl::config_to_json(wanted);
  EXPECT_TRUE(sphnl::snapshot_config_matches(stored.dump(), wanted));
  stored.erase("thread_split");  // a snapshot written before the key existed
  EXPECT_TRUE(sphnl::snapshot_config_matches(stored.dump(), wanted));
  sphnl::RunConfig split = wanted;
  split.thread_split = sphnl::ThreadSplit::dynamic;  // the new key away from its default
  EXPECT_FALSE(sphnl::snapshot_config_matches(stored.dump(), split));
  sphnl::RunConfig denser = wanted;
  denser.particles = 3000;  // a stored key that differs
  EXPECT_FALSE(sphnl::snapshot_config_matches(stored.dump(), denser));
  nlohmann::json removed = sphnl::config_to_json(wanted);
  removed["retired_key"] = 1;  // a key the code no longer knows
  EXPECT_FALSE(sphnl::snapshot_config_matches(removed.dump(), wanted));
  EXPECT_THROW(sphnl::snapshot_config_matches("[1, 2]", wanted), std::runtime_error);
}

}  // namespace
