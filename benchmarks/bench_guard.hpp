#pragma once
// A failure inside a benchmark ends sphnl_bench at once, with its cause on
// stderr and exit status 1. Google Benchmark's own route (SkipWithError)
// prints the cause on stdout, which experiments/run.py discards, exits 0 with
// one repetition, and with several repetitions aborts in ComputeStats with a
// check failure that hides the cause.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

namespace sphnl::bench {

[[noreturn]] inline void fail_benchmark(const std::string& name, const std::string& cause) {
  std::fflush(stdout);
  std::fprintf(stderr, "sphnl_bench: benchmark %s failed: %s\n", name.c_str(), cause.c_str());
  std::fflush(stderr);
  // _Exit: the benchmark library is mid-run; its destructors must not run.
  std::_Exit(1);
}

/// Runs `body`; an exception ends the process through fail_benchmark.
template <class F>
void guarded(const std::string& name, F&& body) {
  try {
    body();
  } catch (const std::exception& e) {
    fail_benchmark(name, e.what());
  } catch (...) {
    fail_benchmark(name, "unknown exception");
  }
}

}  // namespace sphnl::bench
