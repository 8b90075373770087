#include "sphnl/config.hpp"

#include <array>
#include <cmath>
#include <functional>
#include <sstream>

#include <nlohmann/json.hpp>

namespace sphnl {

using nlohmann::json;

namespace {
constexpr std::array kGridderNames{"A", "B", "C", "D"};
constexpr std::array kOrderNames{"sort_x", "sort_xy", "sort_xyz", "hilbert"};
constexpr std::array kListNames{"cll", "vlc", "vlx"};
constexpr std::array kLatticeNames{"bcc", "cubic"};
constexpr std::array kPairLoopNames{"gather", "direct", "masked"};
constexpr std::array kSlidingNames{"occupied", "shift_all"};
constexpr std::array kInitialOrderNames{"generated", "shuffled"};
constexpr std::array kInnerOrderNames{"index", "morton"};
constexpr std::array kOnOffNames{"on", "off"};
constexpr std::array kThreadUpdateNames{"private", "phased"};
constexpr std::array kThreadSplitNames{"fluid", "interactions", "dynamic"};
constexpr std::array kPrecisionNames{"double", "mixed"};
constexpr std::array kBalanceNames{"interactions", "particles"};
constexpr std::array kSnapshotPiecesNames{"gathered", "per_rank"};

template <class Names>
std::string join(const Names& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + std::string(n);
  return s;
}

[[noreturn]] void bad(const std::string& key, const json& v, const std::string& allowed) {
  throw ConfigError("config key '" + key + "': invalid value " + v.dump() + "; allowed: " + allowed);
}

double get_number(const std::string& key, const json& v, double lo, double hi, bool lo_open) {
  if (!v.is_number()) bad(key, v, "a number");
  const double d = v.get<double>();
  if (!std::isfinite(d) || d > hi || (lo_open ? d <= lo : d < lo)) {
    std::ostringstream os;
    os << "a number in " << (lo_open ? "(" : "[") << lo << ", " << hi << "]";
    bad(key, v, os.str());
  }
  return d;
}

long get_integer(const std::string& key, const json& v, long lo, long hi) {
  if (!v.is_number_integer() && !(v.is_number_float() && std::floor(v.get<double>()) == v.get<double>()))
    bad(key, v, "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  const double d = v.get<double>();
  if (d < static_cast<double>(lo) || d > static_cast<double>(hi))
    bad(key, v, "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return static_cast<long>(d);
}

bool get_bool(const std::string& key, const json& v) {
  if (v.is_boolean()) return v.get<bool>();
  if (v.is_number_integer() && (v.get<long>() == 0 || v.get<long>() == 1)) return v.get<long>() == 1;
  bad(key, v, "true or false (or 1 / 0)");
}

template <class E, class Names>
E get_enum(const std::string& key, const json& v, const Names& names) {
  if (v.is_string())
    for (std::size_t i = 0; i < names.size(); ++i)
      if (v.get<std::string>() == names[i]) return static_cast<E>(i);
  bad(key, v, join(names));
}

/// One entry per key: how to read it into a RunConfig and how to write it back.
struct Key {
  const char* name;
  std::function<void(RunConfig&, const json&)> read;
  std::function<json(const RunConfig&)> write;
};

const std::vector<Key>& key_table() {
  static const std::vector<Key> table = {
      {"particles", [](RunConfig& c, const json& v) { c.particles = get_integer("particles", v, 100, 100'000'000); },
       [](const RunConfig& c) { return json(c.particles); }},
      {"dx", [](RunConfig& c, const json& v) { c.dx = get_number("dx", v, 0, 1.0, true); },
       [](const RunConfig& c) { return json(c.dx); }},
      {"steps", [](RunConfig& c, const json& v) { c.steps = get_integer("steps", v, 1, 1'000'000'000); },
       [](const RunConfig& c) { return json(c.steps); }},
      {"end_time", [](RunConfig& c, const json& v) { c.end_time = get_number("end_time", v, 0, 1e4, true); },
       [](const RunConfig& c) { return json(c.end_time); }},
      {"output_interval", [](RunConfig& c, const json& v) { c.output_interval = get_number("output_interval", v, 0, 1e4, false); },
       [](const RunConfig& c) { return json(c.output_interval); }},
      {"snapshot_pieces", [](RunConfig& c, const json& v) { c.snapshot_pieces = get_enum<SnapshotPieces>("snapshot_pieces", v, kSnapshotPiecesNames); },
       [](const RunConfig& c) { return json(to_string(c.snapshot_pieces)); }},
      {"h_coefficient", [](RunConfig& c, const json& v) { c.h_coefficient = get_number("h_coefficient", v, 0.3, 3.0, false); },
       [](const RunConfig& c) { return json(c.h_coefficient); }},
      {"cfl", [](RunConfig& c, const json& v) { c.cfl = get_number("cfl", v, 0, 1.0, true); },
       [](const RunConfig& c) { return json(c.cfl); }},
      {"euler_every", [](RunConfig& c, const json& v) { c.euler_every = static_cast<int>(get_integer("euler_every", v, 1, 1'000'000)); },
       [](const RunConfig& c) { return json(c.euler_every); }},
      {"sound_speed_coef", [](RunConfig& c, const json& v) { c.sound_speed_coef = get_number("sound_speed_coef", v, 0, 1e3, true); },
       [](const RunConfig& c) { return json(c.sound_speed_coef); }},
      {"clamp_boundary_density", [](RunConfig& c, const json& v) { c.clamp_boundary_density = get_bool("clamp_boundary_density", v); },
       [](const RunConfig& c) { return json(c.clamp_boundary_density); }},
      {"viscosity_alpha", [](RunConfig& c, const json& v) { c.viscosity_alpha = get_number("viscosity_alpha", v, 0, 10, false); },
       [](const RunConfig& c) { return json(c.viscosity_alpha); }},
      {"xsph_epsilon", [](RunConfig& c, const json& v) { c.xsph_epsilon = get_number("xsph_epsilon", v, 0, 1, false); },
       [](const RunConfig& c) { return json(c.xsph_epsilon); }},
      {"lattice", [](RunConfig& c, const json& v) { c.lattice = get_enum<Lattice>("lattice", v, kLatticeNames); },
       [](const RunConfig& c) { return json(to_string(c.lattice)); }},
      {"max_lost_fraction", [](RunConfig& c, const json& v) { c.max_lost_fraction = get_number("max_lost_fraction", v, 0, 1, false); },
       [](const RunConfig& c) { return json(c.max_lost_fraction); }},
      {"threads", [](RunConfig& c, const json& v) { c.threads = static_cast<int>(get_integer("threads", v, 1, 1024)); },
       [](const RunConfig& c) { return json(c.threads); }},
      {"thread_updates", [](RunConfig& c, const json& v) { c.thread_updates = get_enum<ThreadUpdates>("thread_updates", v, kThreadUpdateNames); },
       [](const RunConfig& c) { return json(to_string(c.thread_updates)); }},
      {"thread_split", [](RunConfig& c, const json& v) { c.thread_split = get_enum<ThreadSplit>("thread_split", v, kThreadSplitNames); },
       [](const RunConfig& c) { return json(to_string(c.thread_split)); }},
      {"progress", [](RunConfig& c, const json& v) { c.progress = get_bool("progress", v); },
       [](const RunConfig& c) { return json(c.progress); }},
      {"gridder", [](RunConfig& c, const json& v) { c.gridder = get_enum<GridderKind>("gridder", v, kGridderNames); },
       [](const RunConfig& c) { return json(to_string(c.gridder)); }},
      {"cell_order", [](RunConfig& c, const json& v) { c.cell_order = get_enum<CellOrderKind>("cell_order", v, kOrderNames); },
       [](const RunConfig& c) { return json(to_string(c.cell_order)); }},
      {"reorder", [](RunConfig& c, const json& v) { c.reorder = get_bool("reorder", v); },
       [](const RunConfig& c) { return json(c.reorder); }},
      {"inner_order", [](RunConfig& c, const json& v) { c.inner_order = get_enum<InnerOrder>("inner_order", v, kInnerOrderNames); },
       [](const RunConfig& c) { return json(to_string(c.inner_order)); }},
      {"reorder_every", [](RunConfig& c, const json& v) { c.reorder_every = static_cast<int>(get_integer("reorder_every", v, 1, 1'000'000)); },
       [](const RunConfig& c) { return json(c.reorder_every); }},
      {"max_parts_in_cell", [](RunConfig& c, const json& v) { c.max_parts_in_cell = static_cast<int>(get_integer("max_parts_in_cell", v, 0, 1'000'000)); },
       [](const RunConfig& c) { return json(c.max_parts_in_cell); }},
      {"list", [](RunConfig& c, const json& v) { c.list = get_enum<ListKind>("list", v, kListNames); },
       [](const RunConfig& c) { return json(to_string(c.list)); }},
      {"list_steps", [](RunConfig& c, const json& v) { c.list_steps = static_cast<int>(get_integer("list_steps", v, 1, 100'000)); },
       [](const RunConfig& c) { return json(c.list_steps); }},
      {"skin_factor", [](RunConfig& c, const json& v) { c.skin_factor = get_number("skin_factor", v, 0, 100, false); },
       [](const RunConfig& c) { return json(c.effective_skin_factor()); }},
      {"kgc", [](RunConfig& c, const json& v) { c.kgc = get_bool("kgc", v); },
       [](const RunConfig& c) { return json(c.kgc); }},
      {"verify_lists", [](RunConfig& c, const json& v) { c.verify_lists = get_bool("verify_lists", v); },
       [](const RunConfig& c) { return json(c.verify_lists); }},
      {"precision", [](RunConfig& c, const json& v) { c.precision = get_enum<Precision>("precision", v, kPrecisionNames); },
       [](const RunConfig& c) { return json(to_string(c.precision)); }},
      {"pair_loop", [](RunConfig& c, const json& v) { c.pair_loop = get_enum<PairLoopKind>("pair_loop", v, kPairLoopNames); },
       [](const RunConfig& c) { return json(to_string(c.pair_loop)); }},
      {"simd", [](RunConfig& c, const json& v) { c.simd = get_enum<int>("simd", v, kOnOffNames) == 0; },
       [](const RunConfig& c) { return json(c.simd ? "on" : "off"); }},
      {"skip_boundary_pairs", [](RunConfig& c, const json& v) { c.skip_boundary_pairs = get_bool("skip_boundary_pairs", v); },
       [](const RunConfig& c) { return json(c.skip_boundary_pairs); }},
      {"gridder_a_variant", [](RunConfig& c, const json& v) { c.gridder_a_variant = get_enum<SlidingVariant>("gridder_a_variant", v, kSlidingNames); },
       [](const RunConfig& c) { return json(to_string(c.gridder_a_variant)); }},
      {"initial_order", [](RunConfig& c, const json& v) { c.initial_order = get_enum<InitialOrder>("initial_order", v, kInitialOrderNames); },
       [](const RunConfig& c) { return json(to_string(c.initial_order)); }},
      {"extra_loops", [](RunConfig& c, const json& v) { c.extra_loops = static_cast<int>(get_integer("extra_loops", v, 0, 3)); },
       [](const RunConfig& c) { return json(c.extra_loops); }},
      {"rebalance_threshold", [](RunConfig& c, const json& v) { c.rebalance_threshold = get_number("rebalance_threshold", v, 0, 1e3, false); },
       [](const RunConfig& c) { return json(c.rebalance_threshold); }},
      {"balance_by", [](RunConfig& c, const json& v) { c.balance_by = get_enum<BalanceBy>("balance_by", v, kBalanceNames); },
       [](const RunConfig& c) { return json(to_string(c.balance_by)); }},
  };
  return table;
}
}  // namespace

const char* to_string(Lattice l) { return kLatticeNames[static_cast<int>(l)]; }
const char* to_string(SnapshotPieces p) { return kSnapshotPiecesNames[static_cast<int>(p)]; }

std::vector<std::string> config_keys() {
  std::vector<std::string> keys;
  for (const auto& k : key_table()) keys.emplace_back(k.name);
  return keys;
}

RunConfig config_from_json(const json& j) {
  if (!j.is_object()) throw ConfigError("configuration must be a JSON object of key: value pairs");
  RunConfig c;
  for (const auto& [key, value] : j.items()) {
    const Key* found = nullptr;
    for (const auto& k : key_table())
      if (key == k.name) found = &k;
    if (!found) throw ConfigError("unknown config key '" + key + "'; known keys: " + join(config_keys()));
    found->read(c, value);
  }
  if (j.contains("particles") && j.contains("dx"))
    throw ConfigError("config keys 'particles' and 'dx' both set; give one (a particle count, or the lattice spacing in m)");
  if (j.contains("steps") && j.contains("end_time"))
    throw ConfigError("config keys 'steps' and 'end_time' both set; give one (a step count, or simulated seconds)");
  if (j.contains("particles")) c.dx = 0;
  if (j.contains("end_time")) c.steps = 0;
  return c;
}

json config_to_json(const RunConfig& c) {
  json j = json::object();
  for (const auto& k : key_table()) j[k.name] = k.write(c);
  // Of each pair of alternatives only the one in use, so that the echo can be
  // fed back as a config file.
  j.erase(c.dx > 0 ? "particles" : "dx");
  j.erase(c.steps > 0 ? "end_time" : "steps");
  return j;
}

void apply_override(json& j, const std::string& key_value) {
  const auto eq = key_value.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ConfigError("--set expects key=value, got '" + key_value + "'");
  const std::string key = key_value.substr(0, eq), text = key_value.substr(eq + 1);
  json value = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded()) value = text;
  // Overriding one of a pair of alternative keys replaces the other.
  if (key == "particles") j.erase("dx");
  if (key == "dx") j.erase("particles");
  if (key == "steps") j.erase("end_time");
  if (key == "end_time") j.erase("steps");
  j[key] = value;
}

}  // namespace sphnl
