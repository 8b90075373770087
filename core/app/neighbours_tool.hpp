#pragma once
// `sphnl neighbours`: neighbour search on any point cloud with a chosen
// gridder, cell order and reorder setting (docs/DESIGN.md, "The sphnl tool"):
//
//   sphnl neighbours --input points.csv --radius R [--gridder A|B|C|D]
//       [--cell-order sort_x|sort_xy|sort_xyz|hilbert] [--reorder 0|1]
//       [--max-parts-in-cell M] --out counts.csv [--pairs pairs.csv]
//
// Writes the neighbour count (points closer than R, strictly, itself
// excluded) of every input point in input order, and with --pairs every pair
// once as i < j in input indices, sorted. Both files are written to a
// temporary name and renamed, so a reader never sees half a file.
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace sphnl {

struct PointCloud {
  std::vector<double> x, y, z;
  std::size_t size() const { return x.size(); }
};

/// Thrown for malformed point files; the message starts with "FILE:LINE:".
struct PointFileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Parses CSV text of `x,y,z` rows (or `x;y;z`, decided by the first line; an optional header line of non-numeric
/// names, blank lines ignored, CRLF accepted). Rejects non-numeric fields, a
/// column count other than 3, NaN or infinite values and an empty point set,
/// naming the line. `name` is used in messages.
PointCloud parse_points_csv(std::string_view text, const std::string& name);
/// Reads and parses a file (see parse_points_csv).
PointCloud read_points_csv(const std::string& path);

/// A library error message in this tool's syntax (gridder C's overflow
/// names --max-parts-in-cell, not `sphnl run`'s --set max_parts_in_cell=).
std::string neighbours_syntax(std::string msg);

/// Entry point of `sphnl neighbours`; argv[0] is "neighbours". Returns the
/// exit code (0 ok, 1 bad input or failure, 2 bad usage); errors go to stderr.
int neighbours_main(int argc, char** argv);

}  // namespace sphnl
