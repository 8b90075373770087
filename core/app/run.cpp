#include "run.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "sphnl/config_file.hpp"
#include "sphnl/memory_estimate.hpp"
#include "sphnl/run_checks.hpp"
#include "sphnl/output.hpp"
#include "sphnl/parallel/gather_particles.hpp"
#include "sphnl/ranks.hpp"
#include "sphnl/timer.hpp"
#include "sphnl_revision.hpp"

namespace sphnl {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void on_interrupt(int) { g_interrupted = 1; }

std::size_t peak_rss_bytes() { return static_cast<std::size_t>(peak_resident_bytes()); }

std::string format_duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  char buf[32];
  const long t = std::lround(s);
  if (t >= 3600) std::snprintf(buf, sizeof buf, "%ldh%02ldm", t / 3600, (t / 60) % 60);
  else if (t >= 60) std::snprintf(buf, sizeof buf, "%ldm%02lds", t / 60, t % 60);
  else std::snprintf(buf, sizeof buf, "%.1fs", s);
  return buf;
}

/// Progress line on stderr, at most 4 per second: carriage-return updates on a
/// terminal, plain lines otherwise (logs stay readable).
class Progress {
 public:
  explicit Progress(bool enabled) : enabled_(enabled), tty_(::isatty(::fileno(stderr)) != 0) {}

  void update(const Simulation& sim, double fraction_done, bool force) {
    if (!enabled_) return;
    const double now = clock_.lap() + elapsed_;
    elapsed_ = now;
    if (!force && now - last_print_ < 0.25) return;
    last_print_ = now;
    const double rate = now > 0 ? static_cast<double>(sim.steps_done()) / now : 0;
    const double eta = fraction_done > 0 ? std::max(0.0, now * (1 - fraction_done) / fraction_done) : -1;
    const Case& c = sim.case_info();
    const std::size_t total = sim.domain() ? c.n_fluid + c.n_boundary : sim.particles().size();
    const std::size_t active = total - sim.lost();
    std::fprintf(stderr, "%sstep %ld  t = %.4f s  dt = %.3e s  particles %zu  %.1f steps/s  ETA %s%s",
                 tty_ ? "\r" : "", sim.steps_done(), sim.time(), sim.last_dt(), active, rate,
                 format_duration(eta).c_str(), tty_ ? "\033[K" : "\n");
    std::fflush(stderr);
    dirty_ = tty_;
  }
  void finish() {
    if (enabled_ && dirty_) std::fputc('\n', stderr);
    dirty_ = false;
  }

 private:
  bool enabled_, tty_, dirty_ = false;
  Stopwatch clock_;
  double elapsed_ = 0, last_print_ = -1;
};

/// snapshot_pieces=per_rank: no gather (rank 0 need not hold every
/// particle); each rank writes a piece of its own particles, rank 0 the
/// .pvtu at `pvtu` naming them all. Every rank throws when one could not
/// write its piece.
void write_snapshot_pieces(Communicator& comm, const Simulation& sim, const fs::path& snap_dir,
                           const std::string& stem, const fs::path& pvtu) {
  auto piece = [&](int r) {
    char name[32];
    std::snprintf(name, sizeof name, "_rank%04d.vtu", r);
    return stem + name;
  };
  std::string error;
  try {
    write_vtu(snap_dir / piece(comm.rank()), sim.particles(), sim.time(), sim.owned());
  } catch (const std::exception& ex) {
    error = "rank " + std::to_string(comm.rank()) + ": " + ex.what();
  }
  if (comm.any(!error.empty()))
    throw std::runtime_error(error.empty() ? "another rank could not write its snapshot piece" : error);
  if (comm.rank() != 0) return;
  std::vector<std::string> pieces;
  for (int r = 0; r < comm.size(); ++r) pieces.push_back(piece(r));
  write_pvtu(pvtu, pieces);
}

std::string snapshot_stem(long step) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "step_%06ld", step);
  return buf;
}

}  // namespace

