#include "sphnl/run_checks.hpp"

#include <thread>
#include <vector>

namespace sphnl {

namespace fs = std::filesystem;

void check_case_size(const Case& c, const RunConfig& config) {
  if (c.n_fluid >= kMinFluidParticles) return;
  const std::string key = config.dx > 0 ? "dx" : "particles";
  const std::string fix = config.dx > 0 ? "a smaller dx (e.g. --set dx=" + std::to_string(c.dx / 2) + ")"
                                        : "more particles (e.g. --set particles=3000)";
  throw ConfigError("the case has " + std::to_string(c.n_fluid) + " fluid particles (" + key + " = " +
                    (config.dx > 0 ? std::to_string(config.dx) : std::to_string(config.particles)) + "), fewer than the " +
                    std::to_string(kMinFluidParticles) + " a dam break needs; give " + fix);
}

std::string threads_warning(int threads) {
  const unsigned hw = std::thread::hardware_concurrency();
  if (hw == 0 || static_cast<unsigned>(threads) <= hw) return "";
  return "warning: threads = " + std::to_string(threads) + " is more than the " + std::to_string(hw) +
         " hardware threads; the extra threads only wait for each other (threads=1000 on 2 cores ran 42x slower)";
}

void prepare_output_folder(const fs::path& dir, bool overwrite) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  std::vector<fs::path> ours;
  for (const char* f : {"summary.json", "snapshots.pvd"})
    if (fs::exists(dir / f, ec)) ours.push_back(dir / f);
  if (fs::is_directory(dir / "snapshots", ec))
    for (const auto& e : fs::directory_iterator(dir / "snapshots", ec))
      if (e.path().filename().string().rfind("step_", 0) == 0) ours.push_back(e.path());
  if (ours.empty()) return;
  if (!overwrite)
    throw std::runtime_error("output folder '" + dir.string() + "' already holds a run (" + std::to_string(ours.size()) +
                             " files: summary.json, snapshots); its snapshots would mix with this run's. Give another "
                             "--out, or pass --overwrite to delete that run's files first");
  for (const auto& p : ours) {
    fs::remove(p, ec);
    if (ec) throw std::runtime_error("cannot remove '" + p.string() + "' for --overwrite: " + ec.message());
  }
}

}  // namespace sphnl
