#include "sphnl/experiment_schema.hpp"

#include <algorithm>
#include <cmath>
#include <functional>

#include "sphnl/config.hpp"

namespace sphnl {

using nlohmann::json;

namespace {

const std::vector<std::string> kSizes = {"tiny", "default", "full"};

/// A sweep axis and the benchmark families it belongs to, with those
/// requiring it. An axis is a run-config key (README "Configuration") whose
/// values config_from_json checks, unless it has its own `check`: then it is a
/// benchmark-only axis (benchmark_only_axes()), which the bench handles itself.
struct Axis {
  const char* name;
  std::vector<std::string> families, required_in;
  std::function<std::string(const json&)> check;  // benchmark-only axes: "" when the value is fine
};

std::string positive_number(const json& v) {
  return v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() > 0 ? "" : "a number > 0";
}

/// A check accepting exactly `allowed` (string values).
std::function<std::string(const json&)> one_of(std::vector<std::string> allowed) {
  return [allowed](const json& v) {
    if (v.is_string() && std::find(allowed.begin(), allowed.end(), v.get<std::string>()) != allowed.end()) return std::string();
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
    return "one of " + list;
  };
}

std::string positive_integer(const json& v) {
  return v.is_number_integer() && v.get<long>() >= 1 ? "" : "an integer >= 1";
}

/// A first call's free memory (the search family's `freed_memory`): as_found,
/// just_freed, or idle_<s>s with 1 <= s <= 60.
std::string freed_memory_value(const json& v) {
  return v.is_string() && freed_memory_idle_seconds(v.get<std::string>()) >= 0
             ? ""
             : "\"as_found\", \"just_freed\" or \"idle_<s>s\" (s an integer from 1 to 60)";
}

std::string cache_model_name(const json& v) {
  return v.is_string() && (v == "this_machine" || v == "nehalem_2010") ? "" : "\"this_machine\" or \"nehalem_2010\"";
}

// Register a new sweep axis here (and, for its place in benchmark names, in the
// family's axis list in benchmarks/ and FAMILY_KEYS of harness/results.py).
const std::vector<Axis>& axes() {
  static const std::vector<Axis> table = {
      {"particles", {"step", "counters", "cellindex", "search", "mpi"}, {"step", "counters", "cellindex", "search", "mpi"}, {}},
      {"gridder", {"step", "counters", "search"}, {"step", "counters", "search"}, {}},
      {"cell_order", {"step", "counters", "cellindex", "search"}, {"step", "counters", "cellindex", "search"}, {}},
      {"reorder", {"step", "counters", "search"}, {"step", "counters", "search"}, {}},
      {"list", {"step", "counters", "mpi"}, {"step", "counters", "mpi"}, {}},
      {"list_steps", {"step", "counters", "mpi"}, {"step", "counters", "mpi"}, {}},
      {"kgc", {"step", "counters"}, {"step", "counters"}, {}},
      {"threads", {"step", "counters", "search", "mpi"}, {"step", "counters", "search", "mpi"}, {}},
      {"lattice", {"step", "counters"}, {}, {}},
      {"h_coefficient", {"step", "counters"}, {}, {}},
      // simulated time of the developed flow the window starts from (s): picks
      // the snapshot, not a run setting
      {"flow_time", {"step", "counters"}, {}, positive_number},
      // what the window's Simulation ran before it (default primed: one step
      // from the same snapshot, so its buffers already have the window's sizes
      // as in a long run; cold: a fresh Simulation, first touches timed)
      {"window_start", {"step", "counters"}, {}, one_of({"primed", "cold"})},
      // ablations (README.md, "Ablations"): optional, default the normal path
      {"pair_loop", {"step", "counters"}, {}, {}},
      {"simd", {"step", "counters"}, {}, {}},
      {"skip_boundary_pairs", {"step", "counters"}, {}, {}},
      {"gridder_a_variant", {"step", "counters"}, {}, {}},
      {"initial_order", {"step", "counters"}, {}, {}},
      {"extra_loops", {"step", "counters"}, {}, {}},
      // how threads > 1 keep from writing one particle at once (default private)
      {"thread_updates", {"step", "counters"}, {}, {}},
      // how the cell-linked list cuts its home cells between threads (default fluid)
      {"thread_split", {"step", "counters"}, {}, {}},
      // the order of each cell's particles after reordering (default index)
      {"inner_order", {"step", "counters"}, {}, {}},
      // the pair kernel's arithmetic (default double)
      {"precision", {"step", "counters"}, {}, {}},
      // the search family's peers and clouds (benchmarks/search_benchmark.cpp;
      // a sweep without them means sphnl, lattice, generated, warm)
      {"impl", {"search"}, {}, one_of({"sphnl", "nanoflann", "api", "api_visit"})},
      {"cloud", {"search"}, {}, one_of({"lattice", "random"})},
      {"memory_order", {"search"}, {}, one_of({"generated", "shuffled"})},
      {"call", {"search"}, {}, one_of({"warm", "first"})},
      // the lists' pages (a sweep without it means base, as before the axis;
      // default: what the library chooses on this machine, huge_pages_by_default)
      {"pages", {"search"}, {}, one_of({"base", "huge", "default"})},
      // what memory a first call finds (a sweep without it means as_found):
      // just freed by an untimed call of the same size, or left idle that
      // many seconds after it was freed
      {"freed_memory", {"search"}, {}, freed_memory_value},
      // the caches valgrind simulates for the counters kind (harness/valgrind.py)
      {"cache_model", {"counters"}, {"counters"}, cache_model_name},
      // processes of a distributed `sphnl run` under mpirun (the mpi kind,
      // experiments/mpi_runs.py): a launcher setting, not a config key
      {"ranks", {"mpi"}, {"mpi"}, positive_integer},
      // what the ranks' cell ranges balance (optional; default interactions)
      {"balance_by", {"mpi"}, {}, {}},
  };
  return table;
}

/// Sweep axes of the vocabulary before the run-config keys were used
/// everywhere, and what each is called now: named in the error, so that an old
/// experiment file says how to fix it.
const std::vector<std::pair<std::string, std::string>> kRenamedAxes = {
    {"n", "particles"}, {"order", "cell_order"}, {"ns", "list_steps"}, {"hcoef", "h_coefficient"}};

/// Fields of `protocol` (the measurement protocol of docs/MEASUREMENT.md).
struct ProtocolField {
  const char* name;
  bool integer;
};
const std::vector<ProtocolField> kProtocol = {{"min_rounds", true},
                                              {"max_rounds", true},
                                              {"reps_per_round", true},
                                              {"target_halfwidth_pct", false},
                                              {"budget_s", false}};

template <class T, class F>
std::string names(const std::vector<T>& v, F name_of) {
  std::string s;
  for (const auto& e : v) s += (s.empty() ? "" : ", ") + std::string(name_of(e));
  return s;
}
std::string join(const std::vector<std::string>& v) {
  return names(v, [](const std::string& s) { return s; });
}

class Checker {
 public:
  explicit Checker(const ParsedJson& doc) : doc_(doc) {}

