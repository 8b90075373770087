#include "sphnl/output.hpp"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <numeric>
#include <stdexcept>
#include <system_error>

#include <nlohmann/json.hpp>

namespace sphnl {

namespace fs = std::filesystem;

void write_file_atomically(const fs::path& path, const std::function<void(std::ostream&)>& write) {
  fs::path tmp = path;
  tmp += ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out)
      throw std::runtime_error("cannot create '" + tmp.string() + "': " + std::strerror(errno) +
                               "; check that the output directory exists and is writable");
    write(out);
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw std::runtime_error("error writing '" + tmp.string() + "' (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignore;
    fs::remove(tmp, ignore);
    throw std::runtime_error("cannot rename '" + tmp.string() + "' to '" + path.string() + "': " + ec.message());
  }
}

void ensure_writable_directory(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw std::runtime_error("output directory '" + dir.string() + "' cannot be created" +
                             (ec ? ": " + ec.message() : std::string(": a file of that name exists")) +
                             "; give --out a directory you can write to");
  // Creating the directory is not enough (read-only mounts, permissions): try a file.
  const fs::path probe = dir / (".sphnl-write-test." + std::to_string(::getpid()));
  {
    std::ofstream out(probe);
    if (!out)
      throw std::runtime_error("output directory '" + dir.string() + "' is not writable: " + std::strerror(errno) +
                               "; give --out a directory you can write to");
  }
  fs::remove(probe, ec);
}

std::vector<std::uint32_t> id_order(const ParticleSet& ps, std::size_t count) {
  std::vector<std::uint32_t> order(std::min(count, ps.size()));
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return ps.id[a] < ps.id[b]; });
  return order;
}

const char* type_name(ParticleType t) {
  switch (t) {
    case ParticleType::fluid: return "fluid";
    case ParticleType::boundary: return "boundary";
    case ParticleType::out: return "out";
  }
  return "?";
}

namespace {

/// One DataArray of the appended section: its XML header and its bytes.
struct AppendedArray {
  std::string name, type;
  int components = 1;
  std::vector<char> bytes;
};

template <class T>
AppendedArray make_array(std::string name, std::string type, int components, const std::vector<T>& values) {
  AppendedArray a{std::move(name), std::move(type), components, {}};
  a.bytes.resize(values.size() * sizeof(T));
  if (!values.empty()) std::memcpy(a.bytes.data(), values.data(), a.bytes.size());
  return a;
}

void write_data_array(std::ostream& out, const AppendedArray& a, std::uint64_t offset) {
  out << "        <DataArray type=\"" << a.type << "\" Name=\"" << a.name << "\"";
  if (a.components != 1) out << " NumberOfComponents=\"" << a.components << "\"";
  out << " format=\"appended\" offset=\"" << offset << "\"/>\n";
}

}  // namespace

void write_vtu(const fs::path& path, const ParticleSet& ps, double time, std::size_t count) {
  static_assert(std::endian::native == std::endian::little, "the VTU writer declares LittleEndian");
  const std::vector<std::uint32_t> order = id_order(ps, count);
  const std::size_t n = order.size();
  std::vector<double> points(3 * n), velocity(3 * n), density(n), pressure(n);
  std::vector<std::int32_t> type(n), id(n);
  std::vector<std::int64_t> connectivity(n), offsets(n);
  std::vector<std::uint8_t> cell_types(n, 1);  // VTK_VERTEX
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t i = order[k];
    points[3 * k] = ps.x[i]; points[3 * k + 1] = ps.y[i]; points[3 * k + 2] = ps.z[i];
    velocity[3 * k] = ps.vx[i]; velocity[3 * k + 1] = ps.vy[i]; velocity[3 * k + 2] = ps.vz[i];
    density[k] = ps.rho[i];
    pressure[k] = ps.pressure[i];
    type[k] = static_cast<std::int32_t>(ps.type[i]);
    id[k] = static_cast<std::int32_t>(ps.id[i]);
    connectivity[k] = static_cast<std::int64_t>(k);
    offsets[k] = static_cast<std::int64_t>(k + 1);
  }
  const std::vector<double> time_value{time};
  const AppendedArray field = make_array("TimeValue", "Float64", 1, time_value);
  const AppendedArray pts = make_array("Points", "Float64", 3, points);
  const std::vector<AppendedArray> point_data = {
      make_array("velocity", "Float64", 3, velocity), make_array("density", "Float64", 1, density),
      make_array("pressure", "Float64", 1, pressure), make_array("type", "Int32", 1, type),
      make_array("id", "Int32", 1, id)};
  const std::vector<AppendedArray> cells = {make_array("connectivity", "Int64", 1, connectivity),
                                            make_array("offsets", "Int64", 1, offsets),
                                            make_array("types", "UInt8", 1, cell_types)};
  write_file_atomically(path, [&](std::ostream& out) {
    std::uint64_t offset = 0;
    auto next = [&](const AppendedArray& a) {
      const std::uint64_t o = offset;
      offset += sizeof(std::uint64_t) + a.bytes.size();
      return o;
    };
    out << "<?xml version=\"1.0\"?>\n"
        << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
        << "  <UnstructuredGrid>\n"
        << "    <FieldData>\n";
    write_data_array(out, field, next(field));
    out << "    </FieldData>\n"
        << "    <Piece NumberOfPoints=\"" << n << "\" NumberOfCells=\"" << n << "\">\n"
        << "      <PointData Scalars=\"density\" Vectors=\"velocity\">\n";
    for (const auto& a : point_data) write_data_array(out, a, next(a));
    out << "      </PointData>\n      <Points>\n";
    write_data_array(out, pts, next(pts));
    out << "      </Points>\n      <Cells>\n";
    for (const auto& a : cells) write_data_array(out, a, next(a));
    out << "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _";
    auto emit = [&](const AppendedArray& a) {
      const std::uint64_t size = a.bytes.size();
      out.write(reinterpret_cast<const char*>(&size), sizeof size);
      out.write(a.bytes.data(), static_cast<std::streamsize>(a.bytes.size()));
    };
    // Same order as the offsets above.
    emit(field);
    for (const auto& a : point_data) emit(a);
    emit(pts);
    for (const auto& a : cells) emit(a);
    out << "\n  </AppendedData>\n</VTKFile>\n";
  });
}

