#include "neighbours_tool.hpp"

#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "sphnl/config.hpp"
#include "sphnl/memory_estimate.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"

namespace sphnl {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

/// Parses a whole field as a double; false when it is not a number.
bool parse_double(std::string_view s, double& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && end == s.data() + s.size();
}

std::vector<std::string_view> split_fields(std::string_view line, char sep) {
  std::vector<std::string_view> f;
  std::size_t from = 0;
  for (;;) {
    const std::size_t comma = line.find(sep, from);
    f.push_back(trim(line.substr(from, comma == std::string_view::npos ? std::string_view::npos : comma - from)));
    if (comma == std::string_view::npos) return f;
    from = comma + 1;
  }
}

/// Buffered output to `path` through a temporary file renamed on commit().
class AtomicFile {
 public:
  explicit AtomicFile(const std::string& path)
      : path_(path), tmp_(path + ".tmp." + std::to_string(::getpid())), f_(std::fopen(tmp_.c_str(), "wb")) {
    if (!f_) throw std::runtime_error("cannot write '" + tmp_ + "': " + std::strerror(errno) + " (check the --out/--pairs directory)");
    buf_.reserve(1 << 20);
  }
  ~AtomicFile() {  // not committed: nothing of it stays behind
    if (f_) std::fclose(f_);
    if (f_ || closed_) std::remove(tmp_.c_str());
  }
  void put(std::string_view s) {
    buf_.append(s);
    if (buf_.size() >= (1 << 20)) flush();
  }
  void put(std::uint64_t v) {
    char tmp[24];
    const auto r = std::to_chars(tmp, tmp + sizeof tmp, v);
    buf_.append(tmp, r.ptr);
  }
  /// Writes everything out and closes the temporary (still under its temporary name).
  void finish() {
    if (!f_) return;
    flush();
    const bool ok = std::fclose(f_) == 0;
    f_ = nullptr;
    if (!ok) throw std::runtime_error("cannot write '" + tmp_ + "': " + std::strerror(errno));
    closed_ = true;
  }
  void commit() {
    finish();
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0)
      throw std::runtime_error("cannot write '" + path_ + "': " + std::strerror(errno));
    closed_ = false;
  }

 private:
  void flush() {
    if (!buf_.empty() && std::fwrite(buf_.data(), 1, buf_.size(), f_) != buf_.size())
      throw std::runtime_error("cannot write '" + tmp_ + "': " + std::strerror(errno));
    buf_.clear();
  }
  std::string path_, tmp_;
  std::FILE* f_;
  bool closed_ = false;  // finished but not yet renamed
  std::string buf_;
};

const char* gridder_title(GridderKind g) {
  switch (g) {
    case GridderKind::A: return "sliding dynamic vector";
    case GridderKind::B: return "preconditioned dynamic vector";
    case GridderKind::C: return "static matrix";
    case GridderKind::D: return "linked list";
  }
  return "";
}

constexpr const char* kUsage =
    "usage: sphnl neighbours --input points.csv --radius R [--gridder A|B|C|D]\n"
    "           [--cell-order sort_x|sort_xy|sort_xyz|hilbert] [--reorder 0|1]\n"
    "           [--max-parts-in-cell M] --out counts.csv [--pairs pairs.csv] [--force-memory 1]\n"
    "Finds every pair of points closer than R (strictly). Input: CSV rows x,y,z (optional header).\n"
    "Writes index,count for every point in input order; --pairs writes every pair i<j once.\n"
    "The list entries are counted first; above the available memory it stops unless --force-memory 1.\n";

}  // namespace

/// The library's gridder C overflow message names `sphnl run`'s syntax;
/// this tool's option is --max-parts-in-cell.
std::string neighbours_syntax(std::string msg) {
  const std::string from = "the config key max_parts_in_cell (e.g. --set max_parts_in_cell=";
  if (const auto at = msg.find(from); at != std::string::npos)
    msg.replace(at, from.size(), "--max-parts-in-cell (e.g. --max-parts-in-cell ");
  return msg;
}

