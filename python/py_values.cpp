// Grid, Mesh and Program: the value types every part of the module returns.
#include "core/error.hpp"
#include "python/py_types.hpp"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>
#include <cstdlib>
#include <unistd.h>

namespace vmsim::python {

namespace fs = std::filesystem;

TempDir::TempDir() {
  std::string tmpl = (fs::temp_directory_path() / "vmsim-py-XXXXXX").string();
  if (!::mkdtemp(tmpl.data()))
    throw core::Error(tmpl + ": cannot create a temporary directory for the job's overrides");
  path = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path, ec);
}

namespace {

// A 1-D view of `n` doubles at `data`, kept alive by `owner`.
template <class T>
py::array_t<T> view(const T* data, Eigen::Index n, py::handle owner) {
  return py::array_t<T>({static_cast<py::ssize_t>(n)}, {static_cast<py::ssize_t>(sizeof(T))}, data, owner);
}

core::HeightGrid grid_from(py::array_t<double, py::array::c_style | py::array::forcecast> z, double dx_mm,
                           std::optional<double> dy_mm, double x0_mm, double y0_mm,
                           std::optional<py::array_t<bool, py::array::c_style | py::array::forcecast>> mask) {
  if (z.ndim() != 2) throw core::Error("Grid: z_mm must be a 2-D array (rows along y, columns along x)");
  const double dy = dy_mm.value_or(dx_mm);
  if (!(dx_mm > 0) || !(dy > 0) || !std::isfinite(dx_mm) || !std::isfinite(dy))
    throw core::Error("Grid: dx_mm and dy_mm must be finite and > 0");
  core::HeightGrid g;
  g.x0_mm = x0_mm, g.y0_mm = y0_mm, g.dx_mm = dx_mm, g.dy_mm = dy;
  const Eigen::Index ny = z.shape(0), nx = z.shape(1);
  g.z_mm = Eigen::Map<const core::HeightArray>(z.data(), ny, nx);
  if (mask) {
    if (mask->ndim() != 2 || mask->shape(0) != ny || mask->shape(1) != nx)
      throw core::Error("Grid: mask must have z_mm's shape");
    const bool* valid = mask->data();
    for (Eigen::Index k = 0; k < ny * nx; ++k)
      if (!valid[k]) g.z_mm.data()[k] = std::numeric_limits<double>::quiet_NaN();
  }
  return g;
}

}  // namespace

