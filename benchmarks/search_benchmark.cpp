// The `search` family: `sphnl neighbours` as a neighbour-search library, and
// its peers. Full neighbour lists (every j != i with r < R, R = 2.6 spacings)
// of a cloud of `particles` points (benchmarks/peers/clouds.hpp), built by sphnl's
// engine (impl: sphnl), through the public API sphnl/search.hpp on the same
// engine (impl: api, rows in input order and sorted; api_visit, rows handed
// over in place), or by a peer (impl), warm (buffers of the previous call reused) or as
// a first call (call: first; see run_first below). Every repetition's pair
// set is checked against the one sphnl's engine finds on the same cloud (an
// order-independent checksum of the entries): warm, the untimed call that
// warms the buffers up before the timed one; first, the timed call's own
// lists once it has been timed (an extra untimed call would cost as much as
// the timed one, and a peer's call is the slow part of the experiment). A
// difference ends the benchmark with an error naming both implementations,
// and nothing is reported.
#include <malloc.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <thread>
#include <tuple>

#include "bench_common.hpp"
#include "bench_guard.hpp"
#include "peers/clouds.hpp"
#include "roofline/core_peaks.hpp"
#include "sphnl/experiment_schema.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/neighbours/pair_checksum.hpp"
#include "sphnl/search.hpp"
#include "sphnl/timer.hpp"
#ifdef SPHNL_HAVE_NANOFLANN
#include "peers/nanoflann_lists.hpp"
#endif

namespace sphnl::bench {

using nlohmann::json;

namespace {

constexpr double kRadius = 2.6;  // spacings: 4/3 pi 2.6^3 = 74 neighbours a point

/// The axes of the family, in name order, with the value a sweep without the
/// axis means (the first five are required; older results have only those).
const std::vector<std::pair<std::string, json>>& search_axes() {
  static const std::vector<std::pair<std::string, json>> axes = {
      {"particles", nullptr}, {"gridder", nullptr},          {"cell_order", nullptr}, {"reorder", nullptr},
      {"threads", nullptr},   {"impl", "sphnl"},             {"cloud", "lattice"},
      {"memory_order", "generated"}, {"call", "warm"}, {"pages", "base"}, {"freed_memory", "as_found"}};
  return axes;
}

json axis_value(const Point& p, const std::string& axis) {
  if (p.count(axis)) return p.at(axis);
  for (const auto& [name, fallback] : search_axes())
    if (name == axis) return fallback;
  throw std::logic_error("unknown search axis " + axis);
}

/// One cloud and the pair set sphnl's engine finds on it (one thread, the
/// default options): the reference every configuration is checked against.
struct CloudCase {
  peers::Cloud cloud;
  PairChecksum reference;
};

PairChecksum checksum_of(const NeighbourLists& lists) {
  PairChecksum c;
  for (std::size_t r = 0; r < lists.num_rows(); ++r) {
    const auto row = lists.row(r);
    c.add_row(lists.point(r), row.data(), row.size());
  }
  return c;
}

const CloudCase& cloud_case(peers::CloudKind kind, peers::MemoryOrder order, long n) {
  static std::map<std::tuple<int, int, long>, std::unique_ptr<CloudCase>> cache;
  auto& slot = cache[{static_cast<int>(kind), static_cast<int>(order), n}];
  if (!slot) {
    auto c = std::make_unique<CloudCase>();
    c->cloud = peers::make_cloud(kind, order, n);
    NeighbourSearch reference;
    NeighbourLists lists;
    reference.run(c->cloud.x, c->cloud.y, c->cloud.z, kRadius, lists);
    c->reference = checksum_of(lists);
    slot = std::move(c);
  }
  return *slot;
}

/// Page faults so far: this process's (minor and major, getrusage), and the
/// transparent huge pages the kernel has faulted in, system-wide
/// (/proc/vmstat thp_fault_alloc; -1 where unreadable). Read around the timed
/// call: a first call's faults are most of its cost, and their count tells a
/// slow call that faulted more from one that waited on the same faults.
struct FaultCount {
  double process = 0, thp = -1;
};

FaultCount fault_count() {
  FaultCount f;
  const ProcessFaults p = process_faults();
  f.process = p.minor + p.major;
  std::ifstream vmstat("/proc/vmstat");
  std::string key;
  double value = 0;
  while (vmstat >> key >> value)
    if (key == "thp_fault_alloc") {
      f.thp = value;
      break;
    }
  return f;
}

/// KiB of free memory the kernel has reported to the host so far (virtio
/// free page reporting: /sys/module/page_reporting/parameters/reported_kib,
/// which some guest kernels expose; -1 where unreadable). Read across the
/// wait before a first call: how much of the memory that call may take the
/// host had been handed, a witness the process's own fault counts lack.
double host_reported_kib() {
  std::ifstream f("/sys/module/page_reporting/parameters/reported_kib");
  double kib = -1;
  if (!(f >> kib)) return -1;
  return kib;
}

/// What one call of an implementation reports.
struct CallResult {
  double seconds = 0;
  std::uint64_t entries = 0;
  double bytes = 0;
  double s_build = -1, s_search = -1;  // sphnl only
  double s_sweep_max = 0, sweep_busy_fraction = 0;  // sphnl only
};

/// One implementation on one cloud: `call(fresh)` builds the full lists once,
/// into new objects and never-touched memory when `fresh` (after release()).
class Runner {
 public:
  virtual ~Runner() = default;
  virtual CallResult call(bool fresh) = 0;
  /// Frees every object the calls so far made (search structures, lists), so
  /// that malloc_trim can hand their pages back before a fresh call: freed
  /// inside the call instead, they would be reused warm by the new objects.
  virtual void release() = 0;
  virtual PairChecksum checksum() const = 0;
};

class SphnlRunner : public Runner {
 public:
  SphnlRunner(const SearchOptions& so, const peers::Cloud& cloud) : so_(so), cloud_(cloud) {}
  CallResult call(bool fresh) override {
    if (fresh || !search_) {
      release();
      search_ = std::make_unique<NeighbourSearch>(so_);
      lists_ = std::make_unique<NeighbourLists>();
    }
    Stopwatch sw;
    search_->run(cloud_.x, cloud_.y, cloud_.z, kRadius, *lists_);
    CallResult r;
    r.seconds = sw.lap();
    r.entries = lists_->num_entries();
    r.bytes = static_cast<double>(search_->bytes() + lists_->bytes());
    r.s_build = search_->times().build;
    r.s_search = search_->times().search;
    r.s_sweep_max = search_->times().sweep_max;
    r.sweep_busy_fraction = search_->times().sweep_sum / (so_.threads * search_->times().sweep_max);
    return r;
  }
  PairChecksum checksum() const override { return checksum_of(*lists_); }
  void release() override {
    search_.reset();
    lists_.reset();
  }

