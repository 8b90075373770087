#pragma once
// What tests compare between two ways of running the same case: the particle
// state by id after some steps, and the pairs a simulation's pair source
// hands its operations (one recorder per thread).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "sphnl/simulation.hpp"
#include "support/oracle.hpp"
#include "support/pair_recorder.hpp"

namespace sphnl::test {

/// Positions, velocities and densities indexed by particle id (memory order
/// differs between runs that reorder differently).
struct StateById {
  std::vector<double> x, z, vx, vz, rho;
};

inline StateById state_by_id(const ParticleSet& ps) {
  StateById s;
  for (auto* v : {&s.x, &s.z, &s.vx, &s.vz, &s.rho}) v->resize(ps.size());
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const std::uint32_t id = ps.id[i];
    s.x[id] = ps.x[i]; s.z[id] = ps.z[i];
    s.vx[id] = ps.vx[i]; s.vz[id] = ps.vz[i];
    s.rho[id] = ps.rho[i];
  }
  return s;
}

/// The state after `steps` steps of the dam break `c` from t = 0.
inline StateById state_after(const RunConfig& c, int steps) {
  Simulation sim(c);
  for (int s = 0; s < steps; ++s) sim.step();
  return state_by_id(sim.particles());
}

inline double max_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::fabs(a[i] - b[i]));
  return d;
}

/// The same state bit for bit: the same pairs in the same order with the same arithmetic.
inline void expect_same_bits(const StateById& s, const StateById& ref, const std::string& what) {
  EXPECT_EQ(s.x, ref.x) << what;
  EXPECT_EQ(s.vz, ref.vz) << what;
  EXPECT_EQ(s.rho, ref.rho) << what;
}

/// The same state to round-off, for runs where only the order of the sums
/// differs (in-place vs gathered accumulation, the lanes of a vector
/// reduction vs one scalar sum, another memory order, sums split between
/// threads otherwise), which 50-100 steps of flow amplify. Measured on the
/// small dam break (AVX2 build, 2000 particles, 100 steps of the ablations):
/// |dx| <= 2.8e-16 m, |dvz| <= 1.0e-14 m/s, |drho| <= 5.7e-13 kg/m^3, the
/// last bits of values of 0.5 m, 1 m/s and 1000 kg/m^3. The bounds leave a
/// factor of about 100-300 for other targets; a wrong pair or a missing term
/// moves these fields by more than 1e-6 within a few steps.
inline void expect_roundoff_apart(const StateById& s, const StateById& ref, const std::string& what) {
  EXPECT_LT(max_diff(s.x, ref.x), 1e-13) << what;
  EXPECT_LT(max_diff(s.vz, ref.vz), 1e-12) << what;
  EXPECT_LT(max_diff(s.rho, ref.rho), 1e-10) << what;
}

/// As expect_roundoff_apart for two runs of the float pair kernel
/// (precision=mixed) that sum in different orders: float round-off (2^-24
/// relative, against 2^-53), grown over the run; measured after 100 steps
/// of the small dam break: x 7e-9 m, vz 1e-7 m/s, rho 7e-6 kg/m^3.
inline void expect_float_roundoff_apart(const StateById& s, const StateById& ref, const std::string& what) {
  EXPECT_LT(max_diff(s.x, ref.x), 1e-6) << what;
  EXPECT_LT(max_diff(s.vz, ref.vz), 1e-5) << what;
  EXPECT_LT(max_diff(s.rho, ref.rho), 1e-3) << what;
}

/// The pairs (r < 2h) the simulation's pair source hands its operations, by
/// id: one recorder per thread (recorders of several threads would race on
/// one vector), after preparing the neighbour structures.
inline PairSet pairs_of(Simulation& sim) {
  std::vector<std::vector<std::array<double, 6>>> per_thread(static_cast<std::size_t>(sim.config().threads));
  std::vector<PairRecorder> ops;
  for (auto& r : per_thread) ops.push_back(PairRecorder{&r});
  sim.build_neighbours();
  sim.for_each_pair(ops);
  std::vector<std::array<double, 6>> recorded;
  for (const auto& r : per_thread) recorded.insert(recorded.end(), r.begin(), r.end());
  return recorded_ids(sim.particles(), recorded);
}

}  // namespace sphnl::test
