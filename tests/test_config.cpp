// Config parsing: every bad input is an error that names the key (or option)
// and what is allowed; good input round-trips through config_to_json.
#include <gtest/gtest.h>

#include <string>
#include <tuple>

#include <nlohmann/json.hpp>

#include "sphnl/config.hpp"
#include "run.hpp"

using nlohmann::json;
using sphnl::ConfigError;

namespace {

/// The message of the ConfigError `f` throws ("" when it does not throw).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Config, DefaultsMatchDesignTable) {
  const sphnl::RunConfig c = sphnl::config_from_json(json::object());
  EXPECT_EQ(c.particles, 31239);
  EXPECT_DOUBLE_EQ(c.end_time, 0.5);
  EXPECT_DOUBLE_EQ(c.output_interval, 0.05);
  EXPECT_DOUBLE_EQ(c.h_coefficient, 0.866025);
  EXPECT_DOUBLE_EQ(c.cfl, 0.3);
  EXPECT_EQ(c.euler_every, 50);
  EXPECT_DOUBLE_EQ(c.sound_speed_coef, 10);
  EXPECT_FALSE(c.clamp_boundary_density);
  EXPECT_EQ(c.lattice, sphnl::Lattice::bcc);
  EXPECT_EQ(c.threads, 1);
  EXPECT_EQ(c.gridder, sphnl::GridderKind::B);
  EXPECT_EQ(c.cell_order, sphnl::CellOrderKind::sort_x);
  EXPECT_TRUE(c.reorder);
  EXPECT_EQ(c.reorder_every, 1);
  EXPECT_EQ(c.list, sphnl::ListKind::cll);
  EXPECT_EQ(c.list_steps, 1);
  EXPECT_FALSE(c.kgc);
  EXPECT_FALSE(c.verify_lists);
  // ablations: the defaults are the normal path
  EXPECT_EQ(c.pair_loop, sphnl::PairLoopKind::gather);
  EXPECT_TRUE(c.simd);
  EXPECT_FALSE(c.skip_boundary_pairs);
  EXPECT_EQ(c.gridder_a_variant, sphnl::SlidingVariant::occupied);
  EXPECT_EQ(c.initial_order, sphnl::InitialOrder::generated);
  EXPECT_EQ(c.extra_loops, 0);
}

TEST(Config, AblationKeysParseAndBadValuesNameTheAllowedOnes) {
  json j = json::object();
  for (const char* kv : {"pair_loop=direct", "simd=off", "skip_boundary_pairs=true", "gridder_a_variant=shift_all",
                         "initial_order=shuffled", "extra_loops=3"})
    sphnl::apply_override(j, kv);
  const sphnl::RunConfig c = sphnl::config_from_json(j);
  EXPECT_EQ(c.pair_loop, sphnl::PairLoopKind::direct);
  EXPECT_FALSE(c.simd);
  EXPECT_TRUE(c.skip_boundary_pairs);
  EXPECT_EQ(c.gridder_a_variant, sphnl::SlidingVariant::shift_all);
  EXPECT_EQ(c.initial_order, sphnl::InitialOrder::shuffled);
  EXPECT_EQ(c.extra_loops, 3);
  EXPECT_EQ(sphnl::config_from_json(sphnl::config_to_json(c)).extra_loops, 3);
  for (const auto& [key, value, allowed] :
       {std::tuple<std::string, json, std::string>{"pair_loop", "fast", "gather, direct, masked"},
        {"simd", true, "on, off"},
        {"simd", "avx", "on, off"},
        {"skip_boundary_pairs", "boundary", "true or false"},
        {"gridder_a_variant", "paper", "occupied, shift_all"},
        {"initial_order", "random", "generated, shuffled"},
        {"extra_loops", 4, "[0, 3]"},
        {"extra_loops", -1, "[0, 3]"}}) {
    const std::string msg = error_of([&] { sphnl::config_from_json(json{{key, value}}); });
    EXPECT_NE(msg.find("'" + key + "'"), std::string::npos) << key << ": " << msg;
    EXPECT_NE(msg.find(allowed), std::string::npos) << key << ": " << msg;
  }
}