  void error(const std::string& pointer, const std::string& key, const std::string& what) {
    errors_.push_back(doc_.where(pointer) + ": " + key + ": " + what);
  }

  bool expect(const std::string& ptr, const std::string& key, const json& v, bool ok, const std::string& wanted) {
    if (!ok) error(ptr, key, "is " + v.dump() + "; expected " + wanted);
    return ok;
  }

  /// An object {tiny|default|full: ...}; calls `each` for every size.
  void per_size(const std::string& ptr, const std::string& key, const json& v, bool all_sizes,
                const std::function<void(const std::string&, const std::string&, const json&)>& each) {
    if (!expect(ptr, key, v, v.is_object(), "an object with keys " + join(kSizes))) return;
    for (const auto& [size, value] : v.items()) {
      if (std::find(kSizes.begin(), kSizes.end(), size) == kSizes.end()) {
        error(ptr + "/" + size, key, "unknown size '" + size + "'; allowed: " + join(kSizes));
        continue;
      }
      each(ptr + "/" + size, key + "." + size, value);
    }
    if (all_sizes)
      for (const auto& size : kSizes)
        if (!v.contains(size)) error(ptr, key, "missing size '" + size + "' (every one of " + join(kSizes) + " is needed)");
  }

  void positive_int(const std::string& ptr, const std::string& key, const json& v) {
    expect(ptr, key, v, v.is_number_integer() && v.get<long>() >= 1, "an integer >= 1");
  }