 private:
  SearchOptions so_;
  const peers::Cloud& cloud_;
  std::unique_ptr<NeighbourSearch> search_ = std::make_unique<NeighbourSearch>(so_);
  std::unique_ptr<NeighbourLists> lists_ = std::make_unique<NeighbourLists>();
};

/// The public API (sphnl/search.hpp) as a user calls it, on the same engine:
/// Search::build, then the full rows either in input order and sorted
/// (`api`: rows_into, into the caller's offsets and indices, allocated once
/// and kept between warm calls) or handed over in place, row by row
/// (`api_visit`: for_each_row; the caller only sums the row lengths). Beside
/// impl:sphnl (the bare engine) this measures what the API adds.
class ApiRunner : public Runner {
 public:
  ApiRunner(const SearchOptions& so, const peers::Cloud& cloud, bool visit) : cloud_(cloud), visit_(visit) {
    options_.gridder = so.gridder;
    options_.cell_order = so.order;
    options_.reorder = so.reorder;
    options_.threads = so.threads;
    options_.huge_pages = so.huge_pages;
  }
  CallResult call(bool fresh) override {
    if (fresh || !search_) {
      release();
      search_ = std::make_unique<Search>(kRadius, options_);
    }
    Stopwatch sw;
    search_->build(cloud_.x, cloud_.y, cloud_.z);
    std::uint64_t entries = 0;
    if (visit_) {
      search_->for_each_row([&](std::uint32_t, std::span<const std::uint32_t> row) { entries += row.size(); });
    } else {
      offsets_.resize(search_->size() + 1);
      indices_.resize(search_->num_entries(Rows::full));
      search_->rows_into(Rows::full, offsets_, indices_);
      entries = indices_.size();
    }
    CallResult r;
    r.seconds = sw.lap();
    r.entries = entries;
    r.bytes = static_cast<double>(offsets_.capacity() * sizeof(std::int64_t) + indices_.capacity() * sizeof(std::uint32_t));
    return r;
  }
  PairChecksum checksum() const override {
    PairChecksum c;
    if (visit_) {
      search_->for_each_row([&](std::uint32_t i, std::span<const std::uint32_t> row) { c.add_row(i, row.data(), row.size()); });
    } else {
      for (std::size_t i = 0; i + 1 < offsets_.size(); ++i)
        c.add_row(static_cast<std::uint32_t>(i), indices_.data() + offsets_[i],
                  static_cast<std::size_t>(offsets_[i + 1] - offsets_[i]));
    }
    return c;
  }
  void release() override {
    search_.reset();
    offsets_ = std::vector<std::int64_t>();
    indices_ = std::vector<std::uint32_t>();
  }

