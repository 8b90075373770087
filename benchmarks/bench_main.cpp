// sphnl_bench: registers the sweep of one experiment (experiments/<id>.json,
// schema in docs/CONTRACTS.md) as Google Benchmark benchmarks and runs them.
//   sphnl_bench --experiment=experiments/fig06.json [--size=tiny|default|full]
//               [--cache-dir=results/cache] [Google Benchmark flags]
#include <omp.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>

#include "bench_common.hpp"
#include "sphnl_revision.hpp"

using nlohmann::json;
namespace sb = sphnl::bench;

namespace {

const char* kUsage =
    "usage: sphnl_bench --experiment=experiments/<id>.json [--size=tiny|default|full] [--cache-dir=DIR]\n"
    "                   [--benchmark_filter=REGEX --benchmark_out=FILE --benchmark_out_format=json\n"
    "                    --benchmark_repetitions=N --benchmark_min_time=SECONDS ...]\n"
    "Registers the experiment's sweep for that size; every benchmark iteration times `window_steps`\n"
    "steps from the cached developed flow (see docs/CONTRACTS.md).\n";

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

int fail(const std::string& msg) {
  std::fprintf(stderr, "sphnl_bench: %s\n%s", msg.c_str(), kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  sb::Options opt;
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* flag) -> const char* {
      const std::size_t len = std::strlen(flag);
      return a.compare(0, len, flag) == 0 ? argv[i] + len : nullptr;
    };
    if (const char* v = value("--experiment=")) opt.experiment_path = v;
    else if (const char* v2 = value("--size=")) opt.size = v2;
    else if (const char* v3 = value("--cache-dir=")) opt.cache_dir = v3;
    else if (a == "--help" || a == "-h") { std::fputs(kUsage, stdout); return 0; }
    else rest.push_back(argv[i]);
  }
  if (opt.experiment_path.empty()) return fail("--experiment=experiments/<id>.json is required");
  if (opt.size != "tiny" && opt.size != "default" && opt.size != "full")
    return fail("--size must be tiny, default or full, not '" + opt.size + "'");

  json experiment;
  try {
    std::ifstream in(opt.experiment_path);
    if (!in) return fail("cannot read experiment file '" + opt.experiment_path + "'");
    experiment = json::parse(in);
    if (experiment.contains("uses") && !experiment["uses"].is_null())
      return fail("experiment '" + opt.experiment_path + "' only draws from '" + experiment["uses"].get<std::string>() +
                  "'; run that one");
    const std::string family = experiment.at("benchmark").get<std::string>();
    const json& sweep = experiment.at("sweep").at(opt.size);
    if (family == "step") {
      const int window = experiment.at("window_steps").at(opt.size).get<int>();
      if (window < 1) return fail("window_steps must be >= 1");
      sb::register_step_benchmarks(sweep, window, opt);
    } else if (family == "cellindex") {
      sb::register_cellindex_benchmarks(sweep, opt);
    } else if (family == "search") {
      sb::register_search_benchmarks(sweep);
    } else {
      return fail("unknown benchmark family '" + family + "' in " + opt.experiment_path + " (known: step, cellindex, search)");
    }
  } catch (const std::exception& e) {
    return fail("experiment '" + opt.experiment_path + "': " + e.what());
  }

  benchmark::AddCustomContext("sphnl_build_type", SPHNL_BUILD_TYPE);
  benchmark::AddCustomContext("sphnl_compiler", SPHNL_COMPILER);
  benchmark::AddCustomContext("sphnl_git_revision", SPHNL_GIT_REVISION);
  benchmark::AddCustomContext("sphnl_march", SPHNL_MARCH_STR);
  benchmark::AddCustomContext("sphnl_cpu", cpu_model());
  benchmark::AddCustomContext("sphnl_size", opt.size);
  benchmark::AddCustomContext("sphnl_experiment", experiment.value("id", opt.experiment_path));
  benchmark::AddCustomContext("sphnl_cores", std::to_string(std::thread::hardware_concurrency()));
  benchmark::AddCustomContext("sphnl_gridders", "A=sliding vector, B=preconditioned vector, C=static matrix, D=linked list");
  benchmark::AddCustomContext("sphnl_lists", "cll=cell-linked list, vlc=classical Verlet list, vlx=Verlet list rebuilt on displacement");

  int bargc = static_cast<int>(rest.size());
  benchmark::Initialize(&bargc, rest.data());
  if (benchmark::ReportUnrecognizedArguments(bargc, rest.data())) return 2;
  try {
    benchmark::RunSpecifiedBenchmarks();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sphnl_bench: %s\n", e.what());
    return 1;
  }
  benchmark::Shutdown();
  return 0;
}