std::string run_usage() {
  return "usage: sphnl run [--config FILE.json] [--set key=value]... [--out DIR] [--quiet] [--overwrite] [--force-memory]\n"
         "\n"
         "Runs the dam break with obstacle of Dominguez et al. 2011, section 2.2.\n"
         "  --config FILE   JSON object of config keys (see README.md, section 'Configuration')\n"
         "  --set key=value override one key (repeatable; applied after the file)\n"
         "  --out DIR       output directory (default: sphnl-out); receives summary.json,\n"
         "                  snapshots/step_NNNNNN.vtu and .csv, snapshots.pvd\n"
         "  --quiet         no progress line\n"
         "  --overwrite     replace the run already in DIR (else a DIR holding one is refused)\n"
         "  --force-memory  run even when the memory estimate exceeds the available memory\n"
         "config keys: " +
         [] {
           std::string s;
           for (const auto& k : config_keys()) s += (s.empty() ? "" : ", ") + k;
           return s;
         }() + "\n";
}

RunOptions parse_run_options(int argc, char** argv) {
  RunOptions o;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i], value;
    bool has_value = false;
    if (arg.rfind("--", 0) == 0) {
      const auto eq = arg.find('=');
      if (eq != std::string::npos && arg != "--set") {
        value = arg.substr(eq + 1);
        arg = arg.substr(0, eq);
        has_value = true;
      }
    }
    auto take_value = [&]() -> std::string {
      if (has_value) return value;
      // `--config --out x` must not read "--out" as the file name.
      if (i + 1 >= argc || std::strncmp(argv[i + 1], "--", 2) == 0) throw ConfigError("option " + arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--config") o.config_file = take_value();
    else if (arg == "--set") o.overrides.push_back(take_value());
    else if (arg == "--out") o.out_dir = take_value();
    else if (arg == "--quiet" && !has_value) o.quiet = true;
    else if (arg == "--overwrite" && !has_value) o.overwrite = true;
    else if (arg == "--force-memory" && !has_value) o.force_memory = true;
    else throw ConfigError("unknown option '" + std::string(argv[i]) + "' of sphnl run; allowed: --config FILE, --set key=value, --out DIR, --quiet, --overwrite, --force-memory, --help");
  }
  if (o.out_dir.empty()) throw ConfigError("--out needs a directory name");
  return o;
}

RunConfig load_run_config(const RunOptions& options) {
  json j = json::object();
  if (!options.config_file.empty()) j = read_config_file(options.config_file);
  for (const auto& kv : options.overrides) apply_override(j, kv);
  return config_from_json(j);
}

json run_summary(const Simulation& sim, double initial_mass, double wall_total_s) {
  const Case& cs = sim.case_info();
  const PhaseTimes& t = sim.phase_times();
  const NeighbourStats& st = sim.neighbour_stats();
  const std::size_t n = sim.particles().size();
  const double steps = static_cast<double>(std::max<long>(sim.steps_done(), 1));
  const double particle_steps = steps * static_cast<double>(std::max<std::size_t>(n, 1));
  const auto p = sim.momentum();
  json s;
  s["config"] = config_to_json(sim.config());
  s["n_fluid"] = cs.n_fluid;
  s["n_boundary"] = cs.n_boundary;
  s["n_total"] = n;
  s["dx"] = cs.dx;
  s["h"] = sim.physics().h();
  s["c0"] = sim.physics().c0;
  s["steps"] = sim.steps_done();
  s["simulated_time"] = sim.time();
  s["last_dt"] = sim.last_dt();
  // Phases of the paper's Table I, wall seconds summed over all steps.
  s["wall_time_s"] = {{"neighbour_list", t.neighbour_list}, {"force", t.force}, {"update", t.update},
                      {"total", t.total()}, {"run", wall_total_s}};
  s["seconds_per_step"] = t.total() / steps;
  s["particles_lost"] = sim.lost();
  s["total_mass"] = {{"initial", initial_mass}, {"final", sim.total_mass()}};
  s["momentum"] = {p[0], p[1], p[2]};
  s["max_speed"] = sim.max_speed();
  s["neighbour_bytes"] = sim.neighbour_bytes();
  s["peak_rss_bytes"] = peak_rss_bytes();
  // Pairs are counted once per particle of the pair (docs/CONTRACTS.md).
  s["neighbour_stats"] = {{"builds", st.builds},
                          {"candidates", st.candidates},
                          {"interactions", st.interactions},
                          {"candidates_per_particle", 2.0 * static_cast<double>(st.candidates) / particle_steps},
                          {"interactions_per_particle", 2.0 * static_cast<double>(st.interactions) / particle_steps},
                          {"kernel_lanes_per_pair", st.kernel_lanes_per_pair()},
                          {"max_steps_per_list", st.max_steps_per_list},
                          {"mean_steps_per_list", st.mean_steps_per_list()},
                          {"interacting_fraction_of_candidates",
                           st.candidates ? static_cast<double>(st.interactions) / static_cast<double>(st.candidates) : 0.0},
                          // Verlet lists (paper §2.5); zero for the cell-linked list
                          {"forced_rebuilds", st.forced_rebuilds},
                          {"list_pairs", st.list_pairs},
                          {"list_pairs_built", st.list_pairs_built},
                          {"list_bytes", st.list_bytes},
                          {"max_list_bytes", st.max_list_bytes},
                          {"skin_m", st.skin},
                          {"vl_misses", st.vl_misses},
                          {"verified_steps", st.verified_steps},
                          {"kgc_fallbacks", st.kgc_fallbacks},
                          // extra_loops: passes run and the sum of their results (README.md, "Ablations")
                          {"extra_loop_passes", st.extra_loop_passes},
                          {"extra_loop_checksum", st.extra_loop_checksum}};
  s["git_revision"] = SPHNL_GIT_REVISION;
  s["build_type"] = SPHNL_BUILD_TYPE;
  return s;
}