  void sweep_values(const std::string& ptr, const std::string& key, const std::string& family, const json& sweep) {
    if (!expect(ptr, key, sweep, sweep.is_object(), "an object of axis: [values]")) return;
    for (const auto& [axis, values] : sweep.items()) {
      const std::string aptr = ptr + "/" + json_pointer_token(axis);
      const std::string akey = key + "." + axis;
      const auto it = std::find_if(axes().begin(), axes().end(), [&](const Axis& a) { return axis == a.name; });
      const bool in_family =
          it != axes().end() && std::find(it->families.begin(), it->families.end(), family) != it->families.end();
      const auto renamed = std::find_if(kRenamedAxes.begin(), kRenamedAxes.end(), [&](const auto& r) { return axis == r.first; });
      if (renamed != kRenamedAxes.end()) {
        error(aptr, key, "sweep axis '" + axis + "' was renamed to '" + renamed->second +
                             "' (sweep axes are the run-config keys of README \"Configuration\")");
        continue;
      }
      if (!in_family) {
        std::vector<std::string> allowed;
        for (const auto& a : axes())
          if (std::find(a.families.begin(), a.families.end(), family) != a.families.end()) allowed.push_back(a.name);
        error(aptr, key, "unknown sweep axis '" + axis + "' for benchmark '" + family + "'; allowed: " + join(allowed));
        continue;
      }
      if (!expect(aptr, akey, values, values.is_array() && !values.empty(), "a non-empty array of values")) continue;
      for (const auto& value : values) {
        std::string problem;
        if (it->check) {
          problem = it->check(value);
          if (!problem.empty()) problem = "value " + value.dump() + " is not allowed; expected " + problem;
        } else {
          try {
            config_from_json(json{{it->name, value}});
          } catch (const ConfigError& e) {
            problem = e.what();  // names the config key and its allowed values
          }
        }
        if (!problem.empty()) error(aptr, akey, problem);
      }
    }
    for (const auto& a : axes()) {
      const bool old_name_given = std::any_of(kRenamedAxes.begin(), kRenamedAxes.end(), [&](const auto& r) {
        return r.second == a.name && sweep.contains(r.first);  // already reported as renamed
      });
      if (std::find(a.required_in.begin(), a.required_in.end(), family) != a.required_in.end() &&
          !sweep.contains(a.name) && !old_name_given)
        error(ptr, key, std::string("missing sweep axis '") + a.name + "' (required for benchmark '" + family + "')");
    }
  }

  void protocol_fields(const std::string& ptr, const std::string& key, const json& v) {
    if (!expect(ptr, key, v, v.is_object(), "an object")) return;
    for (const auto& [field, value] : v.items()) {
      const std::string fptr = ptr + "/" + field, fkey = key + "." + field;
      const auto it = std::find_if(kProtocol.begin(), kProtocol.end(), [&](const ProtocolField& f) { return field == f.name; });
      if (it == kProtocol.end()) {
        error(fptr, key, "unknown key '" + field + "'; allowed: " + names(kProtocol, [](const ProtocolField& f) { return f.name; }));
        continue;
      }
      if (it->integer) positive_int(fptr, fkey, value);
      else expect(fptr, fkey, value, positive_number(value).empty(), "a number > 0");
    }
  }

  void protocol(const std::string& ptr, const json& v) {
    // Either one protocol for every size or one per size.
    const bool per = v.is_object() && !v.empty() &&
                     std::all_of(v.items().begin(), v.items().end(), [](const auto& kv) {
                       return std::find(kSizes.begin(), kSizes.end(), kv.key()) != kSizes.end();
                     });
    if (per) per_size(ptr, "protocol", v, false, [&](const auto& p, const auto& k, const json& x) { protocol_fields(p, k, x); });
    else protocol_fields(ptr, "protocol", v);
  }

  /// An array of objects with an id: `claims`, `explanations`.
  void claims(const std::string& ptr, const json& v, const std::string& what) {
    if (!expect(ptr, what, v, v.is_array(), "an array of objects with an 'id'")) return;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const json& c = v[i];
      const std::string key = what + "[" + std::to_string(i) + "]";
      if (!expect(ptr, key, c, c.is_object(), "an object with at least an 'id'")) continue;
      if (!c.contains("id") || !c["id"].is_string() || c["id"].get<std::string>().empty())
        error(ptr, key, "needs an 'id' (a non-empty string)");
    }
  }

