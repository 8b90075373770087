#pragma once
// Output files of a run: snapshots (.vtu for ParaView, CSV) and JSON. Every
// file is written to a temporary name in the same directory and renamed into
// place, so an interrupted run never leaves a truncated file under a final name.
#include <cstdint>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "sphnl/particles.hpp"

namespace sphnl {

/// Writes a file through `write` into `path.tmp.<pid>` and renames it to
/// `path` (atomic on POSIX within one file system). Throws std::runtime_error
/// naming the path when the file cannot be written; the temporary is removed.
void write_file_atomically(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write);

/// Creates `dir` (and parents) and checks that a file can be created in it.
/// Throws std::runtime_error naming the directory and the reason otherwise.
void ensure_writable_directory(const std::filesystem::path& dir);

/// Memory indices of the first `count` particles (all by default) sorted by
/// ParticleSet::id (outputs are reported in id order whatever the reordering
/// did to memory order).
std::vector<std::uint32_t> id_order(const ParticleSet& ps, std::size_t count = SIZE_MAX);

/// Name of a particle type in outputs: "fluid", "boundary" or "out".
const char* type_name(ParticleType t);

/// VTK XML UnstructuredGrid, one VTK_VERTEX cell per particle, raw appended
/// binary (little endian, UInt64 headers). PointData: velocity (3 components),
/// density, pressure, type (Int32: 0 fluid, 1 boundary, 2 out), id (Int32).
/// `time` is stored as the TimeValue field data. `count`: only the first
/// `count` particles (a rank's own, not the ghosts after them).
void write_vtu(const std::filesystem::path& path, const ParticleSet& ps, double time, std::size_t count = SIZE_MAX);

/// VTK XML PUnstructuredGrid naming the .vtu `pieces` (paths relative to the
/// .pvtu's folder) that write_vtu wrote, one per rank: ParaView reads them as
/// one data set.
void write_pvtu(const std::filesystem::path& path, const std::vector<std::string>& pieces);

/// CSV with columns id,type,x,y,z,vx,vy,vz,rho,p in id order; `type` is
/// `fluid` or `boundary` (fluid particles that left the domain are `fluid`).
void write_csv(const std::filesystem::path& path, const ParticleSet& ps);

/// One entry of a ParaView collection (.pvd): a snapshot file and its time.
struct SnapshotEntry {
  long step = 0;
  double time = 0;
  std::string vtu, csv;  // paths relative to the output directory
};
/// ParaView collection file listing the .vtu snapshots with their times, so
/// ParaView opens the run as one time series.
void write_pvd(const std::filesystem::path& path, const std::vector<SnapshotEntry>& entries);

/// Pretty-printed JSON (indent 2) with a trailing newline.
void write_json(const std::filesystem::path& path, const nlohmann::json& j);

}  // namespace sphnl