json parallel_summary(const Simulation& sim, Communicator& comm) {
  const DomainExchange& d = *sim.domain();
  const NeighbourStats& st = sim.neighbour_stats();
  const PhaseTimes& t = sim.phase_times();
  const double steps = static_cast<double>(std::max<long>(sim.steps_done(), 1));
  const double owned = static_cast<double>(sim.owned()), ghosts = static_cast<double>(d.ghosts());
  double fluid = 0;
  for (std::size_t i = 0; i < sim.owned(); ++i) fluid += sim.particles().type[i] == ParticleType::fluid;
  // Counts summed over ranks (a pair across a rank boundary counts on both
  // sides; pairs of two ghosts are never evaluated); phase times as the
  // slowest rank's.
  double sums[] = {static_cast<double>(st.candidates), static_cast<double>(st.interactions),
                   static_cast<double>(st.list_pairs), static_cast<double>(st.kgc_fallbacks),
                   static_cast<double>(sim.neighbour_bytes()), static_cast<double>(d.bytes_sent())};
  comm.sum(sums);
  double maxima[] = {t.neighbour_list, t.force, t.update, t.communication, t.total(), owned, -owned, ghosts, -ghosts,
                     static_cast<double>(peak_rss_bytes()), fluid, -fluid,
                     static_cast<double>(st.interactions), -static_cast<double>(st.interactions)};
  comm.max(maxima);
  auto count = [](double v) { return static_cast<std::uint64_t>(std::llround(v)); };
  auto range = [&](double lo, double hi) { return json{{"min", count(lo)}, {"max", count(hi)}}; };
  json p;
  p["ranks"] = comm.size();
  p["particles_per_rank"] = range(-maxima[6], maxima[5]);
  p["ghosts_per_rank"] = range(-maxima[8], maxima[7]);
  p["fluid_per_rank"] = range(-maxima[11], maxima[10]);
  // The work balance the key ranges reached (balance_by): pairs each rank evaluated over the run.
  p["interactions_per_rank"] = range(-maxima[13], maxima[12]);
  p["bytes_sent_per_step"] = sums[5] / steps;
  p["partitions"] = d.partitions();
  p["counts"] = {{"candidates", count(sums[0])}, {"interactions", count(sums[1])}, {"list_pairs", count(sums[2])},
                 {"kgc_fallbacks", count(sums[3])}, {"neighbour_bytes", count(sums[4])}};
  p["wall_time_s"] = {{"neighbour_list", maxima[0]}, {"force", maxima[1]}, {"update", maxima[2]},
                      {"communication", maxima[3]}, {"total", maxima[4]}};
  p["peak_rss_bytes"] = count(maxima[9]);
  return p;
}

