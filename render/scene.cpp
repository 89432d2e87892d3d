// Part pictures: geometry to VTK polydata (height grids directly, with their own normals; meshes through
// vtkPolyDataNormals), a camera framed tightly on what is drawn, a raking key light, and the annotations (caption,
// colour scale in um, scale bar) in a background layer around the scene's viewport.
#include "render/scene.hpp"
#include "core/units.hpp"

#include "core/error.hpp"
#include "render/colormap.hpp"
#include "render/detail.hpp"
#include "render/fxaa.hpp"
#include "render/isolines.hpp"

#include <vtkActor.h>
#include <vtkActor2D.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkContourFilter.h>
#include <vtkFloatArray.h>
#include <vtkImageActor.h>
#include <vtkImageData.h>
#include <vtkImageSliceMapper.h>
#include <vtkLight.h>
#include <vtkLookupTable.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataMapper2D.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkProperty2D.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkSmartPointer.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>
#include <vtkTypeInt32Array.h>
#include <vtkUnsignedCharArray.h>

#include <Eigen/Geometry>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::render {

namespace {

using core::units::kPi;
constexpr double kDeg = kPi / 180.0;

// What is drawn: the surface (with its deviation scalars in um when coloured) and, for grids, its side walls.
struct Geometry {
  vtkSmartPointer<vtkPolyData> surface, walls;
  double bounds[6] = {0, 0, 0, 0, 0, 0};  // drawn (exaggerated) coordinates
  std::vector<double> deviation_um;       // the coloured values, for the limits
  double z_base_mm = 0, exaggeration = 1;
  // Height grids coloured by deviation: the drawn nodes as a rectilinear grid (row-major, j * nx + i), for the
  // iso-lines; NaN where a node is not drawn or has no deviation.
  std::vector<double> node_x_mm, node_y_mm;
  std::vector<float> node_deviation_um, node_z_mm;
  // A grid built without its triangles and normals (a flat map meant to be drawn as an image): the drawn nodes'
  // point ids (-1 where none), row-major, `nodes_across` wide, for add_grid_cells should the triangles be needed.
  std::vector<std::int32_t> pending_node_ids;
  Eigen::Index nodes_across = 0;
};

void check_view(const View& v, const char* what) {
  if (!(v.vertical_exaggeration > 0) || !std::isfinite(v.vertical_exaggeration) || v.vertical_exaggeration > 1e4)
    throw core::Error(fmt::format("{}: vertical exaggeration {} is not in (0, 10000]", what, v.vertical_exaggeration));
  if (!(v.mark_magnification > 0) || !std::isfinite(v.mark_magnification) || v.mark_magnification > 1e5)
    throw core::Error(fmt::format("{}: mark magnification {} is not in (0, 100000]", what, v.mark_magnification));
  if (v.region && !(v.region->x_max_mm > v.region->x_min_mm && v.region->y_max_mm > v.region->y_min_mm))
    throw core::Error(fmt::format("{}: the region x {}..{} y {}..{} mm is empty", what, v.region->x_min_mm,
                                  v.region->x_max_mm, v.region->y_min_mm, v.region->y_max_mm));
}

vtkSmartPointer<vtkTypeInt32Array> int32_array(std::vector<std::int32_t>& v) {
  auto a = vtkSmartPointer<vtkTypeInt32Array>::New();
  a->SetNumberOfValues(static_cast<vtkIdType>(v.size()));
  std::copy(v.begin(), v.end(), a->GetPointer(0));
  return a;
}

vtkSmartPointer<vtkCellArray> cells_of(std::vector<std::int32_t>& offsets, std::vector<std::int32_t>& conn) {
  auto cells = vtkSmartPointer<vtkCellArray>::New();
  cells->SetData(int32_array(offsets), int32_array(conn));  // 32-bit ids: half the memory of vtkIdType
  return cells;
}

void update_bounds(Geometry& g) {
  double b[6] = {std::numeric_limits<double>::max(), -std::numeric_limits<double>::max(),
                 std::numeric_limits<double>::max(), -std::numeric_limits<double>::max(),
                 std::numeric_limits<double>::max(), -std::numeric_limits<double>::max()};
  for (vtkPolyData* pd : {g.surface.Get(), g.walls.Get()}) {
    if (!pd || pd->GetNumberOfPoints() == 0) continue;
    const double* pb = pd->GetBounds();
    for (int i = 0; i < 3; ++i)
      b[2 * i] = std::min(b[2 * i], pb[2 * i]), b[2 * i + 1] = std::max(b[2 * i + 1], pb[2 * i + 1]);
  }
  std::copy(b, b + 6, g.bounds);
}

// ---- height grid ----------------------------------------------------------------------------------------------

// The nodes drawn along one axis of the window [lo, hi]: every `stride`-th, and always the last so the drawn extent
// stays the window's.
std::vector<Eigen::Index> drawn_nodes(Eigen::Index lo, Eigen::Index hi, Eigen::Index stride) {
  std::vector<Eigen::Index> v;
  for (Eigen::Index i = lo; i < hi; i += stride) v.push_back(i);
  v.push_back(hi);
  return v;
}

// Okabe and Ito's qualitative palette (without black), then the grey of uncut stock.
constexpr unsigned char kCategoryRgb[7][3] = {{230, 159, 0}, {86, 180, 233}, {0, 158, 115},  {240, 228, 66},
                                              {0, 114, 178}, {213, 94, 0},   {204, 121, 167}};
constexpr unsigned char kNoCategoryRgb[3] = {150, 150, 150};
const unsigned char* category_rgb(int k) { return k < 0 ? kNoCategoryRgb : kCategoryRgb[k % 7]; }

// Two triangles per cell of four valid nodes, one where exactly three are valid (edges of holes stay close); `id` the
// drawn nodes' point ids (-1: not drawn), row-major, nx wide.
vtkSmartPointer<vtkCellArray> grid_cells(const std::vector<std::int32_t>& id, Eigen::Index nx, Eigen::Index ny) {
  std::vector<std::int32_t> offsets, conn;
  offsets.reserve(static_cast<std::size_t>(2 * nx * ny + 1));
  conn.reserve(static_cast<std::size_t>(6 * nx * ny));
  offsets.push_back(0);
  auto tri = [&](std::int32_t a, std::int32_t b, std::int32_t c) {
    conn.insert(conn.end(), {a, b, c});
    offsets.push_back(static_cast<std::int32_t>(conn.size()));
  };
  for (Eigen::Index j = 0; j + 1 < ny; ++j)
    for (Eigen::Index i = 0; i + 1 < nx; ++i) {
      const std::int32_t a = id[static_cast<std::size_t>(j * nx + i)], b = id[static_cast<std::size_t>(j * nx + i + 1)];
      const std::int32_t c = id[static_cast<std::size_t>((j + 1) * nx + i + 1)],
                         d = id[static_cast<std::size_t>((j + 1) * nx + i)];
      const int valid = (a >= 0) + (b >= 0) + (c >= 0) + (d >= 0);
      if (valid == 4) {
        tri(a, b, c);
        tri(a, c, d);
      } else if (valid == 3) {
        if (a < 0)
          tri(b, c, d);
        else if (b < 0)
          tri(a, c, d);
        else if (c < 0)
          tri(a, b, d);
        else
          tri(a, b, c);
      }
    }
  return cells_of(offsets, conn);
}

// The triangles of a grid built without them (Geometry::pending_node_ids), added to its surface.
void add_grid_cells(Geometry& g) {
  if (g.pending_node_ids.empty()) return;
  const auto ny = static_cast<Eigen::Index>(g.pending_node_ids.size()) / g.nodes_across;
  g.surface->SetPolys(grid_cells(g.pending_node_ids, g.nodes_across, ny));
  g.pending_node_ids.clear();
}

// `with_cells` false: the surface gets its points and scalars but neither triangles nor normals (a flat map drawn as
// an image needs neither; add_grid_cells adds the triangles later if it is drawn with them after all).
Geometry grid_geometry(const core::HeightGrid& s, const core::HeightGrid* dev, const View& view, bool coloured,
                       Eigen::Index max_nodes_across, const CategoryColours* categories = nullptr,
                       bool with_cells = true) {
  if (categories && (categories->index.rows() != s.ny() || categories->index.cols() != s.nx()))
    throw core::Error(fmt::format("render_part: the categories ({}x{}) are not the surface's grid ({}x{})",
                                  categories->index.cols(), categories->index.rows(), s.nx(), s.ny()));
  if (s.nx() < 2 || s.ny() < 2) throw core::Error("render_part: the height grid has fewer than 2 x 2 nodes");
  if (!(s.dx_mm > 0) || !(s.dy_mm > 0)) throw core::Error("render_part: the height grid's spacing is not positive");
  const bool magnified = view.mark_magnification != 1.0;
  if (coloured || magnified) {
    if (!dev)
      throw core::Error(std::string("render_part: ") + (coloured ? "deviation colours" : "a mark magnification") +
                        " asked for, but no deviation grid given");
    if (dev->nx() != s.nx() || dev->ny() != s.ny() || std::abs(dev->x0_mm - s.x0_mm) > 1e-9 ||
        std::abs(dev->y0_mm - s.y0_mm) > 1e-9 || std::abs(dev->dx_mm - s.dx_mm) > 1e-12 ||
        std::abs(dev->dy_mm - s.dy_mm) > 1e-12)
      throw core::Error(
          fmt::format("render_part: the deviation grid ({}x{}) is not the surface's grid ({}x{}, same "
                      "origin and spacing)",
                      dev->nx(), dev->ny(), s.nx(), s.ny()));
  }
  // Index window of the region (one node of margin so the cut edge lies on or outside the region).
  Eigen::Index i0 = 0, i1 = s.nx() - 1, j0 = 0, j1 = s.ny() - 1;
  if (view.region) {
    const Region& r = *view.region;
    i0 = std::max<Eigen::Index>(0, static_cast<Eigen::Index>(std::floor((r.x_min_mm - s.x0_mm) / s.dx_mm)));
    i1 = std::min<Eigen::Index>(s.nx() - 1, static_cast<Eigen::Index>(std::ceil((r.x_max_mm - s.x0_mm) / s.dx_mm)));
    j0 = std::max<Eigen::Index>(0, static_cast<Eigen::Index>(std::floor((r.y_min_mm - s.y0_mm) / s.dy_mm)));
    j1 = std::min<Eigen::Index>(s.ny() - 1, static_cast<Eigen::Index>(std::ceil((r.y_max_mm - s.y0_mm) / s.dy_mm)));
    if (i1 - i0 < 1 || j1 - j0 < 1)
      throw core::Error(fmt::format(
          "render_part: the region x {}..{} y {}..{} mm does not overlap the grid (x {}..{}, "
          "y {}..{} mm)",
          r.x_min_mm, r.x_max_mm, r.y_min_mm, r.y_max_mm, s.x0_mm, s.x(s.nx() - 1), s.y0_mm, s.y(s.ny() - 1)));
  }
  // A picture shows at most about one node per pixel: a finer grid is drawn at every `stride`-th node (point samples,
  // as the rasteriser samples a finer mesh anyway), which cuts the triangles of a 0.025 mm part several-fold.
  const Eigen::Index stride =
      max_nodes_across > 0
          ? std::max<Eigen::Index>(1, (std::max(i1 - i0, j1 - j0) + max_nodes_across - 1) / max_nodes_across)
          : 1;
  const std::vector<Eigen::Index> xs = drawn_nodes(i0, i1, stride), ys = drawn_nodes(j0, j1, stride);
  const auto nx = static_cast<Eigen::Index>(xs.size()), ny = static_cast<Eigen::Index>(ys.size());
  // The surface as drawn before the vertical exaggeration: with its deviation magnified where there is one.
  const double mag = view.mark_magnification;
  auto zm = [&](Eigen::Index j, Eigen::Index i) {
    const double z = s.z_mm(j, i);
    if (!magnified) return z;
    const double d = dev->z_mm(j, i);
    return std::isfinite(d) ? z + (mag - 1) * d : z;
  };
  double zmin = std::numeric_limits<double>::max(), zmax = -zmin;
  for (Eigen::Index j : ys)
    for (Eigen::Index i : xs)
      if (s.valid(j, i)) zmin = std::min(zmin, zm(j, i)), zmax = std::max(zmax, zm(j, i));
  if (zmin > zmax) throw core::Error("render_part: the height grid has no valid node in the drawn region");

  Geometry g;
  g.z_base_mm = zmin;
  g.exaggeration = view.vertical_exaggeration;
  const double e = view.vertical_exaggeration;
  auto zd = [&](Eigen::Index j, Eigen::Index i) { return zmin + e * (zm(j, i) - zmin); };

  // Nodes, with normals from central differences of the drawn heights (one-sided next to holes and edges).
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToFloat();
  pts->SetNumberOfPoints(nx * ny);
  vtkNew<vtkFloatArray> normals;
  normals->SetNumberOfComponents(3);
  if (with_cells) normals->SetNumberOfTuples(nx * ny);
  normals->SetName("Normals");
  vtkNew<vtkFloatArray> scalars;
  scalars->SetName("deviation_um");
  if (coloured) scalars->SetNumberOfValues(nx * ny);
  vtkNew<vtkUnsignedCharArray> rgb;
  rgb->SetName("category_rgb");
  rgb->SetNumberOfComponents(3);
  if (categories) rgb->SetNumberOfTuples(nx * ny);
  std::vector<std::int32_t> id(static_cast<std::size_t>(nx * ny), -1);
  vtkIdType n = 0;
  for (Eigen::Index jj = 0; jj < ny; ++jj)
    for (Eigen::Index ii = 0; ii < nx; ++ii) {
      const Eigen::Index j = ys[static_cast<std::size_t>(jj)], i = xs[static_cast<std::size_t>(ii)];
      if (!s.valid(j, i)) continue;
      pts->SetPoint(n, s.x(i), s.y(j), zd(j, i));
      if (coloured) {
        const double d = dev->z_mm(j, i);
        scalars->SetValue(n, static_cast<float>(d * 1e3));
        if (std::isfinite(d)) g.deviation_um.push_back(d * 1e3);
      }
      if (categories) rgb->SetTypedTuple(n, category_rgb(categories->index(j, i)));
      id[static_cast<std::size_t>(jj * nx + ii)] = static_cast<std::int32_t>(n++);
      if (!with_cells) continue;
      // Neighbours one stride away (inside the window they are drawn nodes; at its edge, nodes outside it).
      const Eigen::Index step_l = ii > 0 ? i - xs[static_cast<std::size_t>(ii - 1)] : stride;
      const Eigen::Index step_r = ii + 1 < nx ? xs[static_cast<std::size_t>(ii + 1)] - i : stride;
      const Eigen::Index step_d = jj > 0 ? j - ys[static_cast<std::size_t>(jj - 1)] : stride;
      const Eigen::Index step_u = jj + 1 < ny ? ys[static_cast<std::size_t>(jj + 1)] - j : stride;
      const Eigen::Index il = (i - step_l >= 0 && s.valid(j, i - step_l)) ? i - step_l : i,
                         ir = (i + step_r < s.nx() && s.valid(j, i + step_r)) ? i + step_r : i;
      const Eigen::Index jl = (j - step_d >= 0 && s.valid(j - step_d, i)) ? j - step_d : j,
                         jr = (j + step_u < s.ny() && s.valid(j + step_u, i)) ? j + step_u : j;
      const double gx = ir > il ? (zd(j, ir) - zd(j, il)) / ((ir - il) * s.dx_mm) : 0.0;
      const double gy = jr > jl ? (zd(jr, i) - zd(jl, i)) / ((jr - jl) * s.dy_mm) : 0.0;
      const double len = std::sqrt(gx * gx + gy * gy + 1);
      const float nrm[3] = {static_cast<float>(-gx / len), static_cast<float>(-gy / len), static_cast<float>(1 / len)};
      normals->SetTypedTuple(n - 1, nrm);
    }
  pts->SetNumberOfPoints(n);
  if (with_cells) normals->SetNumberOfTuples(n);
  if (coloured) {
    for (Eigen::Index i : xs) g.node_x_mm.push_back(s.x(i));
    for (Eigen::Index j : ys) g.node_y_mm.push_back(s.y(j));
    constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
    g.node_deviation_um.assign(static_cast<std::size_t>(nx * ny), kNaNf);
    g.node_z_mm.assign(static_cast<std::size_t>(nx * ny), kNaNf);
    for (Eigen::Index jj = 0; jj < ny; ++jj)
      for (Eigen::Index ii = 0; ii < nx; ++ii) {
        const std::int32_t k = id[static_cast<std::size_t>(jj * nx + ii)];
        if (k < 0) continue;
        g.node_deviation_um[static_cast<std::size_t>(jj * nx + ii)] = scalars->GetValue(k);
        g.node_z_mm[static_cast<std::size_t>(jj * nx + ii)] = static_cast<float>(pts->GetPoint(k)[2]);
      }
  }
  if (coloured) scalars->SetNumberOfValues(n);
  if (categories) rgb->SetNumberOfTuples(n);

  g.surface = vtkSmartPointer<vtkPolyData>::New();
  g.surface->SetPoints(pts);
  if (with_cells) {
    g.surface->SetPolys(grid_cells(id, nx, ny));
    g.surface->GetPointData()->SetNormals(normals);
  } else {
    g.pending_node_ids = std::move(id);
    g.nodes_across = nx;
  }
  if (coloured) g.surface->GetPointData()->SetScalars(scalars);
  if (categories) g.surface->GetPointData()->SetScalars(rgb);

  // Side walls along the four edges of the drawn window, down to a base below the lowest point: the part reads as
  // a solid block, and a cut-out region shows its profile on its faces.
  const double dz =
      std::max({0.06 * std::max((i1 - i0) * s.dx_mm, (j1 - j0) * s.dy_mm), 0.05 * e * (zmax - zmin), 1e-3});
  const double base = zmin - dz;
  vtkNew<vtkPoints> wp;
  wp->SetDataTypeToFloat();
  vtkNew<vtkFloatArray> wn;
  wn->SetNumberOfComponents(3);
  wn->SetName("Normals");
  std::vector<std::int32_t> woff{0}, wconn;
  auto wall = [&](Eigen::Index ja, Eigen::Index ia, Eigen::Index jb, Eigen::Index ib, float nx_, float ny_) {
    if (!s.valid(ja, ia) || !s.valid(jb, ib)) return;
    const auto first = static_cast<std::int32_t>(wp->GetNumberOfPoints());
    wp->InsertNextPoint(s.x(ia), s.y(ja), zd(ja, ia));
    wp->InsertNextPoint(s.x(ib), s.y(jb), zd(jb, ib));
    wp->InsertNextPoint(s.x(ib), s.y(jb), base);
    wp->InsertNextPoint(s.x(ia), s.y(ja), base);
    for (int k = 0; k < 4; ++k) wn->InsertNextTuple3(nx_, ny_, 0);
    wconn.insert(wconn.end(), {first, first + 3, first + 2, first + 1});  // counter-clockwise seen from outside
    woff.push_back(static_cast<std::int32_t>(wconn.size()));
  };
  for (std::size_t k = 0; k + 1 < xs.size(); ++k) {
    wall(j0, xs[k], j0, xs[k + 1], 0, -1);
    wall(j1, xs[k + 1], j1, xs[k], 0, 1);
  }
  for (std::size_t k = 0; k + 1 < ys.size(); ++k) {
    wall(ys[k + 1], i0, ys[k], i0, -1, 0);
    wall(ys[k], i1, ys[k + 1], i1, 1, 0);
  }
  g.walls = vtkSmartPointer<vtkPolyData>::New();
  g.walls->SetPoints(wp);
  g.walls->SetPolys(cells_of(woff, wconn));
  g.walls->GetPointData()->SetNormals(wn);
  update_bounds(g);
  return g;
}

// ---- mesh -----------------------------------------------------------------------------------------------------

Geometry mesh_geometry(const core::TriangleMesh& m, const View& view, bool coloured, const std::string& array) {
  const Eigen::Index nv = m.vertices_mm.rows(), nt = m.triangles.rows();
  if (nv < 3 || nt < 1) throw core::Error("render_part: the mesh has no triangles");
  if (view.mark_magnification != 1.0)
    throw core::Error("render_part: mark magnification applies to height grids with a deviation grid, not to meshes");
  if (nv > std::numeric_limits<std::int32_t>::max() / 2)
    throw core::Error("render_part: the mesh has too many vertices");
  const Eigen::VectorXd* dev = nullptr;
  if (coloured) {
    for (const auto& [name, values] : m.point_data)
      if (name == array) dev = &values;
    if (!dev)
      throw core::Error("render_part: deviation colours asked for, but the mesh has no \"" + array + "\" array");
    if (dev->size() != nv)
      throw core::Error(fmt::format("render_part: \"{}\" has {} values for {} vertices", array, dev->size(), nv));
  }
  // Triangles kept: those with their centroid in the region.
  std::vector<char> keep(static_cast<std::size_t>(nt), 1);
  std::vector<char> used(static_cast<std::size_t>(nv), 0);
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int c = 0; c < 3; ++c)
      if (m.triangles(t, c) < 0 || m.triangles(t, c) >= nv)
        throw core::Error(
            fmt::format("render_part: triangle {} refers to vertex {}, the mesh has {}", t, m.triangles(t, c), nv));
    if (view.region) {
      const Region& r = *view.region;
      const Eigen::Vector3d c = (m.vertices_mm.row(m.triangles(t, 0)) + m.vertices_mm.row(m.triangles(t, 1)) +
                                 m.vertices_mm.row(m.triangles(t, 2)))
                                    .transpose() /
                                3;
      keep[static_cast<std::size_t>(t)] =
          c.x() >= r.x_min_mm && c.x() <= r.x_max_mm && c.y() >= r.y_min_mm && c.y() <= r.y_max_mm;
    }
    if (keep[static_cast<std::size_t>(t)])
      for (int c = 0; c < 3; ++c) used[static_cast<std::size_t>(m.triangles(t, c))] = 1;
  }
  double zmin = std::numeric_limits<double>::max();
  for (Eigen::Index v = 0; v < nv; ++v)
    if (used[static_cast<std::size_t>(v)]) zmin = std::min(zmin, m.vertices_mm(v, 2));
  if (zmin == std::numeric_limits<double>::max())
    throw core::Error("render_part: no triangle of the mesh lies in the region");
  Geometry g;
  g.z_base_mm = zmin;
  g.exaggeration = view.vertical_exaggeration;
  std::vector<std::int32_t> id(static_cast<std::size_t>(nv), -1);
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToFloat();
  vtkNew<vtkFloatArray> scalars;
  scalars->SetName("deviation_um");
  std::int32_t n = 0;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (!used[static_cast<std::size_t>(v)]) continue;
    id[static_cast<std::size_t>(v)] = n++;
    pts->InsertNextPoint(m.vertices_mm(v, 0), m.vertices_mm(v, 1),
                         zmin + g.exaggeration * (m.vertices_mm(v, 2) - zmin));
    if (coloured) {
      const double d = (*dev)[v];
      scalars->InsertNextValue(static_cast<float>(d * 1e3));
      if (std::isfinite(d)) g.deviation_um.push_back(d * 1e3);
    }
  }
  std::vector<std::int32_t> offsets{0}, conn;
  conn.reserve(static_cast<std::size_t>(3 * nt));
  for (Eigen::Index t = 0; t < nt; ++t) {
    if (!keep[static_cast<std::size_t>(t)]) continue;
    for (int c = 0; c < 3; ++c) conn.push_back(id[static_cast<std::size_t>(m.triangles(t, c))]);
    offsets.push_back(static_cast<std::int32_t>(conn.size()));
  }
  vtkNew<vtkPolyData> pd;
  pd->SetPoints(pts);
  pd->SetPolys(cells_of(offsets, conn));
  if (coloured) pd->GetPointData()->SetScalars(scalars);
  // Normals: shared across smooth edges, split across sharp ones (a part's edges), the mesh's own orientation kept.
  vtkNew<vtkPolyDataNormals> normals;
  normals->SetInputData(pd);
  normals->SetFeatureAngle(40);
  normals->SplittingOn();
  normals->ConsistencyOff();
  normals->AutoOrientNormalsOff();
  normals->ComputeCellNormalsOff();
  normals->Update();
  g.surface = normals->GetOutput();
  update_bounds(g);
  return g;
}

