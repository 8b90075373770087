// sphnl_bench: registers the sweep of one experiment (experiments/<id>.json,
// schema in docs/CONTRACTS.md) as Google Benchmark benchmarks and runs them.
//   sphnl_bench --experiment=experiments/fig06.json [--size=tiny|default|full]
//               [--cache-dir=results/cache] [Google Benchmark flags]
//   sphnl_bench --experiment=F --validate   only check F against the schema (exit 0 or 2)
#include <omp.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>

#include "bench_common.hpp"
#include "sphnl/experiment_schema.hpp"
#include "sphnl/memory_estimate.hpp"
#include "sphnl/output.hpp"
#include "sphnl_revision.hpp"

using nlohmann::json;
namespace sb = sphnl::bench;

namespace {

const char* kUsage =
    "usage: sphnl_bench --experiment=experiments/<id>.json [--size=tiny|default|full] [--cache-dir=DIR] [--validate] [--revision]\n"
    "                   [--force-memory]\n"
    "                   [--benchmark_filter=REGEX --benchmark_out=FILE --benchmark_out_format=json\n"
    "                    --benchmark_repetitions=N --benchmark_min_time=SECONDS ...]\n"
    "Registers the experiment's sweep for that size; every benchmark iteration times `window_steps`\n"
    "steps from the cached developed flow (see docs/CONTRACTS.md).\n"
    "--validate only checks the experiment file (unknown or duplicate keys, sweep axes, values) and exits.\n"
    "--revision prints the git revision this binary was built from (\"-dirty\": with uncommitted code) and exits.\n"
    "A sweep whose memory estimate exceeds the available memory is refused unless --force-memory.\n";

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

/// The largest memory estimate over the sweep's points (each benchmark runs
/// on its own, but the developed flows stay cached in memory: summed per N).
sphnl::MemoryEstimate sweep_memory(const std::string& family, const json& sweep) {
  sphnl::MemoryEstimate worst;
  for (const sb::Point& p : sb::cross_product(sweep, {})) {
    sphnl::MemoryEstimate e;
    const sphnl::RunConfig run = sb::run_config_of(p);
    const long n = run.particles;
    if (family == "search") {
      // full lists of a cubic lattice with R = 2.6 spacings: 4/3 pi 2.6^3 = 74 entries a point;
      // nanoflann's rows are collected per thread, then joined: twice the entries
      const bool peer = p.count("impl") && p.at("impl") == "nanoflann";
      e = sphnl::estimate_search_memory(static_cast<std::uint64_t>(n), static_cast<std::uint64_t>(n) * 74 * (peer ? 2 : 1));
    } else {
      e = sphnl::estimate_run_memory(run);
      e.bytes += static_cast<double>(n) * 200;  // the cached developed flow beside the timed copy
      e.detail += " + the cached flow";
    }
    if (e.bytes > worst.bytes) worst = e;
  }
  return worst;
}

int fail(const std::string& msg) {
  std::fprintf(stderr, "sphnl_bench: %s\n%s", msg.c_str(), kUsage);
  return 2;
}

/// The benchmark dies with its parent (experiments/run.py, make): killed
/// alone (kill -9, the OOM killer) the driver would otherwise leave it
/// running, possibly for an hour of snapshot building, beside the rerun.
/// Linux sends the signal when the parent *thread* that started us exits,
/// so a driver must start sphnl_bench from a thread that outlives it.
void die_with_parent(pid_t parent) {
  if (::prctl(PR_SET_PDEATHSIG, SIGKILL) != 0) std::perror("sphnl_bench: prctl(PR_SET_PDEATHSIG)");
  // The parent may have died before prctl: then we were already re-parented.
  if (::getppid() != parent) {
    std::fprintf(stderr, "sphnl_bench: the parent process has exited; stopping\n");
    std::_Exit(1);
  }
}

}  // namespace

