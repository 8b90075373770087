#pragma once
// Up-front memory estimates: `sphnl run`, `sphnl neighbours` and each
// benchmark compare what they will need with the memory available
// (/proc/meminfo MemAvailable) before they allocate, and stop at once with
// the estimate and the option that overrides the check. Without it,
// particles=1e8 ran three minutes before std::bad_alloc (or the OOM killer).
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>

#include "sphnl/config.hpp"

namespace sphnl {

/// Thrown when an estimate exceeds the available memory; the message gives
/// the estimate, what is available and the override.
struct MemoryError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct MemoryEstimate {
  double bytes = 0;
  std::string detail;  // how the figure was made, for the message
};

/// MemAvailable of /proc/meminfo in bytes, 0 when unknown. The environment
/// variable SPHNL_MEMORY_AVAILABLE (bytes) replaces it, so tests can play a
/// small machine.
double available_memory_bytes();

/// Peak memory of a simulation with `config` (sphnl run, the step benchmark):
/// per particle, the SoA state, the gridder and orderings, and for the
/// Verlet lists the lists (see the measured figures in memory_estimate.cpp).
MemoryEstimate estimate_run_memory(const RunConfig& config);

/// Peak memory of `sphnl neighbours` for `points` points and `entries` list
/// entries (each pair counted twice): input, search structures, the lists,
/// and the --pairs output rows.
MemoryEstimate estimate_search_memory(std::uint64_t points, std::uint64_t entries);

/// Exact number of list entries (ordered pairs i != j with |xi - xj| < radius)
/// without storing any list, counting stops as soon as it exceeds
/// `stop_above` (the return value is then > stop_above, not exact). Cell
/// pairs whose bounding boxes lie wholly within the radius are counted
/// without distance tests, so 10^5 identical points take milliseconds.
/// `exact = false` skips the distance tests altogether and returns an upper
/// bound (every candidate pair of neighbouring cells of side `radius`) in
/// O(N log N): the cheap first look that makes the exact count rarely needed.
std::uint64_t count_neighbour_entries(std::span<const double> x, std::span<const double> y, std::span<const double> z,
                                      double radius, std::uint64_t stop_above, bool exact = true);

/// Throws MemoryError when `estimate` exceeds the available memory.
/// `what` names the job ("sphnl run", "benchmark step/n:..."), `override_hint`
/// the option that skips the check ("--force-memory").
void check_memory(const MemoryEstimate& estimate, const std::string& what, const std::string& override_hint);

/// Peak resident set of this process in bytes (VmHWM of /proc/self/status).
/// Not getrusage's ru_maxrss: Linux keeps that across execve, so a benchmark
/// started by a 180 MB Python driver reported the driver's peak as its own.
double peak_resident_bytes();

/// "1.23 GiB"
std::string format_bytes(double bytes);

}  // namespace sphnl