// ---- camera -----------------------------------------------------------------------------------------------------

struct CameraFrame {
  Eigen::Vector3d to_camera, up;  // unit vectors: from the focal point towards the camera; the picture's up
};

CameraFrame camera_frame(const View& v) {
  CameraFrame f;
  switch (v.direction) {
    case ViewDirection::Top:
      f.to_camera = {0, 0, 1};
      f.up = {0, 1, 0};
      return f;
    case ViewDirection::Isometric: {
      const double az = -120 * kDeg, el = 35 * kDeg;
      f.to_camera = {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
      break;
    }
    case ViewDirection::AlongPath: {
      // Behind the cut (against the path direction), 20 deg to its left, 25 deg up.
      const double az = (v.path_direction_deg + 180 - 20) * kDeg, el = 25 * kDeg;
      f.to_camera = {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
      break;
    }
  }
  f.up = {0, 0, 1};
  return f;
}

// Frames the box [bounds] in a viewport of the given aspect (width / height): the focal point and distance at
// which every corner is inside the view (perspective, vertical view angle `fov_deg`) or the parallel scale.
void frame_camera(vtkCamera* cam, const CameraFrame& f, const double b[6], double aspect, bool parallel,
                  double fov_deg) {
  const Eigen::Vector3d centre((b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2);
  const Eigen::Vector3d dir = f.to_camera;
  const Eigen::Vector3d right = (-dir).cross(f.up).normalized();
  const Eigen::Vector3d up = right.cross(-dir);
  double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300;
  std::vector<Eigen::Vector3d> corners;
  for (int k = 0; k < 8; ++k) corners.emplace_back(b[(k & 1) ? 1 : 0], b[(k & 2) ? 3 : 2], b[(k & 4) ? 5 : 4]);
  for (const auto& c : corners) {
    const Eigen::Vector3d r = c - centre;
    amin = std::min(amin, r.dot(right)), amax = std::max(amax, r.dot(right));
    bmin = std::min(bmin, r.dot(up)), bmax = std::max(bmax, r.dot(up));
  }
  const Eigen::Vector3d focal = centre + right * (amin + amax) / 2 + up * (bmin + bmax) / 2;
  const double margin = 1.04;
  double extent = 0;
  for (const auto& c : corners) extent = std::max(extent, (c - centre).norm());
  extent = std::max(extent, 1e-6);
  cam->SetViewUp(up.data());
  cam->SetFocalPoint(focal.data());
  if (parallel) {
    cam->ParallelProjectionOn();
    const double half_h = (bmax - bmin) / 2, half_w = (amax - amin) / 2;
    cam->SetParallelScale(margin * std::max({half_h, half_w / aspect, 1e-6}));
    const Eigen::Vector3d pos = focal + dir * 4 * extent;
    cam->SetPosition(pos.data());
  } else {
    cam->ParallelProjectionOff();
    cam->SetViewAngle(fov_deg);
    const double tv = std::tan(fov_deg * kDeg / 2), th = tv * aspect;
    double d = 0;
    for (const auto& c : corners) {
      const Eigen::Vector3d r = c - focal;
      d = std::max(d, r.dot(dir) + std::max(std::abs(r.dot(right)) / th, std::abs(r.dot(up)) / tv));
    }
    const Eigen::Vector3d pos = focal + dir * margin * d;
    cam->SetPosition(pos.data());
  }
  cam->SetClippingRange(1e-3 * extent, 10 * extent);
}

// ---- lights and materials ---------------------------------------------------------------------------------------

void add_lights(vtkRenderer* ren, const CameraFrame& f, const Lighting& l, const double b[6]) {
  ren->AutomaticLightCreationOff();
  ren->RemoveAllLights();
  // The camera's horizontal viewing direction and its right; straight down (Top) counts as looking towards +Y.
  Eigen::Vector3d h(-f.to_camera.x(), -f.to_camera.y(), 0);
  if (h.norm() < 1e-6) h = {0, 1, 0};
  h.normalize();
  const Eigen::Vector3d right = h.cross(Eigen::Vector3d::UnitZ());
  const double a = l.azimuth_deg * kDeg, e = l.elevation_deg * kDeg;
  const Eigen::Vector3d from =
      (std::cos(a) * -h + std::sin(a) * right) * std::cos(e) + Eigen::Vector3d::UnitZ() * std::sin(e);
  const Eigen::Vector3d centre((b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2);
  const Eigen::Vector3d pos = centre + from * 1000;
  vtkNew<vtkLight> key;
  key->SetLightTypeToSceneLight();
  key->PositionalOff();
  key->SetPosition(pos.data());
  key->SetFocalPoint(centre.data());
  key->SetIntensity(1.4);  // the flat floor mid-grey under a 15 deg light, faces towards it just below white
  key->SetColor(1.0, 0.98, 0.95);
  ren->AddLight(key);
  vtkNew<vtkLight> fill;  // from the camera, weak: faces turned away from the key light stay legible
  fill->SetLightTypeToHeadlight();
  fill->SetIntensity(0.22);
  fill->SetColor(0.9, 0.93, 1.0);
  ren->AddLight(fill);
}

void metal(vtkProperty* p, double shade) {
  p->SetColor(0.80 * shade, 0.81 * shade, 0.83 * shade);
  p->SetAmbient(0.10);
  p->SetDiffuse(0.85);
  p->SetSpecular(0.35);
  p->SetSpecularPower(40);
  p->SetSpecularColor(1, 1, 1);
}

vtkSmartPointer<vtkLookupTable> deviation_table(double limit_um) {
  auto lut = vtkSmartPointer<vtkLookupTable>::New();
  lut->SetNumberOfTableValues(kColourTableSize);
  for (int k = 0; k < kColourTableSize; ++k) {
    const Rgb c = diverging_colour(-1 + (2.0 * k + 1) / kColourTableSize);
    lut->SetTableValue(k, c[0], c[1], c[2], 1.0);
  }
  lut->SetTableRange(-limit_um, limit_um);
  lut->SetNanColor(0.55, 0.55, 0.55, 1.0);
  lut->SetUseBelowRangeColor(false);
  lut->SetUseAboveRangeColor(false);  // beyond the limits: the end colours
  return lut;
}

// Iso-lines as VTK lines.
vtkSmartPointer<vtkPolyData> isoline_polydata(const IsoLines& lines) {
  vtkNew<vtkPoints> p;
  p->SetDataTypeToFloat();
  p->SetNumberOfPoints(lines.points_mm.rows());
  for (Eigen::Index k = 0; k < lines.points_mm.rows(); ++k)
    p->SetPoint(k, lines.points_mm(k, 0), lines.points_mm(k, 1), lines.points_mm(k, 2));
  std::vector<std::int32_t> offsets{0}, conn;
  conn.reserve(2 * lines.segments.size());
  offsets.reserve(lines.segments.size() + 1);
  for (const auto& s : lines.segments) {
    conn.insert(conn.end(), {s[0], s[1]});
    offsets.push_back(static_cast<std::int32_t>(conn.size()));
  }
  auto pd = vtkSmartPointer<vtkPolyData>::New();
  pd->SetPoints(p);
  pd->SetLines(cells_of(offsets, conn));
  return pd;
}

// Iso-deviation values: multiples of step on each side of zero, within the limits.
std::vector<double> iso_values(double limit_um, int n) {
  std::vector<double> v;
  if (n <= 0) return v;
  const double step = limit_um / (n + 1);
  for (int k = -n; k <= n; ++k)
    if (k != 0) v.push_back(k * step);
  return v;
}

// A scale bar of a round length under the scene (Top views: the picture has a true scale).
void add_scale_bar(vtkRenderer* overlay, double mm_per_px, const double vp[4], int font_px) {
  const double target_mm = 0.22 * vp[2] * mm_per_px;
  double len = nice_ceil(target_mm);
  if (len > target_mm * 1.3) len = nice_ceil(target_mm / 2.5);
  const double px = len / mm_per_px;
  const double x0 = vp[0] + 24, y0 = 8;  // display coordinates: y up from the bottom
  vtkNew<vtkPoints> p;
  p->InsertNextPoint(x0, y0 + 6, 0);
  p->InsertNextPoint(x0, y0, 0);
  p->InsertNextPoint(x0 + px, y0, 0);
  p->InsertNextPoint(x0 + px, y0 + 6, 0);
  vtkNew<vtkCellArray> lines;
  const vtkIdType ids[4] = {0, 1, 2, 3};
  lines->InsertNextCell(4, ids);
  vtkNew<vtkPolyData> pd;
  pd->SetPoints(p);
  pd->SetLines(lines);
  vtkNew<vtkPolyDataMapper2D> m;
  m->SetInputData(pd);
  vtkNew<vtkActor2D> a;
  a->SetMapper(m);
  a->GetProperty()->SetColor(0.95, 0.95, 0.95);
  a->GetProperty()->SetLineWidth(2.5);
  overlay->AddActor2D(a);
  vtkNew<vtkTextActor> t;
  t->SetInput(fmt::format("{:g} mm", len).c_str());
  detail::set_font(t->GetTextProperty(), font_px, 0.95, 0.95, 0.95);
  t->GetTextProperty()->SetJustificationToCentered();
  t->SetDisplayPosition(static_cast<int>(x0 + px / 2), static_cast<int>(y0 + 10));
  overlay->AddActor2D(t);
}

// ---- flat maps drawn as an image --------------------------------------------------------------------------------

// Whether a flat map of this grid can be drawn as an image: every drawn node valid with a finite deviation (holes,
// and VTK's own way of colouring next to a NaN, stay with the triangles).
bool map_image_possible(const Geometry& g) {
  if (g.node_deviation_um.empty() || g.node_x_mm.size() < 2 || g.node_y_mm.size() < 2) return false;
  for (std::size_t k = 0; k < g.node_deviation_um.size(); ++k)
    if (!std::isfinite(g.node_deviation_um[k]) || !std::isfinite(g.node_z_mm[k])) return false;
  return true;
}

// Where the centre of each pixel column (or row) of the viewport falls among the drawn nodes' coordinates
// (ascending): the cell and the fraction across it; cell -1 outside their span.
struct CellFraction {
  std::int32_t cell = -1;
  double t = 0;
};
std::vector<CellFraction> cell_fractions(const std::vector<double>& nodes, double first_centre, double step, int n) {
  std::vector<CellFraction> out(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double x = first_centre + k * step;
    if (!(x >= nodes.front() && x <= nodes.back())) continue;
    const auto it = std::upper_bound(nodes.begin(), nodes.end(), x);
    const auto c = std::min<std::ptrdiff_t>(std::max<std::ptrdiff_t>(it - nodes.begin() - 1, 0),
                                            static_cast<std::ptrdiff_t>(nodes.size()) - 2);
    const double a = nodes[static_cast<std::size_t>(c)], b = nodes[static_cast<std::size_t>(c) + 1];
    out[static_cast<std::size_t>(k)] = {static_cast<std::int32_t>(c), (x - a) / (b - a)};
  }
  return out;
}

// The flat map as an image actor, one texel per pixel of the renderer's viewport, each texel centred on its pixel's
// centre (parallel projection straight down, the camera already framed) and coloured by `lut` at the deviation
// interpolated there linearly over the triangles (a, b, c) and (a, c, d) of its cell, as the triangles are split
// (grid_geometry): what the rasteriser computes per pixel for InterpolateScalarsBeforeMapping. It lies at z_mm
// (below the surface, so the iso-lines drawn at the surface's heights stay in front). Null when no pixel centre
// falls on the grid, or for a viewport over 4096 x 4096 pixels: the image and its texture (~7 B a pixel) would then
// outgrow what detail::check_size allows a picture, and the triangles are drawn instead.
vtkSmartPointer<vtkImageActor> map_image(vtkRenderer* ren, const Geometry& g, vtkLookupTable* lut, double z_mm) {
  int vw = 0, vh = 0, vx = 0, vy = 0;
  ren->GetTiledSizeAndOrigin(&vw, &vh, &vx, &vy);
  vtkMatrix4x4* m = ren->GetActiveCamera()->GetCompositeProjectionTransformMatrix(ren->GetTiledAspectRatio(), -1, 1);
  // Straight down with +Y up: x depends on the NDC x only, y on the NDC y only.
  const double m00 = m->GetElement(0, 0), m03 = m->GetElement(0, 3), m11 = m->GetElement(1, 1),
               m13 = m->GetElement(1, 3);
  if (vw < 1 || vh < 1 || !(m00 > 0) || !(m11 > 0) || static_cast<double>(vw) * vh > 4096.0 * 4096.0) return nullptr;
  // Pixel k's centre at NDC 2 (k + 0.5) / n - 1.
  const double x0 = ((1.0 / vw - 1) - m03) / m00, sx = 2.0 / vw / m00;
  const double y0 = ((1.0 / vh - 1) - m13) / m11, sy = 2.0 / vh / m11;
  const std::vector<CellFraction> cx = cell_fractions(g.node_x_mm, x0, sx, vw),
                                  cy = cell_fractions(g.node_y_mm, y0, sy, vh);
  const auto first = [](const std::vector<CellFraction>& v) {
    return static_cast<int>(std::find_if(v.begin(), v.end(), [](const CellFraction& c) { return c.cell >= 0; }) -
                            v.begin());
  };
  const auto last = [](const std::vector<CellFraction>& v) {
    return static_cast<int>(v.rend() -
                            std::find_if(v.rbegin(), v.rend(), [](const CellFraction& c) { return c.cell >= 0; }) - 1);
  };
  const int i0 = first(cx), i1 = last(cx), j0 = first(cy), j1 = last(cy);
  if (i0 > i1 || j0 > j1) return nullptr;
  const int nx = i1 - i0 + 1, ny = j1 - j0 + 1;
  vtkNew<vtkImageData> image;
  image->SetDimensions(nx, ny, 1);
  image->SetOrigin(x0 + i0 * sx, y0 + j0 * sy, z_mm);
  image->SetSpacing(sx, sy, 1);
  image->AllocateScalars(VTK_UNSIGNED_CHAR, 3);
  auto* px = static_cast<unsigned char*>(image->GetScalarPointer());
  const std::size_t stride = g.node_x_mm.size();
  const float* d = g.node_deviation_um.data();
  for (int j = 0; j < ny; ++j) {
    const CellFraction& fy = cy[static_cast<std::size_t>(j0 + j)];
    const float* row = d + static_cast<std::size_t>(fy.cell) * stride;  // nodes a, b at row j, d, c at row j + 1
    for (int i = 0; i < nx; ++i, px += 3) {
      const CellFraction& fx = cx[static_cast<std::size_t>(i0 + i)];
      const std::size_t c = static_cast<std::size_t>(fx.cell);
      const double u = fx.t, v = fy.t;
      const double a = row[c], b = row[c + 1], cc = row[stride + c + 1], dd = row[stride + c];
      const double value = u >= v ? a * (1 - u) + b * (u - v) + cc * v : a * (1 - v) + cc * u + dd * (v - u);
      const unsigned char* rgba = lut->MapValue(value);
      px[0] = rgba[0], px[1] = rgba[1], px[2] = rgba[2];
    }
  }
  auto actor = vtkSmartPointer<vtkImageActor>::New();
  actor->SetInputData(image);
  actor->InterpolateOff();  // nearest texel: each pixel its own
  actor->ForceOpaqueOn();
  actor->GetMapper()->BorderOn();  // texels are squares around their centres: the edge pixels are drawn too
  return actor;
}

PartImage draw(Window& window, Geometry& g, const PartPicture& pic) {
  const int W = pic.width, H = pic.height;
  const bool coloured = pic.deviation.has_value();
  vtkRenderWindow* rw = detail::begin_picture(window, W, H);
  rw->SetNumberOfLayers(2);

  // Layout (pixels): caption band on top, colour scale on the right, the scene in the rest.
  const int n_caption = static_cast<int>(pic.caption.size());
  const double big = std::clamp(H / 40.0, 13.0, 36.0), small = std::clamp(H / 56.0, 11.0, 26.0);
  const double top_band = n_caption > 0 ? 14 + big + (n_caption - 1) * (small * 1.35) + 12 : 0;
  const bool categorised = pic.categories.has_value();
  const double right_band = coloured || categorised ? std::clamp(W * 0.14, 120.0, 320.0) : 0;
  const bool top = pic.view.direction == ViewDirection::Top;
  const double bottom_band = top ? small * 1.6 + 22 : 0;                           // the scale bar of a map, under it
  const double vp[4] = {0, top_band, W - right_band, H - top_band - bottom_band};  // left, top, width, height (px)
  if (vp[2] < 16 || vp[3] < 16)
    throw core::Error(fmt::format("render_part: {}x{} pixels leave no room for the part", W, H));

  vtkNew<vtkRenderer> overlay;  // layer 0: background and annotations
  overlay->SetLayer(0);
  overlay->GradientBackgroundOn();
  overlay->SetBackground(0.09, 0.10, 0.12);
  overlay->SetBackground2(0.27, 0.29, 0.33);
  vtkNew<vtkRenderer> ren;  // layer 1: the part, drawn over the background
  ren->SetLayer(1);
  ren->SetViewport(vp[0] / W, 1 - (vp[1] + vp[3]) / H, (vp[0] + vp[2]) / W, 1 - vp[1] / H);
  // Maps stay exact (every pixel one colour of the table); 3-D views get smooth silhouettes. FXAA works on the
  // scene's viewport only: the annotations around it stay as drawn.
  const Antialiasing aa = top ? Antialiasing::None : pic.antialiasing;
  detail::set_antialiasing(rw, ren, aa);
  rw->AddRenderer(overlay);
  rw->AddRenderer(ren);

  PartImage out;
  vtkSmartPointer<vtkLookupTable> lut;
  if (coloured) {
    const DeviationColours& dc = *pic.deviation;
    if (dc.limit_mm < 0 || !std::isfinite(dc.limit_mm)) throw core::Error("render_part: the colour limit must be >= 0");
    if (dc.isolines < 0 || dc.isolines > 50) throw core::Error("render_part: isolines must be in 0..50");
    const double limit_um = dc.limit_mm > 0 ? dc.limit_mm * 1e3 : symmetric_limit(g.deviation_um, 1.0);
    out.limit_mm = limit_um / 1e3;
    lut = deviation_table(limit_um);
  }

  vtkNew<vtkPolyDataMapper> sm;
  sm->SetInputData(g.surface);
  vtkNew<vtkActor> surface;
  surface->SetMapper(sm);
  if (coloured) {
    sm->SetLookupTable(lut);
    sm->SetScalarRange(lut->GetTableRange());
    sm->SetScalarModeToUsePointData();
    sm->ScalarVisibilityOn();
    sm->InterpolateScalarsBeforeMappingOn();  // colours interpolated as values, not as RGB: exact across a triangle
    sm->SetColorModeToMapScalars();
    vtkProperty* p = surface->GetProperty();
    if (pic.deviation->lit) {
      // Brighter in the shadows and duller in the light than metal: the colours must stay readable, a face
      // towards the light must not wash out to white.
      p->SetAmbient(0.24);
      p->SetDiffuse(0.58);
      p->SetSpecular(0.10);
      p->SetSpecularPower(30);
    } else {
      p->LightingOff();  // every pixel its map colour
    }
  } else if (categorised) {
    // Each node its category's colour (interpolated between nodes of different ones), lit as the deviation maps.
    sm->SetScalarModeToUsePointData();
    sm->ScalarVisibilityOn();
    sm->SetColorModeToDirectScalars();
    vtkProperty* p = surface->GetProperty();
    p->SetAmbient(0.24);
    p->SetDiffuse(0.58);
    p->SetSpecular(0.10);
    p->SetSpecularPower(30);
  } else {
    sm->ScalarVisibilityOff();
    metal(surface->GetProperty(), 1.0);
  }
  // Flat Top maps as an image (PartPicture::map_as_image), made once the camera is framed.
  const bool as_image = coloured && top && !pic.deviation->lit && pic.map_as_image && map_image_possible(g);
  if (!as_image) {
    add_grid_cells(g);
    ren->AddActor(surface);
  }
  vtkNew<vtkPolyDataMapper> wm;
  vtkNew<vtkActor> walls;
  if (g.walls && g.walls->GetNumberOfCells() > 0) {
    wm->SetInputData(g.walls);
    wm->ScalarVisibilityOff();
    walls->SetMapper(wm);
    metal(walls->GetProperty(), 0.55);  // cut faces darker than the machined surface
    ren->AddActor(walls);
  }
  vtkNew<vtkContourFilter> iso;
  vtkNew<vtkPolyDataMapper> im;
  vtkNew<vtkActor> isolines;
  if (coloured && pic.deviation->isolines > 0) {
    const std::vector<double> values = iso_values(out.limit_mm * 1e3, pic.deviation->isolines);
    if (!g.node_deviation_um.empty()) {
      // A grid: marching squares over its nodes (render/isolines.hpp), the same crossings on every grid edge.
      im->SetInputData(
          isoline_polydata(grid_isolines(g.node_x_mm, g.node_y_mm, g.node_deviation_um, g.node_z_mm, values)));
    } else {
      iso->SetInputData(g.surface);
      iso->SetNumberOfContours(static_cast<int>(values.size()));
      for (std::size_t k = 0; k < values.size(); ++k) iso->SetValue(static_cast<int>(k), values[k]);
      iso->ComputeScalarsOff();
      iso->ComputeNormalsOff();
      im->SetInputConnection(iso->GetOutputPort());
    }
    im->ScalarVisibilityOff();
    // Drawn over the coincident surface.
    im->SetResolveCoincidentTopologyToPolygonOffset();
    im->SetRelativeCoincidentTopologyLineOffsetParameters(0, -66000);
    isolines->SetMapper(im);
    isolines->GetProperty()->SetColor(0.12, 0.12, 0.12);
    isolines->GetProperty()->SetLineWidth(std::max(1.0, H / 800.0));
    isolines->GetProperty()->LightingOff();
    ren->AddActor(isolines);
  }

  const CameraFrame frame = camera_frame(pic.view);
  double b[6];
  std::copy(g.bounds, g.bounds + 6, b);
  if (pic.view.direction == ViewDirection::Top && pic.view.region) {
    // A map frames the asked rectangle exactly, not the grid nodes around it.
    b[0] = pic.view.region->x_min_mm, b[1] = pic.view.region->x_max_mm;
    b[2] = pic.view.region->y_min_mm, b[3] = pic.view.region->y_max_mm;
  }
  const double aspect = vp[2] / vp[3];
  vtkCamera* cam = ren->GetActiveCamera();
  frame_camera(cam, frame, b, aspect, pic.view.direction == ViewDirection::Top, 30.0);
  vtkSmartPointer<vtkImageActor> map;
  if (as_image) {
    map = map_image(ren, g, lut, g.bounds[4]);
    if (!map) add_grid_cells(g);
    ren->AddActor(map ? static_cast<vtkProp*>(map) : surface.Get());
  }
  add_lights(ren, frame, pic.light, b);

  // Annotations.
  std::vector<vtkSmartPointer<vtkTextActor>> texts;
  double y = H - 14 - big;
  for (int k = 0; k < n_caption; ++k) {
    auto t = vtkSmartPointer<vtkTextActor>::New();
    t->SetInput(pic.caption[static_cast<std::size_t>(k)].c_str());
    detail::set_font(t->GetTextProperty(), static_cast<int>(k == 0 ? big : small), 0.96, 0.96, 0.96, k == 0);
    t->SetDisplayPosition(16, static_cast<int>(y));
    overlay->AddActor2D(t);
    texts.push_back(t);
    y -= (k == 0 ? small * 1.45 : small * 1.35);
  }
  vtkNew<vtkScalarBarActor> bar;
  vtkNew<vtkTextActor> bar_top, bar_bottom;
  if (coloured) {
    bar->SetLookupTable(lut);
    bar->SetTitle("deviation [µm]");
    bar->SetNumberOfLabels(5);
    bar->SetLabelFormat("%.3g");
    bar->SetMaximumNumberOfColors(kColourTableSize);
    bar->UnconstrainedFontSizeOn();
    bar->SetBarRatio(0.28);
    bar->DrawFrameOff();
    detail::set_font(bar->GetTitleTextProperty(), static_cast<int>(small * 1.05), 0.96, 0.96, 0.96, true);
    detail::set_font(bar->GetLabelTextProperty(), static_cast<int>(small), 0.92, 0.92, 0.92);
    bar->GetPositionCoordinate()->SetCoordinateSystemToDisplay();
    bar->GetPosition2Coordinate()->SetCoordinateSystemToDisplay();
    const double bx = W - right_band + 10, bh = std::min(0.62 * H, vp[3] - 2 * small - 20);
    const double by = (H - top_band - bh) / 2 - small;  // display y of the bar's bottom
    bar->SetPosition(bx, by);
    bar->SetPosition2(right_band - 20, bh);
    overlay->AddActor2D(bar);
    // What the two ends mean.
    bar_top->SetInput("+ undercut\n  (material left)");
    bar_bottom->SetInput("− overcut\n  (cut too deep)");
    for (vtkTextActor* t : {bar_top.Get(), bar_bottom.Get()}) {
      detail::set_font(t->GetTextProperty(), static_cast<int>(small * 0.8), 0.85, 0.85, 0.85);
      overlay->AddActor2D(t);
    }
    bar_top->SetDisplayPosition(static_cast<int>(bx), static_cast<int>(by + bh + small * 2.4));
    bar_bottom->SetDisplayPosition(static_cast<int>(bx), static_cast<int>(by - small * 2.6));
  }
  if (categorised) {
    // The legend: a square of each category's colour and its name, from the top of the right band down.
    const CategoryColours& cc = *pic.categories;
    std::vector<std::pair<int, std::string>> rows;
    for (std::size_t k = 0; k < cc.names.size(); ++k) rows.emplace_back(static_cast<int>(k), cc.names[k]);
    if (!cc.none_name.empty()) rows.emplace_back(-1, cc.none_name);
    const double bx = W - right_band + 10;
    double ly = H - top_band - 2 * small;
    if (!cc.title.empty()) {
      auto t = vtkSmartPointer<vtkTextActor>::New();
      t->SetInput(cc.title.c_str());
      detail::set_font(t->GetTextProperty(), static_cast<int>(small * 1.05), 0.96, 0.96, 0.96, true);
      t->SetDisplayPosition(static_cast<int>(bx), static_cast<int>(ly));
      overlay->AddActor2D(t);
      texts.push_back(t);
      ly -= small * 1.8;
    }
    for (const auto& [k, name] : rows) {
      const unsigned char* c = category_rgb(k);
      auto sq = vtkSmartPointer<vtkTextActor>::New();
      sq->SetInput("\u25A0");
      detail::set_font(sq->GetTextProperty(), static_cast<int>(small * 1.4), c[0] / 255.0, c[1] / 255.0, c[2] / 255.0);
      sq->SetDisplayPosition(static_cast<int>(bx), static_cast<int>(ly - small * 0.2));
      auto t = vtkSmartPointer<vtkTextActor>::New();
      t->SetInput(name.c_str());
      detail::set_font(t->GetTextProperty(), static_cast<int>(small * 0.9), 0.92, 0.92, 0.92);
      t->SetDisplayPosition(static_cast<int>(bx + small * 1.6), static_cast<int>(ly));
      overlay->AddActor2D(sq);
      overlay->AddActor2D(t);
      texts.push_back(sq);
      texts.push_back(t);
      ly -= small * 1.8;
    }
  }
  if (top) add_scale_bar(overlay, 2 * cam->GetParallelScale() / vp[3], vp, static_cast<int>(small));

  // The scene's viewport in pixels as VTK rounds it (lower-left origin), for FXAA on the CPU.
  int vp_px[4];
  ren->GetTiledSizeAndOrigin(&vp_px[2], &vp_px[3], &vp_px[0], &vp_px[1]);
  out.image = detail::finish_picture(window);
  if (aa == Antialiasing::Fxaa) fxaa(out.image, PixelRect{vp_px[0], H - vp_px[1] - vp_px[3], vp_px[2], vp_px[3]});
  vtkMatrix4x4* mtx = cam->GetCompositeProjectionTransformMatrix(aspect, -1, 1);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out.world_to_ndc(r, c) = mtx->GetElement(r, c);
  std::copy(vp, vp + 4, out.viewport_px);
  out.exaggeration = g.exaggeration;
  out.z_base_mm = g.z_base_mm;
  return out;
}

void check_picture(const PartPicture& pic) {
  detail::check_size(pic.width, pic.height, "render_part");
  if (pic.categories && pic.deviation) throw core::Error("render_part: colour by deviation or by category, not both");
  check_view(pic.view, "render_part");
  if (!std::isfinite(pic.light.elevation_deg) || pic.light.elevation_deg <= 0 || pic.light.elevation_deg > 90)
    throw core::Error("render_part: the light's elevation must be in (0, 90] degrees");
}

}  // namespace

Eigen::Vector2d PartImage::pixel(const Eigen::Vector3d& p) const {
  const Eigen::Vector4d w(p.x(), p.y(), z_base_mm + exaggeration * (p.z() - z_base_mm), 1.0);
  const Eigen::Vector4d c = world_to_ndc * w;
  const double nx = c.x() / c.w(), ny = c.y() / c.w();
  return {viewport_px[0] + (nx + 1) / 2 * viewport_px[2], viewport_px[1] + (1 - ny) / 2 * viewport_px[3]};
}

PartImage render_part(Window& window, const core::HeightGrid& surface, const core::HeightGrid* deviation,
                      const PartPicture& picture) {
  check_picture(picture);
  // About one node per pixel of the picture's larger side (the part fills most of it).
  const Eigen::Index max_across = picture.full_resolution ? 0 : std::max(picture.width, picture.height);
  // A flat map drawn as an image needs neither the triangles nor the normals (~10 % of such a picture's CPU).
  const bool image_map = picture.deviation && !picture.deviation->lit && picture.view.direction == ViewDirection::Top &&
                         picture.map_as_image;
  Geometry g = grid_geometry(surface, deviation, picture.view, picture.deviation.has_value(), max_across,
                             picture.categories ? &*picture.categories : nullptr, !image_map);
  return draw(window, g, picture);
}

PartImage render_part(Window& window, const core::TriangleMesh& mesh, const PartPicture& picture,
                      const std::string& deviation_array) {
  check_picture(picture);
  if (picture.categories) throw core::Error("render_part: category colours apply to height grids, not to meshes");
  Geometry g = mesh_geometry(mesh, picture.view, picture.deviation.has_value(), deviation_array);
  return draw(window, g, picture);
}

Region region_around(double x_mm, double y_mm, double half_extent_mm, const Region& bounds, int width, int height) {
  const double aspect = static_cast<double>(width) / height;
  double hx = half_extent_mm, hy = half_extent_mm;
  if (aspect >= 1)
    hx = half_extent_mm * aspect;
  else
    hy = half_extent_mm / aspect;
  Region r{x_mm - hx, x_mm + hx, y_mm - hy, y_mm + hy};
  // Slide it inside the bounds where it fits, clip where it does not.
  auto fit = [](double& lo, double& hi, double blo, double bhi) {
    if (hi - lo >= bhi - blo) {
      lo = blo, hi = bhi;
      return;
    }
    if (lo < blo) hi += blo - lo, lo = blo;
    if (hi > bhi) lo -= hi - bhi, hi = bhi;
  };
  fit(r.x_min_mm, r.x_max_mm, bounds.x_min_mm, bounds.x_max_mm);
  fit(r.y_min_mm, r.y_max_mm, bounds.y_min_mm, bounds.y_max_mm);
  return r;
}

}  // namespace vmsim::render