namespace {

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace

PointCloud parse_points_csv(std::string_view text, const std::string& name) {
  PointCloud pc;
  std::size_t line_no = 0, from = 0;
  bool header_allowed = true;
  // Comma-separated, or semicolon-separated as spreadsheets in many locales
  // write it ("0;0;0"): the first non-empty line decides for the file.
  char sep = ',';
  {
    const std::size_t first = text.find_first_not_of(" \t\r\n");
    const std::string_view head = first == std::string_view::npos ? std::string_view{} : text.substr(first, text.find('\n', first) - first);
    if (head.find(',') == std::string_view::npos && head.find(';') != std::string_view::npos) sep = ';';
  }
  while (from < text.size()) {
    std::size_t nl = text.find('\n', from);
    if (nl == std::string_view::npos) nl = text.size();
    const std::string_view line = trim(text.substr(from, nl - from));
    from = nl + 1;
    ++line_no;
    if (line.empty()) continue;
    const auto fields = split_fields(line, sep);
    double v[3] = {0, 0, 0};
    bool numeric[3] = {false, false, false};
    int numeric_count = 0;
    for (std::size_t k = 0; k < std::min<std::size_t>(3, fields.size()); ++k) {
      numeric[k] = parse_double(fields[k], v[k]);
      numeric_count += numeric[k];
    }
    const std::string where = name + ":" + std::to_string(line_no) + ": ";
    if (header_allowed) {
      header_allowed = false;
      if (numeric_count == 0) continue;  // a header such as "x,y,z"
    }
    if (fields.size() != 3)
      throw PointFileError(where + "expected 3 columns (x,y,z), found " + std::to_string(fields.size()) +
                           " (columns are separated by '" + sep + "', as on the first line)");
    for (int k = 0; k < 3; ++k) {
      if (!numeric[k])
        throw PointFileError(where + "field " + std::to_string(k + 1) + " '" + std::string(fields[k]) +
                             "' is not a number (rows must be x,y,z decimal numbers)");
      if (!std::isfinite(v[k]))
        throw PointFileError(where + "field " + std::to_string(k + 1) + " '" + std::string(fields[k]) +
                             "' is not finite (NaN and infinity are not coordinates)");
    }
    pc.x.push_back(v[0]);
    pc.y.push_back(v[1]);
    pc.z.push_back(v[2]);
  }
  if (pc.size() == 0)
    throw PointFileError(name + ":" + std::to_string(std::max<std::size_t>(line_no, 1)) +
                         ": no points (the file is empty or holds only a header); give rows x,y,z");
  return pc;
}

PointCloud read_points_csv(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw PointFileError(path + ": cannot open (" + std::strerror(errno) + "); check --input");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_points_csv(ss.str(), path);
}

int neighbours_main(int argc, char** argv) {
  try {
    std::map<std::string, std::string> opt;
    const char* known[] = {"input", "radius", "gridder", "cell-order", "reorder", "max-parts-in-cell", "out", "pairs",
                           "force-memory"};
    for (int a = 1; a < argc; ++a) {
      std::string arg = argv[a];
      if (arg == "-h" || arg == "--help") {
        std::fputs(kUsage, stdout);
        return 0;
      }
      if (arg.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + arg + "'");
      arg = arg.substr(2);
      std::string value;
      if (const auto eq = arg.find('='); eq != std::string::npos) {
        value = arg.substr(eq + 1);
        arg = arg.substr(0, eq);
      } else {
        if (a + 1 >= argc) throw UsageError("option --" + arg + " needs a value");
        value = argv[++a];
      }
      if (std::find(std::begin(known), std::end(known), arg) == std::end(known))
        throw UsageError("unknown option --" + arg);
      opt[arg] = value;
    }
    for (const char* req : {"input", "radius", "out"})
      if (!opt.count(req)) throw UsageError(std::string("missing --") + req);

    bool force_memory = false;
    if (opt.count("force-memory")) {
      const std::string& f = opt["force-memory"];
      if (f != "0" && f != "1") throw UsageError("--force-memory '" + f + "': allowed 0, 1");
      force_memory = f == "1";
    }
    SearchOptions so;
    double radius = 0;
    if (!parse_double(opt["radius"], radius) || !(radius > 0) || !std::isfinite(radius))
      throw UsageError("--radius '" + opt["radius"] + "': must be a positive finite number");
    if (opt.count("gridder")) {
      const std::string& g = opt["gridder"];
      if (g.size() != 1 || g[0] < 'A' || g[0] > 'D') throw UsageError("--gridder '" + g + "': allowed A, B, C, D");
      so.gridder = static_cast<GridderKind>(g[0] - 'A');
    }
    if (opt.count("cell-order")) {
      const std::string& o = opt["cell-order"];
      bool found = false;
      for (auto k : {CellOrderKind::sort_x, CellOrderKind::sort_xy, CellOrderKind::sort_xyz, CellOrderKind::hilbert})
        if (o == to_string(k)) { so.order = k; found = true; }
      if (!found) throw UsageError("--cell-order '" + o + "': allowed sort_x, sort_xy, sort_xyz, hilbert");
    }
    if (opt.count("reorder")) {
      const std::string& r = opt["reorder"];
      if (r != "0" && r != "1" && r != "true" && r != "false") throw UsageError("--reorder '" + r + "': allowed 0, 1");
      so.reorder = r == "1" || r == "true";
    }
    if (opt.count("max-parts-in-cell")) {
      const std::string& m = opt["max-parts-in-cell"];
      int v = 0;
      const auto [end, ec] = std::from_chars(m.data(), m.data() + m.size(), v);
      if (ec != std::errc() || end != m.data() + m.size() || v < 0)
        throw UsageError("--max-parts-in-cell '" + m + "': must be an integer >= 0 (0 = twice the fullest cell)");
      so.max_parts_in_cell = v;
    }

    const PointCloud pc = read_points_csv(opt["input"]);
    if (!force_memory) {
      // The entries are counted before the lists are allocated: first a cheap
      // upper bound, the exact count only when the bound does not fit.
      const double available = available_memory_bytes();
      const double per_entry = 4, room = available - estimate_search_memory(pc.size(), 0).bytes;
      const std::uint64_t limit = room > 0 ? static_cast<std::uint64_t>(room / per_entry) : 0;
      std::uint64_t entries = count_neighbour_entries(pc.x, pc.y, pc.z, radius, limit, /*exact=*/false);
      if (available > 0 && entries > limit) entries = count_neighbour_entries(pc.x, pc.y, pc.z, radius, limit);
      check_memory(estimate_search_memory(pc.size(), entries),
                   "this search (" + std::string(entries > limit ? "at least " : "") + std::to_string(entries) +
                       " list entries, counted before allocating)",
                   "--force-memory 1");
    }
    NeighbourSearch search(so);
    NeighbourLists lists;
    try {
      search.run(pc.x, pc.y, pc.z, radius, lists);
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(neighbours_syntax(e.what()));
    }
    const std::size_t n = pc.size();

    // Both files are complete before either is renamed into place: a failed
    // --pairs write must not leave a counts file of this run behind.
    std::vector<std::uint32_t> counts;
    lists.counts(counts);
    AtomicFile counts_file(opt["out"]);
    counts_file.put("index,count\n");
    for (std::size_t i = 0; i < n; ++i) {
      counts_file.put(i);
      counts_file.put(",");
      counts_file.put(counts[i]);
      counts_file.put("\n");
    }
    counts_file.finish();
    if (opt.count("pairs")) {  // every pair once, i < j, sorted
      std::vector<std::uint32_t> row_of(n), js;
      for (std::size_t r = 0; r < n; ++r) row_of[lists.point(r)] = static_cast<std::uint32_t>(r);
      AtomicFile f(opt["pairs"]);
      f.put("i,j\n");
      for (std::size_t i = 0; i < n; ++i) {
        js.clear();
        for (std::uint32_t j : lists.row(row_of[i]))
          if (j > i) js.push_back(j);
        std::sort(js.begin(), js.end());
        for (std::uint32_t j : js) {
          f.put(i);
          f.put(",");
          f.put(j);
          f.put("\n");
        }
      }
      f.commit();
      try {
        counts_file.commit();
      } catch (...) {
        std::remove(opt["pairs"].c_str());
        throw;
      }
    } else {
      counts_file.commit();
    }

    const SearchTimes& t = search.times();
    const double entries = static_cast<double>(lists.num_entries());
    // In use, not capacity: the list buffer grows in steps and keeps slack.
    const std::size_t list_bytes = static_cast<std::size_t>(lists.num_entries()) * sizeof(std::uint32_t) +
                                   (lists.num_rows() + 1) * sizeof(std::uint64_t) + lists.num_rows() * sizeof(std::uint32_t);
    const std::size_t bytes = search.bytes() + list_bytes;
    std::printf("points              %zu\n", n);
    std::printf("radius              %.15g\n", radius);
    std::printf("gridder             %s (%s)\n", to_string(so.gridder), gridder_title(so.gridder));
    std::printf("cell order          %s\n", to_string(so.order));
    std::printf("reorder             %d\n", so.reorder ? 1 : 0);
    std::printf("cells               %d x %d x %d of side %.6g (%u keys)\n", search.grid().n[0], search.grid().n[1],
                search.grid().n[2], search.grid().cell_size, search.order().num_keys());
    std::printf("pairs found         %.0f\n", entries / 2);
    std::printf("list entries        %.0f (%.2f per point)\n", entries, n ? entries / static_cast<double>(n) : 0.0);
    std::printf("build time          %.6f s (cells, keys, gridder, reordering)\n", t.build);
    std::printf("search time         %.6f s (distance tests, writing the lists)\n", t.search);
    std::printf("bytes used          %zu (search structures %zu + lists %zu; list capacity %zu)\n", bytes,
                search.bytes(), list_bytes, lists.bytes());
    std::printf("entries per second  %.4g (build + search), %.4g (search only)\n", entries / (t.build + t.search),
                entries / t.search);
    return 0;
  } catch (const UsageError& e) {
    std::fprintf(stderr, "sphnl neighbours: %s\n%s", e.what(), kUsage);
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sphnl neighbours: %s\n", e.what());
    return 1;
  }
}

}  // namespace sphnl