void write_pvtu(const fs::path& path, const std::vector<std::string>& pieces) {
  write_file_atomically(path, [&](std::ostream& out) {
    // The arrays of write_vtu, by name, type and components (the pieces hold the data).
    out << "<?xml version=\"1.0\"?>\n"
        << "<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
        << "  <PUnstructuredGrid GhostLevel=\"0\">\n"
        << "    <PPointData Scalars=\"density\" Vectors=\"velocity\">\n"
        << "      <PDataArray type=\"Float64\" Name=\"velocity\" NumberOfComponents=\"3\"/>\n"
        << "      <PDataArray type=\"Float64\" Name=\"density\" NumberOfComponents=\"1\"/>\n"
        << "      <PDataArray type=\"Float64\" Name=\"pressure\" NumberOfComponents=\"1\"/>\n"
        << "      <PDataArray type=\"Int32\" Name=\"type\" NumberOfComponents=\"1\"/>\n"
        << "      <PDataArray type=\"Int32\" Name=\"id\" NumberOfComponents=\"1\"/>\n"
        << "    </PPointData>\n"
        << "    <PPoints>\n      <PDataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\"/>\n    </PPoints>\n";
    for (const auto& piece : pieces) out << "    <Piece Source=\"" << piece << "\"/>\n";
    out << "  </PUnstructuredGrid>\n</VTKFile>\n";
  });
}

void write_csv(const fs::path& path, const ParticleSet& ps) {
  const std::vector<std::uint32_t> order = id_order(ps);
  write_file_atomically(path, [&](std::ostream& out) {
    out << "id,type,x,y,z,vx,vy,vz,rho,p\n";
    char line[512];
    for (const std::uint32_t i : order) {
      // A fluid particle that left the domain is still fluid: the columns stay fixed.
      const char* type = ps.type[i] == ParticleType::boundary ? "boundary" : "fluid";
      const int len = std::snprintf(line, sizeof line, "%u,%s,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g\n",
                                    ps.id[i], type, ps.x[i], ps.y[i], ps.z[i], ps.vx[i], ps.vy[i], ps.vz[i],
                                    ps.rho[i], ps.pressure[i]);
      out.write(line, len);
    }
  });
}

void write_pvd(const fs::path& path, const std::vector<SnapshotEntry>& entries) {
  write_file_atomically(path, [&](std::ostream& out) {
    out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\">\n  <Collection>\n";
    char line[1024];
    for (const auto& e : entries) {
      std::snprintf(line, sizeof line, "    <DataSet timestep=\"%.17g\" file=\"%s\"/>\n", e.time, e.vtu.c_str());
      out << line;
    }
    out << "  </Collection>\n</VTKFile>\n";
  });
}

void write_json(const fs::path& path, const nlohmann::json& j) {
  write_file_atomically(path, [&](std::ostream& out) { out << j.dump(2) << '\n'; });
}

}  // namespace sphnl