int run_main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::cout << run_usage();
      return 0;
    }
  // A launcher (mpirun, srun) with P > 1 ranks: this process is one of them.
  std::unique_ptr<Communicator> comm;
  try {
    comm = start_ranks();
  } catch (const std::exception& e) {
    std::cerr << "sphnl run: " << e.what() << "\n";
    return 2;
  }
  const bool root = !comm || comm->rank() == 0;
  std::ostream null_stream(nullptr);
  std::ostream& err = root ? std::cerr : null_stream;  // every rank finds the same input errors: rank 0 tells
  // --- everything the user gave is checked before any work ---
  RunOptions options;
  RunConfig config;
  try {
    options = parse_run_options(argc, argv);
    config = load_run_config(options);
  } catch (const ConfigError& e) {
    err << "sphnl run: " << e.what() << "\n\n" << run_usage();
    return 2;
  } catch (const nlohmann::json::exception& e) {
    err << "sphnl run: " << e.what() << "\n";
    return 2;
  }
  if (!options.force_memory) {
    try {
      check_memory(estimate_run_memory(config), "this run", "--force-memory");
    } catch (const MemoryError& e) {
      err << "sphnl run: " << e.what() << "\n";
      return 2;
    }
  }
  if (const std::string w = threads_warning(config.threads); !w.empty()) err << "sphnl run: " << w << "\n";
  if (comm) options.quiet = options.quiet || !root;
  const fs::path out_dir(options.out_dir), snap_dir = out_dir / "snapshots";
  bool folder_ok = true;
  if (root) {  // one rank prepares the folder that rank 0 alone writes
    try {
      prepare_output_folder(out_dir, options.overwrite);
      ensure_writable_directory(out_dir);
      ensure_writable_directory(snap_dir);
    } catch (const std::exception& e) {
      err << "sphnl run: " << e.what() << "\n";
      folder_ok = false;
    }
  }
  if (comm) folder_ok = !comm->any(!folder_ok);
  if (!folder_ok) return 2;

  Stopwatch wall;
  std::unique_ptr<Simulation> sim_ptr;
  try {
    sim_ptr = std::make_unique<Simulation>(config, comm.get());
    check_case_size(sim_ptr->case_info(), config);
  } catch (const ConfigError& e) {
    err << "sphnl run: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    err << "sphnl run: cannot set up the case: " << e.what() << "\n";
    return 2;
  }
  Simulation& sim = *sim_ptr;
  const bool quiet = options.quiet || !config.progress;
  if (!quiet)
    std::fprintf(stderr, "sphnl run: %zu particles (%zu fluid, %zu boundary), dx = %.5g m, h = %.5g m, %s -> %s%s\n",
                 sim.domain() ? sim.case_info().n_fluid + sim.case_info().n_boundary : sim.particles().size(), sim.case_info().n_fluid, sim.case_info().n_boundary, sim.case_info().dx,
                 sim.physics().h(),
                 config.steps > 0 ? (std::to_string(config.steps) + " steps").c_str()
                                  : (std::to_string(config.end_time) + " s").c_str(),
                 out_dir.string().c_str(), comm ? (", " + std::to_string(comm->size()) + " ranks").c_str() : "");

  const double initial_mass = sim.total_mass();
  std::vector<SnapshotEntry> snapshots;
  double output_seconds = 0;
  auto snapshot = [&] {
    Stopwatch sw;
    const std::string stem = snapshot_stem(sim.steps_done());
    const bool pieces = comm && config.snapshot_pieces == SnapshotPieces::per_rank;
    const SnapshotEntry e{sim.steps_done(), sim.time(), "snapshots/" + stem + (pieces ? ".pvtu" : ".vtu"),
                          pieces ? "" : "snapshots/" + stem + ".csv"};  // per_rank writes no CSV
    snapshots.push_back(e);
    if (pieces) {
      write_snapshot_pieces(*comm, sim, snap_dir, stem, out_dir / e.vtu);
    } else if (comm) {  // rank 0 writes every rank's particles, in id order as ever
      const ParticleSet all = gather_particles(*comm, sim.particles(), sim.owned());
      if (root) {
        write_vtu(out_dir / e.vtu, all, sim.time());
        write_csv(out_dir / e.csv, all);
      }
    } else {
      write_vtu(out_dir / e.vtu, sim.particles(), sim.time());
      write_csv(out_dir / e.csv, sim.particles());
    }
    if (root) write_pvd(out_dir / "snapshots.pvd", snapshots);
    output_seconds += sw.lap();
  };
  auto summary = [&](const std::string& status) {
    json s = run_summary(sim, initial_mass, wall.lap());  // setup, steps and output
    if (comm) {
      const json p = parallel_summary(sim, *comm);
      if (!root) return;
      const Case& c = sim.case_info();
      s["n_total"] = c.n_fluid + c.n_boundary;
      for (const char* k : {"ranks", "particles_per_rank", "ghosts_per_rank", "fluid_per_rank", "interactions_per_rank",
                            "bytes_sent_per_step", "partitions"})
        s[k] = p[k];
      for (const auto& [k, v] : p["counts"].items())
        if (k == "neighbour_bytes") s[k] = v; else s["neighbour_stats"][k] = v;
      const double steps = static_cast<double>(std::max<long>(sim.steps_done(), 1)) * static_cast<double>(s["n_total"].get<std::size_t>());
      const double candidates = p["counts"]["candidates"].get<double>(), interactions = p["counts"]["interactions"].get<double>();
      s["neighbour_stats"]["candidates_per_particle"] = 2.0 * candidates / steps;
      s["neighbour_stats"]["interactions_per_particle"] = 2.0 * interactions / steps;
      s["neighbour_stats"]["interacting_fraction_of_candidates"] = candidates > 0 ? interactions / candidates : 0.0;
      const double run_s = s["wall_time_s"]["run"];
      s["wall_time_s"] = p["wall_time_s"];
      s["wall_time_s"]["run"] = run_s;
      s["seconds_per_step"] = p["wall_time_s"]["total"].get<double>() / static_cast<double>(std::max<long>(sim.steps_done(), 1));
      s["peak_rss_bytes"] = p["peak_rss_bytes"];
    }
    s["status"] = status;
    s["wall_time_s"]["output"] = output_seconds;
    json snaps = json::array();
    for (const auto& e : snapshots) {
      json entry = {{"step", e.step}, {"time", e.time}, {"vtu", e.vtu}};
      if (!e.csv.empty()) entry["csv"] = e.csv;  // snapshot_pieces=per_rank writes no CSV
      snaps.push_back(entry);
    }
    s["snapshots"] = snaps;
    write_json(out_dir / "summary.json", s);
  };

  g_interrupted = 0;
  auto old_int = std::signal(SIGINT, on_interrupt);
  auto old_term = std::signal(SIGTERM, on_interrupt);
  struct RestoreSignals {
    decltype(old_int) i, t;
    ~RestoreSignals() { std::signal(SIGINT, i); std::signal(SIGTERM, t); }
  } restore{old_int, old_term};

  Progress progress(!quiet);
  const bool by_steps = config.steps > 0;
  auto done = [&] { return by_steps ? sim.steps_done() >= config.steps : sim.time() >= config.end_time; };
  auto fraction = [&] {
    return by_steps ? static_cast<double>(sim.steps_done()) / static_cast<double>(config.steps)
                    : sim.time() / config.end_time;
  };
  std::string status = "completed";
  int exit_code = 0;
  try {
    double next_output = config.output_interval;
    if (config.output_interval > 0) snapshot();  // t = 0
    while (!done()) {
      // Distributed: every rank stops at the same step when any was interrupted.
      if (comm ? comm->any(g_interrupted != 0) : g_interrupted != 0) { status = "interrupted"; exit_code = 130; break; }
      sim.step();
      progress.update(sim, fraction(), false);
      if (config.output_interval > 0 && sim.time() >= next_output && !done()) {
        snapshot();
        // Skip intervals a single long step jumped over rather than writing duplicates.
        while (next_output <= sim.time()) next_output += config.output_interval;
      }
    }
    progress.update(sim, fraction(), true);
    progress.finish();
    if (snapshots.empty() || snapshots.back().step != sim.steps_done()) snapshot();  // the final state, always
  } catch (const std::exception& e) {
    progress.finish();
    std::cerr << "sphnl run: " << (comm ? "rank " + std::to_string(comm->rank()) + ": " : "") << e.what() << "\n";
    status = std::string("failed: ") + e.what();
    exit_code = 1;
    try {
      if (snapshots.empty() || snapshots.back().step != sim.steps_done()) snapshot();
    } catch (const std::exception& e2) {
      std::cerr << "sphnl run: " << e2.what() << "\n";
    }
  }
  try {
    summary(status);
  } catch (const std::exception& e) {
    std::cerr << "sphnl run: " << e.what() << "\n";
    return 1;
  }
  if (!quiet && root)
    std::fprintf(stderr, "sphnl run: %s: %ld steps, t = %.4f s, %.3f s per step, %zu lost; wrote %s\n",
                 status.c_str(), sim.steps_done(), sim.time(),
                 sim.phase_times().total() / static_cast<double>(std::max<long>(sim.steps_done(), 1)), sim.lost(),
                 (out_dir / "summary.json").string().c_str());
  return exit_code;
}

}  // namespace sphnl
