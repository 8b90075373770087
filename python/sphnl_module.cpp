// The `sphnl` Python module: sphnl.neighbours(points, radius, ...) -> (offsets,
// indices), a thin binding of sphnl::Search (sphnl/search.hpp).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>

#include "sphnl/search.hpp"

namespace py = pybind11;

namespace {

sphnl::GridderKind parse_gridder(const std::string& s) {
  if (s == "A") return sphnl::GridderKind::A;
  if (s == "B") return sphnl::GridderKind::B;
  if (s == "C") return sphnl::GridderKind::C;
  if (s == "D") return sphnl::GridderKind::D;
  throw py::value_error("gridder=" + s + ": allowed values are 'A', 'B', 'C', 'D'");
}

sphnl::CellOrderKind parse_order(const std::string& s) {
  if (s == "sort_x") return sphnl::CellOrderKind::sort_x;
  if (s == "sort_xy") return sphnl::CellOrderKind::sort_xy;
  if (s == "sort_xyz") return sphnl::CellOrderKind::sort_xyz;
  if (s == "hilbert") return sphnl::CellOrderKind::hilbert;
  throw py::value_error("cell_order=" + s + ": allowed values are 'sort_x', 'sort_xy', 'sort_xyz', 'hilbert'");
}

template <class T>
void build_from(sphnl::Search& search, const py::array& points) {
  const auto* data = static_cast<const T*>(points.data());
  const std::size_t n = static_cast<std::size_t>(points.shape(0));
  py::gil_scoped_release release;
  search.build_interleaved(std::span<const T>(data, 3 * n));
}

py::tuple neighbours(const py::array& points, double radius, const std::string& gridder, const std::string& cell_order,
                     bool reorder, bool half, int threads) {
  if (points.ndim() != 2 || points.shape(1) != 3)
    throw py::value_error("points must have shape (n, 3), got ndim " + std::to_string(points.ndim()) +
                          (points.ndim() >= 2 ? " with " + std::to_string(points.shape(1)) + " columns" : std::string()));
  const bool f64 = py::isinstance<py::array_t<double>>(points);
  const bool f32 = py::isinstance<py::array_t<float>>(points);
  if (!f64 && !f32)
    throw py::value_error("points must be float64 or float32, got dtype " + py::str(points.dtype()).cast<std::string>() +
                          " (convert with points.astype(numpy.float64))");
  // A non-contiguous view (a slice, a transpose) is copied once into a
  // C-contiguous array; a C-contiguous one is read in place.
  py::array contiguous = points;
  if (!(points.flags() & py::array::c_style))
    contiguous = f64 ? py::array(py::array_t<double, py::array::c_style | py::array::forcecast>(points))
                     : py::array(py::array_t<float, py::array::c_style | py::array::forcecast>(points));
  sphnl::Search::Options options;
  options.gridder = parse_gridder(gridder);
  options.cell_order = parse_order(cell_order);
  options.reorder = reorder;
  options.threads = threads;
  try {
    sphnl::Search search(radius, options);
    if (f64)
      build_from<double>(search, contiguous);
    else
      build_from<float>(search, contiguous);
    const sphnl::Rows kind = half ? sphnl::Rows::half : sphnl::Rows::full;
    const std::size_t n = search.size();
    py::array_t<std::int64_t> offsets(static_cast<py::ssize_t>(n + 1));
    py::array_t<std::uint32_t> indices(static_cast<py::ssize_t>(search.num_entries(kind)));
    {
      std::span<std::int64_t> o(offsets.mutable_data(), n + 1);
      std::span<std::uint32_t> i(indices.mutable_data(), static_cast<std::size_t>(indices.size()));
      py::gil_scoped_release release;
      search.rows_into(kind, o, i);
    }
    return py::make_tuple(offsets, indices);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(e.what());
  } catch (const std::length_error& e) {
    throw py::value_error(e.what());
  }
}

}  // namespace

PYBIND11_MODULE(sphnl, m) {
  m.doc() = "sphnl: cell-grid neighbour search (Dominguez et al. 2011) for 3-D point clouds";
  m.def("neighbours", &neighbours, py::arg("points"), py::arg("radius"), py::arg("gridder") = "B",
        py::arg("cell_order") = "sort_x", py::arg("reorder") = true, py::arg("half") = false, py::arg("threads") = 1,
        R"doc(Neighbour lists of a point cloud.

points: (n, 3) numpy array of float64 or float32. A C-contiguous array is read
    in place (its rows are split into the x/y/z columns the search reads);
    any other layout is first copied once into a C-contiguous array.
radius: neighbours are strictly closer than radius (> 0, finite).
gridder: 'A', 'B', 'C' or 'D' (paper section 2.3).
cell_order: 'sort_x', 'sort_xy', 'sort_xyz' or 'hilbert' (section 2.4).
reorder: search on coordinates copied into cell order; results do not change.
half: False: row i holds every neighbour j of i; True: only those with j > i.
threads: OpenMP threads the search and the copy into the output split the
    rows over (>= 1); the result does not depend on it.

Returns (offsets, indices): offsets int64 of length n + 1, indices uint32; the
neighbours of point i are indices[offsets[i]:offsets[i + 1]], sorted ascending,
indices of input rows. Raises ValueError naming the problem for a bad shape,
dtype, NaN/inf coordinate, radius or threads.)doc");
}