int main(int argc, char** argv) {
  die_with_parent(::getppid());
  sb::Options opt;
  bool validate_only = false, force_memory = false;
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
    else if (a == "--validate") validate_only = true;
    else if (a == "--force-memory") force_memory = true;
    else if (a == "--help" || a == "-h") { std::fputs(kUsage, stdout); return 0; }
    else if (a == "--revision") { std::printf("%s\n", SPHNL_GIT_REVISION); return 0; }
    else rest.push_back(argv[i]);
  }
  if (opt.experiment_path.empty()) return fail("--experiment=experiments/<id>.json is required");
  if (opt.size != "tiny" && opt.size != "default" && opt.size != "full")
    return fail("--size must be tiny, default or full, not '" + opt.size + "'");

  json experiment;
  try {
    experiment = sphnl::load_experiment(opt.experiment_path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sphnl_bench: invalid experiment file:\n%s\n", e.what());
    return 2;
  }
  if (validate_only) {
    std::printf("%s: valid\n", opt.experiment_path.c_str());
    return 0;
  }
  try {
    if (experiment.contains("uses") && !experiment["uses"].is_null())
      return fail("experiment '" + opt.experiment_path + "' only draws from '" + experiment["uses"].get<std::string>() +
                  "'; run that one");
    const std::string family = experiment.at("benchmark").get<std::string>();
    const json& sweep = experiment.at("sweep").at(opt.size);
    // Before anything is built: a snapshot that cannot be cached would be
    // developed (minutes to an hour) and then lost.
    if (family != "search") {
      try {
        sphnl::ensure_writable_directory(opt.cache_dir);
      } catch (const std::exception&) {
        return fail("snapshot cache '" + opt.cache_dir + "' is not a writable directory (" + std::strerror(errno) +
                    "); give --cache-dir=DIR a directory you can write to");
      }
    }
    if (!force_memory) {
      try {
        sphnl::check_memory(sweep_memory(family, sweep), "the largest benchmark of this sweep", "--force-memory");
      } catch (const sphnl::MemoryError& e) {
        std::fprintf(stderr, "sphnl_bench: %s\n", e.what());
        return 2;
      }
    }
    if (family == "step" || family == "counters") {
      const int window = experiment.at("window_steps").at(opt.size).get<int>();
      if (window < 1) return fail("window_steps must be >= 1");
      sb::register_step_benchmarks(sweep, window, opt, family);
    } else if (family == "cellindex") {
      sb::register_cellindex_benchmarks(sweep, opt);
    } else if (family == "search") {
      sb::register_search_benchmarks(sweep);
    } else {
      return fail("unknown benchmark family '" + family + "' in " + opt.experiment_path + " (known: step, counters, cellindex, search)");
    }
  } catch (const std::exception& e) {
    return fail("experiment '" + opt.experiment_path + "': " + e.what());
  }

  benchmark::AddCustomContext("sphnl_build_type", SPHNL_BUILD_TYPE);
  benchmark::AddCustomContext("sphnl_compiler", SPHNL_COMPILER);
  benchmark::AddCustomContext("sphnl_git_revision", SPHNL_GIT_REVISION);
  benchmark::AddCustomContext("sphnl_march", SPHNL_MARCH_STR);
  benchmark::AddCustomContext("sphnl_hardware_gathers", SPHNL_GATHER_STR);
  benchmark::AddCustomContext("sphnl_cpu", cpu_model());
  benchmark::AddCustomContext("sphnl_size", opt.size);
  benchmark::AddCustomContext("sphnl_experiment", experiment.value("id", opt.experiment_path));
  benchmark::AddCustomContext("sphnl_cores", std::to_string(std::thread::hardware_concurrency()));
  benchmark::AddCustomContext("sphnl_gridders", "A=sliding vector, B=preconditioned vector, C=static matrix, D=linked list");
  benchmark::AddCustomContext("sphnl_lists", "cll=cell-linked list, vlc=classical Verlet list, vlx=Verlet list rebuilt on displacement");

  // Debian's libbenchmark is built without NDEBUG, and Google Benchmark says
  // so before every run; sphnl's own code is what is timed.
  std::fprintf(stderr, "sphnl_bench: a \"Library was built as DEBUG\" warning below is about Google Benchmark's own "
               "library (Debian's build), not about sphnl's timed code, which is a %s build\n", SPHNL_BUILD_TYPE);
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