void bind_values(py::module_& m) {
  py::class_<core::HeightGrid, GridPtr>(m, "Grid", py::dynamic_attr(), R"(A height grid: z over a regular x/y grid (mm).

z_mm is a 2-D float64 array of shape (ny, nx), row j at y = y0_mm + j*dy_mm, column i at x = x0_mm + i*dx_mm
(x varies fastest in memory, as in X3P files); invalid points (not measured, outside the part) are NaN and
mask is False there. z_mm is a view of the grid's own memory (no copy).

Grid(z_mm, dx_mm, dy_mm=None, x0_mm=0, y0_mm=0, mask=None) builds one from an array (copied; mask False
marks invalid points).)")
      .def(py::init(&grid_from), py::arg("z_mm"), py::arg("dx_mm"), py::arg("dy_mm") = py::none(),
           py::arg("x0_mm") = 0.0, py::arg("y0_mm") = 0.0, py::arg("mask") = py::none())
      .def_property_readonly(
          "z_mm", [](core::HeightGrid& g) -> core::HeightArray& { return g.z_mm; },
          py::return_value_policy::reference_internal,
          "heights (mm), shape (ny, nx), NaN where invalid; a view of the grid")
      .def_property_readonly(
          "mask",
          [](const core::HeightGrid& g) { return Eigen::Array<bool, -1, -1, Eigen::RowMajor>(g.z_mm.isFinite()); },
          "True where the height is valid (a new array)")
      .def_readwrite("x0_mm", &core::HeightGrid::x0_mm, "x of column 0 (mm)")
      .def_readwrite("y0_mm", &core::HeightGrid::y0_mm, "y of row 0 (mm)")
      .def_readwrite("dx_mm", &core::HeightGrid::dx_mm, "spacing along x (mm)")
      .def_readwrite("dy_mm", &core::HeightGrid::dy_mm, "spacing along y (mm)")
      .def_property_readonly("nx", &core::HeightGrid::nx)
      .def_property_readonly("ny", &core::HeightGrid::ny)
      .def_property_readonly("shape", [](const core::HeightGrid& g) { return py::make_tuple(g.ny(), g.nx()); })
      .def_property_readonly(
          "x_mm",
          [](const core::HeightGrid& g) {
            return Eigen::ArrayXd(Eigen::ArrayXd::LinSpaced(g.nx(), 0, g.nx() - 1) * g.dx_mm + g.x0_mm);
          },
          "x of each column (mm)")
      .def_property_readonly(
          "y_mm",
          [](const core::HeightGrid& g) {
            return Eigen::ArrayXd(Eigen::ArrayXd::LinSpaced(g.ny(), 0, g.ny() - 1) * g.dy_mm + g.y0_mm);
          },
          "y of each row (mm)")
      .def(
          "copy", [](const core::HeightGrid& g) { return std::make_shared<core::HeightGrid>(g); }, "a deep copy")
      .def("__repr__", [](const core::HeightGrid& g) {
        return "<vmsim.Grid " + std::to_string(g.ny()) + "x" + std::to_string(g.nx()) + " at " +
               std::to_string(g.dx_mm) + " x " + std::to_string(g.dy_mm) + " mm>";
      });

  py::class_<core::TriangleMesh, std::shared_ptr<core::TriangleMesh>>(m, "Mesh", R"(A triangle mesh (mm).

vertices_mm: (n, 3) float64; triangles: (m, 3) int32 vertex indices, counter-clockwise seen from outside;
point_data: {name: (n,) float64} per-vertex scalars (e.g. "deviation_mm"). Views of the mesh (no copy).)")
      .def_property_readonly(
          "vertices_mm", [](core::TriangleMesh & t) -> auto& { return t.vertices_mm; },
          py::return_value_policy::reference_internal)
      .def_property_readonly(
          "triangles", [](core::TriangleMesh & t) -> auto& { return t.triangles; },
          py::return_value_policy::reference_internal)
      .def_property_readonly("point_data",
                             [](py::object self) {
                               auto& t = self.cast<core::TriangleMesh&>();
                               py::dict d;
                               for (const auto& [name, v] : t.point_data)
                                 d[py::str(name)] = view(v.data(), v.size(), self);
                               return d;
                             })
      .def("__repr__", [](const core::TriangleMesh& t) {
        return "<vmsim.Mesh " + std::to_string(t.vertices_mm.rows()) + " vertices, " +
               std::to_string(t.triangles.rows()) + " triangles>";
      });

  py::class_<core::ToolPath, std::shared_ptr<core::ToolPath>>(m, "Program", R"(A program's moves in the workpiece frame
(what the G-code, Sinumerik or APT/CL reader gives), as arrays with one row per move (copies: the reader's moves
are records).

start, end: (n, 6) X Y Z in mm, A B C in rad; kind: "line" | "arc"; rapid: bool; feed_mm_per_min (0 for rapids;
deg/min for moves of rotary axes only); inverse_time_per_min (G93 moves, else 0); centre_mm (n, 2) arc centre in
the arc plane's coordinates; plane: "XY" | "ZX" | "YZ"; rotation (arcs: > 0 counter-clockwise, |r|-1 extra turns);
tool_number; tool_length_offset_mm; source_line (1-based line of the program that made the move).)")
      .def("__len__", [](const core::ToolPath& p) { return p.moves.size(); })
      .def_readonly("source_path", &core::ToolPath::source_path)
      .def_readonly("warnings", &core::ToolPath::warnings)
      .def_readonly("tool_diameter_mm", &core::ToolPath::tool_diameter_mm)
      .def_property_readonly("initial_position",
                             [](const core::ToolPath& p) { return Eigen::VectorXd(p.initial_position); })
      .def_property_readonly("start",
                             [](const core::ToolPath& p) {
                               Eigen::Matrix<double, -1, 6, Eigen::RowMajor> a(
                                   static_cast<Eigen::Index>(p.moves.size()), 6);
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a.row(static_cast<Eigen::Index>(k)) = p.moves[k].start.transpose();
                               return a;
                             })
      .def_property_readonly("end",
                             [](const core::ToolPath& p) {
                               Eigen::Matrix<double, -1, 6, Eigen::RowMajor> a(
                                   static_cast<Eigen::Index>(p.moves.size()), 6);
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a.row(static_cast<Eigen::Index>(k)) = p.moves[k].end.transpose();
                               return a;
                             })
      .def_property_readonly("centre_mm",
                             [](const core::ToolPath& p) {
                               Eigen::Matrix<double, -1, 2, Eigen::RowMajor> a(
                                   static_cast<Eigen::Index>(p.moves.size()), 2);
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a.row(static_cast<Eigen::Index>(k)) = p.moves[k].centre_mm.transpose();
                               return a;
                             })
      .def_property_readonly("kind",
                             [](const core::ToolPath& p) {
                               py::list l;
                               for (const core::Move& mv : p.moves)
                                 l.append(mv.kind == core::MotionKind::Arc ? "arc" : "line");
                               return py::module_::import("numpy").attr("array")(l);
                             })
      .def_property_readonly(
          "plane",
          [](const core::ToolPath& p) {
            py::list l;
            for (const core::Move& mv : p.moves)
              l.append(mv.plane == core::ArcPlane::XY ? "XY" : mv.plane == core::ArcPlane::ZX ? "ZX" : "YZ");
            return py::module_::import("numpy").attr("array")(l);
          })
      .def_property_readonly("rapid",
                             [](const core::ToolPath& p) {
                               Eigen::Array<bool, -1, 1> a(static_cast<Eigen::Index>(p.moves.size()));
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a[static_cast<Eigen::Index>(k)] = p.moves[k].rapid;
                               return a;
                             })
      .def_property_readonly("feed_mm_per_min",
                             [](const core::ToolPath& p) {
                               Eigen::ArrayXd a(static_cast<Eigen::Index>(p.moves.size()));
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a[static_cast<Eigen::Index>(k)] = p.moves[k].feed_mm_per_min;
                               return a;
                             })
      .def_property_readonly("inverse_time_per_min",
                             [](const core::ToolPath& p) {
                               Eigen::ArrayXd a(static_cast<Eigen::Index>(p.moves.size()));
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a[static_cast<Eigen::Index>(k)] = p.moves[k].feed_mode == core::FeedMode::InverseTime
                                                                       ? p.moves[k].inverse_time_per_min
                                                                       : 0.0;
                               return a;
                             })
      .def_property_readonly("tool_length_offset_mm",
                             [](const core::ToolPath& p) {
                               Eigen::ArrayXd a(static_cast<Eigen::Index>(p.moves.size()));
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a[static_cast<Eigen::Index>(k)] = p.moves[k].tool_length_offset_mm;
                               return a;
                             })
      .def_property_readonly("rotation",
                             [](const core::ToolPath& p) {
                               Eigen::ArrayXi a(static_cast<Eigen::Index>(p.moves.size()));
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a[static_cast<Eigen::Index>(k)] = p.moves[k].rotation;
                               return a;
                             })
      .def_property_readonly("tool_number",
                             [](const core::ToolPath& p) {
                               Eigen::ArrayXi a(static_cast<Eigen::Index>(p.moves.size()));
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a[static_cast<Eigen::Index>(k)] = p.moves[k].tool_number;
                               return a;
                             })
      .def_property_readonly("source_line",
                             [](const core::ToolPath& p) {
                               Eigen::ArrayXi a(static_cast<Eigen::Index>(p.moves.size()));
                               for (std::size_t k = 0; k < p.moves.size(); ++k)
                                 a[static_cast<Eigen::Index>(k)] = p.moves[k].source_line;
                               return a;
                             })
      .def("__repr__", [](const core::ToolPath& p) {
        return "<vmsim.Program " + p.source_path + ": " + std::to_string(p.moves.size()) + " moves>";
      });
}

// Used by the job's results (a 1-D view kept alive by its owner).
py::array_t<double> view_of(const Eigen::ArrayXd& a, py::handle owner) { return view(a.data(), a.size(), owner); }
py::array_t<int> view_of(const Eigen::ArrayXi& a, py::handle owner) { return view(a.data(), a.size(), owner); }

}  // namespace vmsim::python
