#pragma once
// Checks `sphnl run` makes before it simulates: nonsense cases are errors,
// settings that work but hurt are warnings, and an output folder of an
// earlier run is not silently mixed with this one.
#include <cstddef>
#include <filesystem>
#include <string>

#include "sphnl/case.hpp"
#include "sphnl/config.hpp"

namespace sphnl {

/// Fewest fluid particles a run accepts. Below it the water column is
/// under ~5 lattice spacings, about 1.5 kernel radii (2h = 3 dx at the
/// default h), across: no fluid particle has a full kernel support of
/// fluid, so the run is a boundary-dominated droplet, not the dam break of
/// paper §2.2 (particles=100 gives 2 fluid particles, dx=1.0 none).
inline constexpr std::size_t kMinFluidParticles = 200;

/// Throws ConfigError when `c` has fewer than kMinFluidParticles fluid
/// particles, naming the key to change (particles or dx, as `config` set).
void check_case_size(const Case& c, const RunConfig& config);

/// A warning line (empty when none) for more threads than hardware threads:
/// threads=1000 on 2 cores ran 42x slower.
std::string threads_warning(int threads);

/// Makes `dir` ready for a new run's output. A folder that already holds a
/// run's files (summary.json, snapshots.pvd, snapshots/step_*) is refused
/// unless `overwrite`, which removes exactly those files. Throws
/// std::runtime_error naming the folder and the option.
void prepare_output_folder(const std::filesystem::path& dir, bool overwrite);

}  // namespace sphnl