 private:
  Search::Options options_;
  const peers::Cloud& cloud_;
  bool visit_;
  std::unique_ptr<Search> search_;
  std::vector<std::int64_t> offsets_;
  std::vector<std::uint32_t> indices_;
};

#ifdef SPHNL_HAVE_NANOFLANN
class NanoflannRunner : public Runner {
 public:
  NanoflannRunner(int threads, const peers::Cloud& cloud) : threads_(threads), cloud_(cloud) {}
  CallResult call(bool fresh) override {
    if (fresh || !lists_) lists_ = std::make_unique<peers::PeerLists>();
    Stopwatch sw;
    peers::nanoflann_full_lists(cloud_.x, cloud_.y, cloud_.z, kRadius, threads_, *lists_);
    CallResult r;
    r.seconds = sw.lap();
    r.entries = lists_->entries.size();
    r.bytes = static_cast<double>(lists_->entries.capacity() * sizeof(std::uint32_t) +
                                  lists_->offsets.capacity() * sizeof(std::uint64_t));
    return r;
  }
  PairChecksum checksum() const override { return lists_->checksum(); }
  void release() override { lists_.reset(); }

 private:
  int threads_;
  const peers::Cloud& cloud_;
  std::unique_ptr<peers::PeerLists> lists_ = std::make_unique<peers::PeerLists>();
};
#endif

std::unique_ptr<Runner> make_runner(const std::string& impl, const SearchOptions& so, int threads,
                                    const peers::Cloud& cloud) {
  if (impl == "sphnl") return std::make_unique<SphnlRunner>(so, cloud);
  if (impl == "api" || impl == "api_visit") return std::make_unique<ApiRunner>(so, cloud, impl == "api_visit");
#ifdef SPHNL_HAVE_NANOFLANN
  if (impl == "nanoflann") return std::make_unique<NanoflannRunner>(threads, cloud);
#else
  (void)threads;
  if (impl == "nanoflann")
    throw std::runtime_error("this sphnl_bench was built without nanoflann (install libnanoflann-dev and "
                             "reconfigure: CMake then builds the peer rows)");
#endif
  throw std::invalid_argument("impl: '" + impl + "'; allowed: sphnl, api, api_visit, nanoflann");
}

}  // namespace

void register_search_benchmarks(const json& sweep) {
  std::vector<std::string> axes;
  for (const auto& a : search_axes()) axes.push_back(a.first);
  for (const Point& p : cross_product(sweep, axes)) {
    SearchOptions so;
    const RunConfig cfg = run_config_of(p);  // the config keys of the point; impl, cloud, ... are the bench's own
    so.gridder = cfg.gridder;
    so.order = cfg.cell_order;
    so.reorder = cfg.reorder;
    so.threads = cfg.threads;
    const long n = cfg.particles;
    const std::string impl = axis_value(p, "impl").get<std::string>();
    const peers::CloudKind kind = peers::cloud_kind(axis_value(p, "cloud").get<std::string>());
    const peers::MemoryOrder order = peers::memory_order(axis_value(p, "memory_order").get<std::string>());
    const std::string call = axis_value(p, "call").get<std::string>();
    if (call != "warm" && call != "first") throw std::invalid_argument("call: '" + call + "'; allowed: warm, first");
    const bool first = call == "first";
    // pages: the lists on 4 KiB base pages (the axis's default, as every
    // result before the axis existed), advised as huge pages, or `default`:
    // what the public API's Search::Options chooses on this machine
    // (huge_pages_by_default(): base pages where the kernel reports free
    // memory to its host), so a claim about the library as users get it
    // measures that. nanoflann's rows ignore the axis.
    const std::string pages = axis_value(p, "pages").get<std::string>();
    if (pages != "base" && pages != "huge" && pages != "default")
      throw std::invalid_argument("pages: '" + pages + "'; allowed: base, huge, default");
    so.huge_pages = pages == "default" ? sphnl::huge_pages_by_default() : pages == "huge";
    // freed_memory (first calls): the memory a first call's pages come from.
    // as_found: whatever the kernel holds free (the default, as before the
    // axis). just_freed: an untimed call of the same size made and freed
    // right before. idle_<s>s: the same, then s seconds idle before the timed
    // call. On a virtual machine that reports free memory to its host
    // (virtio free page reporting) the pages idle long enough are handed
    // back to the host, and touching them again costs host faults that the
    // guest's own fault counters do not see (docs/FINDINGS.md, "Where slow
    // first calls go").
    const std::string freed = axis_value(p, "freed_memory").get<std::string>();
    const int idle_s = freed_memory_idle_seconds(freed);  // validated with the file: >= 0
    if (freed != "as_found" && !first)
      throw std::invalid_argument("freed_memory: '" + freed + "' applies to first calls only (call: first); "
                                  "a warm call reuses its own buffers");
    const std::string name = benchmark_name("search", p, axes);
    benchmark::RegisterBenchmark(name.c_str(), [=](benchmark::State& st) {
      guarded(name, [&] {
        const long sequence = next_run_sequence();
        const CloudCase& cc = cloud_case(kind, order, n);
        const std::unique_ptr<Runner> runner = make_runner(impl, so, cfg.threads, cc.cloud);
        auto check = [&] {
          require_same_pairs(impl + " (" + name + ")", runner->checksum(), "sphnl (engine, 1 thread)", cc.reference);
        };
        if (!first) {
          runner->call(false);  // untimed: the warm state, and its pair set checked
          check();
        }
        CallResult r;
        FaultCount faults;
        double reported_kib = -1;  // KiB reported to the host between freeing and the call (first calls)
        const MachineWitness witness = measure_machine_witness(cfg.threads);  // untimed, just before the call
        if (freed != "as_found") runner->call(true);  // untimed: its memory is what the timed call finds freed
        for (auto _ : st) {
          // call: first stands in for the first call of a fresh process: the
          // last call's objects freed, every free page the allocator holds
          // given back to the kernel (malloc_trim), then new objects, so each
          // page the call writes is a fresh one and its fault is timed
          // (docs/CONTRACTS.md).
          if (first) {
            runner->release();
            malloc_trim(0);
          }
          const double reported_before = first ? host_reported_kib() : -1;
          if (idle_s > 0) {  // the freed pages left idle, the wait not timed
            st.PauseTiming();
            std::this_thread::sleep_for(std::chrono::seconds(idle_s));
            st.ResumeTiming();
          }
          const double reported_after = first ? host_reported_kib() : -1;
          reported_kib = reported_before >= 0 && reported_after >= 0 ? reported_after - reported_before : -1;
          const FaultCount before = fault_count();
          r = runner->call(first);
          const FaultCount after = fault_count();
          faults.process = after.process - before.process;
          faults.thp = before.thp >= 0 && after.thp >= 0 ? after.thp - before.thp : -1;
        }
        if (first) check();  // the lists just timed, before anything is reported
        st.counters["n_particles"] = static_cast<double>(cc.cloud.size());
        st.counters["entries"] = static_cast<double>(r.entries);
        st.counters["entries_per_s"] = static_cast<double>(r.entries) / r.seconds;
        st.counters["s_call"] = r.seconds;
        if (r.s_build >= 0) {
          st.counters["s_build"] = r.s_build;
          st.counters["s_search"] = r.s_search;
          st.counters["s_search_sweep"] = r.s_sweep_max;
          st.counters["search_busy_fraction"] = r.sweep_busy_fraction;
        }
        st.counters["bytes"] = r.bytes;
        if (impl != "nanoflann") st.counters["huge_pages"] = so.huge_pages ? 1 : 0;  // the pages the lists asked for
        st.counters["page_faults"] = faults.process;
        if (faults.thp >= 0) st.counters["thp_faults"] = faults.thp;
        if (reported_kib >= 0) st.counters["host_reported_kib"] = reported_kib;
        st.counters["witness_core_gflops"] = witness.core_gflops;
        st.counters["witness_mem_gbps"] = witness.mem_gbps;
        st.counters["run_sequence"] = static_cast<double>(sequence);
      });
    })->Unit(benchmark::kMillisecond)->UseRealTime();
  }
}

}  // namespace sphnl::bench