TEST(Config, UnknownKeyIsNamedWithTheKnownKeys) {
  const std::string msg = error_of([] { sphnl::config_from_json(json{{"gridr", "B"}}); });
  EXPECT_NE(msg.find("'gridr'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("gridder"), std::string::npos) << msg;  // lists what is allowed
}

TEST(Config, BadEnumValueNamesKeyAndAllowedValues) {
  const std::string msg = error_of([] { sphnl::config_from_json(json{{"gridder", "E"}}); });
  EXPECT_NE(msg.find("'gridder'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("A, B, C, D"), std::string::npos) << msg;
  const std::string order = error_of([] { sphnl::config_from_json(json{{"cell_order", "zorder"}}); });
  EXPECT_NE(order.find("hilbert"), std::string::npos) << order;
}

TEST(Config, WrongTypeNamesKey) {
  const std::string msg = error_of([] { sphnl::config_from_json(json{{"threads", "many"}}); });
  EXPECT_NE(msg.find("'threads'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("integer"), std::string::npos) << msg;
  const std::string b = error_of([] { sphnl::config_from_json(json{{"reorder", "yes"}}); });
  EXPECT_NE(b.find("'reorder'"), std::string::npos) << b;
  EXPECT_NE(b.find("true or false"), std::string::npos) << b;
}

TEST(Config, ImpossibleValuesNameKeyAndRange) {
  for (const auto& [key, value] : {std::pair<std::string, json>{"cfl", 0.0}, {"cfl", -0.3}, {"threads", 0},
                                   {"dx", -0.01}, {"steps", 0}, {"end_time", -1.0}, {"output_interval", -0.1},
                                   {"particles", 3}, {"euler_every", 0}}) {
    const std::string msg = error_of([&] { sphnl::config_from_json(json{{key, value}}); });
    EXPECT_NE(msg.find("'" + key + "'"), std::string::npos) << key << ": " << msg;
    EXPECT_NE(msg.find("allowed"), std::string::npos) << key << ": " << msg;
  }
}

TEST(Config, AlternativeKeysAreExclusive) {
  EXPECT_NE(error_of([] { sphnl::config_from_json(json{{"particles", 1000}, {"dx", 0.02}}); }).find("dx"),
            std::string::npos);
  EXPECT_NE(error_of([] { sphnl::config_from_json(json{{"steps", 10}, {"end_time", 0.1}}); }).find("end_time"),
            std::string::npos);
}

TEST(Config, OverridesParseValuesAndReplaceAlternatives) {
  json j = json{{"particles", 5000}, {"end_time", 0.2}};
  sphnl::apply_override(j, "gridder=C");
  sphnl::apply_override(j, "reorder=false");
  sphnl::apply_override(j, "dx=0.02");
  sphnl::apply_override(j, "steps=7");
  const sphnl::RunConfig c = sphnl::config_from_json(j);
  EXPECT_EQ(c.gridder, sphnl::GridderKind::C);
  EXPECT_FALSE(c.reorder);
  EXPECT_DOUBLE_EQ(c.dx, 0.02);
  EXPECT_EQ(c.steps, 7);
  EXPECT_NE(error_of([&] { sphnl::apply_override(j, "novalue"); }).find("key=value"), std::string::npos);
}

TEST(Config, RoundTripsThroughJson) {
  json j = {{"gridder", "D"}, {"cell_order", "sort_xyz"}, {"threads", 2}, {"kgc", true}, {"dx", 0.03}};
  const sphnl::RunConfig c = sphnl::config_from_json(j);
  json echoed = sphnl::config_to_json(c);
  // The echo holds both members of each alternative pair (particles/dx,
  // steps/end_time); the unused one (particles here, steps = 0) is dropped.
  echoed.erase("particles");
  echoed.erase("steps");
  const sphnl::RunConfig again = sphnl::config_from_json(echoed);
  EXPECT_EQ(sphnl::config_to_json(again), sphnl::config_to_json(c));
}

TEST(RunOptions, UnknownOptionAndMissingValueAreNamed) {
  const char* a1[] = {"run", "--out", "x", "--bogus"};
  const std::string m1 = error_of([&] { sphnl::parse_run_options(4, const_cast<char**>(a1)); });
  EXPECT_NE(m1.find("--bogus"), std::string::npos) << m1;
  const char* a2[] = {"run", "--config"};
  const std::string m2 = error_of([&] { sphnl::parse_run_options(2, const_cast<char**>(a2)); });
  EXPECT_NE(m2.find("--config"), std::string::npos) << m2;
}

TEST(RunOptions, SetAccumulatesAndBadOverrideNamesKey) {
  const char* a[] = {"run", "--set", "gridder=A", "--set=threads=x", "--out=dir", "--quiet"};
  const sphnl::RunOptions o = sphnl::parse_run_options(6, const_cast<char**>(a));
  ASSERT_EQ(o.overrides.size(), 2u);
  EXPECT_EQ(o.out_dir, "dir");
  EXPECT_TRUE(o.quiet);
  const std::string msg = error_of([&] { sphnl::load_run_config(o); });
  EXPECT_NE(msg.find("'threads'"), std::string::npos) << msg;
}

TEST(RunOptions, MissingConfigFileIsNamed) {
  sphnl::RunOptions o;
  o.config_file = "/nonexistent/cfg.json";
  const std::string msg = error_of([&] { sphnl::load_run_config(o); });
  EXPECT_NE(msg.find("/nonexistent/cfg.json"), std::string::npos) << msg;
}
