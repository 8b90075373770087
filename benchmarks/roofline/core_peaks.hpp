#pragma once
// The limits of one core of this machine, measured (docs/PERFORMANCE.md): the
// floating-point peak (independent FMA chains at the vector width of the
// build's -march) and the memory bandwidth (a STREAM-like triad over arrays
// far larger than the last-level cache). Used by the roofline micro-benchmark
// (sphnl_roofline) and, for the FMA peak, by the step family's counters.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace sphnl::bench {

/// Bits of the vectors the FMA kernels use: 512 with AVX-512, 256 with AVX,
/// else 128 (SSE2); the build's -march decides, as it does for the solver.
int fma_vector_bits();
/// Whether the kernels issue fused multiply-adds (-march with FMA); without,
/// a multiply and an add per chain link (still 2 flops).
bool fma_fused();

/// Runs `rounds` rounds of the double-precision kernel: every round one FMA on
/// each of the independent chains (enough to cover the FMA latency on every
/// FMA pipe). Returns the flops done (an FMA counts 2 per lane).
double fma_flops_double(std::int64_t rounds);
/// The same in single precision (twice the lanes).
double fma_flops_float(std::int64_t rounds);

/// a[i] = b[i] + s c[i] over three arrays of `elements` doubles (STREAM's
/// triad). The arrays are allocated and touched once at construction.
class Triad {
 public:
  explicit Triad(std::size_t elements);
  /// One pass; returns the bytes STREAM counts for it (24 per element: two
  /// reads and one write; the write-allocate read of a[] is not counted).
  double run() { return run(0, a_.size()); }
  /// One pass over elements [begin, end) only (a thread's share).
  double run(std::size_t begin, std::size_t end);
  std::size_t elements() const { return a_.size(); }

 private:
  std::vector<double> a_, b_, c_;
  double s_ = 0.5;
};

/// Bytes of the last-level cache of cpu0 (sysfs), or 32 MiB when unreadable.
std::size_t last_level_cache_bytes();
/// Elements per triad array: 4x the last-level cache each, so that no pass
/// finds its data in any cache.
std::size_t triad_elements();

/// CPU seconds of the calling thread (CLOCK_THREAD_CPUTIME_ID): time the
/// thread ran, without the time a shared machine gave its core to others.
double thread_cpu_seconds();

/// The best of `trials` runs of about `seconds` of thread CPU time each of the
/// double FMA kernel on the calling thread, in GFlop/s per CPU second: what
/// the core does while it runs this thread (the least disturbed trial is the
/// closest to it: caches and the clock shared with other work only slow it).
double measure_fma_peak_double_gflops(int trials = 3, double seconds = 0.02);
/// The same with the float kernel (the peak of precision=mixed's pair kernel).
double measure_fma_peak_float_gflops(int trials = 3, double seconds = 0.02);

/// How fast this machine runs at this moment, in a few milliseconds of wall
/// time: the double FMA kernel (the core's clock and its share of the
/// physical core) and a triad pass over 3 x 32 MiB (the memory path other
/// tenants of a shared host contend for). With `threads` > 1 every thread of
/// a team that size runs both at once, the FMA rounds each and the triad on
/// its share of the arrays, as the timed code's threads would; the slowest
/// thread's speeds are returned (a team is as fast as its slowest member).
/// Timed by the wall clock, as the benchmarks are, so time the host takes
/// from a thread shows too. The benchmarks record it before each timed call,
/// so a slow repetition can be told apart from a slow machine
/// (docs/MEASUREMENT.md, "Witness").
struct MachineWitness {
  double core_gflops = 0;  ///< per thread, the slowest thread's
  double mem_gbps = 0;     ///< per thread, the slowest thread's
};
MachineWitness measure_machine_witness(int threads = 1);

}  // namespace sphnl::bench
