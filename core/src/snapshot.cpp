#include "sphnl/snapshot.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>

namespace sphnl {

namespace {
constexpr char kMagic[8] = {'S', 'P', 'H', 'N', 'L', 'S', 'N', 'P'};
constexpr std::uint32_t kVersion = 1;

std::uint64_t fnv1a(const std::string& bytes) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : bytes) { h ^= c; h *= 1099511628211ull; }
  return h;
}

struct Writer {
  std::string buf;
  template <class T> void put(const T& v) { buf.append(reinterpret_cast<const char*>(&v), sizeof(T)); }
  template <class T> void put_array(const std::vector<T>& v) {
    buf.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
};

struct Reader {
  const std::string& buf;
  const std::string& path;
  std::size_t pos = 0;
  void need(std::size_t n) const {
    if (pos + n > buf.size()) throw std::runtime_error("snapshot '" + path + "' is truncated; delete it to have it rebuilt");
  }
  template <class T> T get() { need(sizeof(T)); T v; std::memcpy(&v, buf.data() + pos, sizeof(T)); pos += sizeof(T); return v; }
  template <class T> void get_array(std::vector<T>& v, std::size_t n) {
    need(n * sizeof(T)); v.resize(n); std::memcpy(v.data(), buf.data() + pos, n * sizeof(T)); pos += n * sizeof(T);
  }
};

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open snapshot '" + path + "'");
  return std::string(std::istreambuf_iterator<char>(in), {});
}

template <class F>
void for_each_array(ParticleSet& ps, F&& f) {
  for (auto* v : {&ps.x, &ps.y, &ps.z, &ps.vx, &ps.vy, &ps.vz, &ps.rho, &ps.vx_prev, &ps.vy_prev, &ps.vz_prev,
                  &ps.rho_prev, &ps.mass})
    f(*v);
}

/// Parses a whole snapshot; fills `ps` when given.
SnapshotInfo parse(const std::string& path, const std::string& buf, ParticleSet* ps) {
  Reader r{buf, path};
  r.need(sizeof(kMagic));
  if (std::memcmp(buf.data(), kMagic, sizeof(kMagic)) != 0) throw std::runtime_error("'" + path + "' is not an sphnl snapshot");
  r.pos = sizeof(kMagic);
  if (r.get<std::uint32_t>() != kVersion) throw std::runtime_error("snapshot '" + path + "' has another format version; delete it to have it rebuilt");
  if (buf.size() < sizeof(std::uint64_t) + r.pos) throw std::runtime_error("snapshot '" + path + "' is truncated");
  const std::size_t body = buf.size() - sizeof(std::uint64_t);
  std::uint64_t stored;
  std::memcpy(&stored, buf.data() + body, sizeof(stored));
  if (stored != fnv1a(buf.substr(0, body)))
    throw std::runtime_error("snapshot '" + path + "' fails its checksum (corrupt or truncated); delete it to have it rebuilt");
  SnapshotInfo info;
  info.checksum = stored;
  info.n = r.get<std::uint64_t>();
  info.dx = r.get<double>(); info.h = r.get<double>(); info.time = r.get<double>();
  info.steps = r.get<long>(); info.lost = r.get<std::uint64_t>();
  const auto len = r.get<std::uint64_t>();
  r.need(len);
  info.config_json = buf.substr(r.pos, len);
  r.pos += len;
  if (!ps) return info;
  ParticleSet& p = *ps;
  for_each_array(p, [&](std::vector<double>& v) { r.get_array(v, info.n); });
  std::vector<std::uint8_t> type;
  r.get_array(type, info.n);
  p.type.resize(info.n);
  for (std::size_t i = 0; i < info.n; ++i) p.type[i] = static_cast<ParticleType>(type[i]);
  r.get_array(p.id, info.n);
  return info;
}
}  // namespace

void save_snapshot(const std::string& path, const Simulation& sim) {
  // Arrays are stored in id order so a snapshot does not depend on reordering.
  const ParticleSet& src = sim.particles();
  const std::size_t n = src.size();
  std::vector<std::uint32_t> by_id(n);
  for (std::size_t i = 0; i < n; ++i) by_id[src.id[i]] = static_cast<std::uint32_t>(i);
  ParticleSet ps = src;
  std::vector<double> s64;
  std::vector<std::uint32_t> s32;
  ps.permute(by_id, s64, s32);

  Writer w;
  w.buf.append(kMagic, sizeof(kMagic));
  w.put(kVersion);
  w.put(static_cast<std::uint64_t>(n));
  w.put(sim.case_info().dx); w.put(sim.case_info().h); w.put(sim.time());
  w.put(sim.steps_done()); w.put(static_cast<std::uint64_t>(sim.lost()));
  const std::string cfg = config_to_json(sim.config()).dump();
  w.put(static_cast<std::uint64_t>(cfg.size()));
  w.buf += cfg;
  for_each_array(ps, [&](std::vector<double>& v) { w.put_array(v); });
  for (auto t : ps.type) w.put(static_cast<std::uint8_t>(t));
  w.put_array(ps.id);
  w.put(fnv1a(w.buf));

  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot write snapshot '" + tmp + "' (check that the directory exists and is writable)");
    out.write(w.buf.data(), static_cast<std::streamsize>(w.buf.size()));
    if (!out) { std::remove(tmp.c_str()); throw std::runtime_error("short write on snapshot '" + tmp + "'"); }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw std::runtime_error("cannot rename '" + tmp + "' to '" + path + "'");
  }
}

SnapshotInfo read_snapshot_info(const std::string& path) { return parse(path, read_file(path), nullptr); }

SnapshotInfo load_snapshot(const std::string& path, Simulation& sim) {
  const std::string buf = read_file(path);
  ParticleSet ps;
  const SnapshotInfo info = parse(path, buf, &ps);
  if (info.n != sim.particles().size())
    throw std::runtime_error("snapshot '" + path + "' holds " + std::to_string(info.n) + " particles but the simulation has " +
                             std::to_string(sim.particles().size()) + "; it was made for another case or size");
  sim.restore(ps, info.time, info.steps, static_cast<std::size_t>(info.lost));
  return info;
}

bool snapshot_config_matches(const std::string& stored_json, const RunConfig& wanted) {
  const nlohmann::json stored = nlohmann::json::parse(stored_json);
  if (!stored.is_object()) throw std::runtime_error("a snapshot's config is not a JSON object: " + stored_json);
  const nlohmann::json want = config_to_json(wanted), defaults = config_to_json(RunConfig{});
  for (const auto& [key, value] : stored.items())
    if (!want.contains(key) || want.at(key) != value) return false;
  for (const auto& [key, value] : want.items())
    if (!stored.contains(key) && defaults.at(key) != value) return false;
  return true;
}

}  // namespace sphnl