  std::vector<std::string> run() {
    const json& d = doc_.value;
    if (!d.is_object()) {
      errors_.push_back(doc_.name + ": an experiment file must hold one JSON object");
      return errors_;
    }
    using Check = std::function<void(const std::string&, const json&)>;
    const auto string_key = [&](const char* k) {
      return Check([this, k](const std::string& p, const json& v) { expect(p, k, v, v.is_string(), "a string"); });
    };
    const auto text_key = [&](const char* k) {  // descriptive text, null when there is none
      return Check([this, k](const std::string& p, const json& v) { expect(p, k, v, v.is_string() || v.is_null(), "a string or null"); });
    };
    const std::string family = d.contains("benchmark") && d["benchmark"].is_string() ? d["benchmark"].get<std::string>() : "";
    const bool draws = d.contains("uses") && !d["uses"].is_null();
    // Every top-level key, with its check. Add a key here.
    const std::vector<std::pair<const char*, Check>> top = {
        {"id", string_key("id")},
        {"figure", text_key("figure")},
        {"title", text_key("title")},
        {"notes", text_key("notes")},
        {"metric", string_key("metric")},
        {"benchmark",
         [&](const std::string& p, const json& v) {
           expect(p, "benchmark", v,
                  v.is_string() && (family == "step" || family == "counters" || family == "cellindex" || family == "search" ||
                                     family == "mpi"),
                  "one of step, counters, cellindex, search, mpi");
         }},
        {"uses", [&](const std::string& p, const json& v) { expect(p, "uses", v, v.is_null() || v.is_string(), "null or an experiment id"); }},
        {"sweep",
         [&](const std::string& p, const json& v) {
           if (draws && v.is_object() && v.empty()) return;
           per_size(p, "sweep", v, !draws, [&](const auto& sp, const auto& k, const json& x) { sweep_values(sp, k, family, x); });
         }},
        {"window_steps",
         [&](const std::string& p, const json& v) {
           if (draws && v.is_object() && v.empty()) return;
           per_size(p, "window_steps", v, !draws, [&](const auto& sp, const auto& k, const json& x) { positive_int(sp, k, x); });
         }},
        {"repetitions",
         [&](const std::string& p, const json& v) {
           if (draws && v.is_object() && v.empty()) return;
           per_size(p, "repetitions", v, false, [&](const auto& sp, const auto& k, const json& x) { positive_int(sp, k, x); });
         }},
        {"protocol", [&](const std::string& p, const json& v) { protocol(p, v); }},
        // the mpi kind: sweep points with ranks x threads above this are left out
        {"max_cores", [&](const std::string& p, const json& v) { positive_int(p, "max_cores", v); }},
        {"claims", [&](const std::string& p, const json& v) { claims(p, v, "claims"); }},
        // hypotheses for the claims not reproduced, tested by this experiment (plots/explanations.py checks the rest)
        {"explanations", [&](const std::string& p, const json& v) { claims(p, v, "explanations"); }},
    };
    for (const auto& [key, value] : d.items()) {
      const auto it = std::find_if(top.begin(), top.end(), [&](const auto& t) { return key == t.first; });
      if (it == top.end()) {
        error("/" + json_pointer_token(key), "top level",
              "unknown key '" + key + "'; allowed: " + names(top, [](const auto& t) { return t.first; }));
        continue;
      }
      it->second("/" + key, value);
    }
    for (const char* required : {"id", "benchmark"})
      if (!d.contains(required)) errors_.push_back(doc_.name + ": missing top-level key '" + required + "'");
    if (!draws && !d.contains("sweep")) errors_.push_back(doc_.name + ": missing top-level key 'sweep' (or set 'uses')");
    if (!draws && (family == "step" || family == "counters" || family == "mpi") && !d.contains("window_steps"))
      errors_.push_back(doc_.name + ": missing top-level key 'window_steps' (steps timed per iteration, per size)");
    return errors_;
  }

 private:
  const ParsedJson& doc_;
  std::vector<std::string> errors_;
};

}  // namespace

std::vector<std::string> validate_experiment(const ParsedJson& doc) { return Checker(doc).run(); }

const std::vector<std::string>& benchmark_only_axes() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const auto& a : axes())
      if (a.check) v.emplace_back(a.name);
    return v;
  }();
  return names;
}

int freed_memory_idle_seconds(const std::string& value) {
  if (value == "as_found" || value == "just_freed") return 0;
  if (value.size() < 7 || value.rfind("idle_", 0) != 0 || value.back() != 's') return -1;
  const std::string digits = value.substr(5, value.size() - 6);
  if (digits.size() > 2 || digits[0] == '0' || digits.find_first_not_of("0123456789") != std::string::npos) return -1;
  const int seconds = std::stoi(digits);
  return seconds <= 60 ? seconds : -1;
}

json load_experiment(const std::string& path) {
  ParsedJson doc = read_json_strict(path);
  const auto errors = validate_experiment(doc);
  if (!errors.empty()) {
    std::string msg;
    for (const auto& e : errors) msg += (msg.empty() ? "" : "\n") + e;
    throw JsonFileError(msg);
  }
  return std::move(doc.value);
}

}  // namespace sphnl
