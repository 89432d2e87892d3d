#include "removal/vdb_grid.hpp"

#include "core/error.hpp"
#include "core/stl.hpp"

#include <openvdb/io/File.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/LevelSetMeasure.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/RayIntersector.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <random>

namespace vmsim::removal {

void vdb_initialize() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

openvdb::math::Transform::Ptr vdb_transform(double voxel_mm, const Eigen::Vector3d& origin_mm) {
  auto xf = openvdb::math::Transform::createLinearTransform(voxel_mm);
  xf->postTranslate(openvdb::Vec3d(origin_mm.x(), origin_mm.y(), origin_mm.z()));
  return xf;
}

VdbPart vdb_wrap(openvdb::FloatGrid::Ptr grid) {
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  grid->setName("part");
  VdbPart p;
  p.impl().grid = std::move(grid);
  return p;
}

namespace {

using Grid = openvdb::FloatGrid;

void check_options(const VdbOptions& o) {
  if (!(o.voxel_mm > 0) || !std::isfinite(o.voxel_mm))
    throw core::Error(fmt::format("vdb: the voxel size must be > 0 mm, found {}", o.voxel_mm));
  if (!(o.half_width_voxels >= 2))
    throw core::Error(fmt::format("vdb: the band half width must be >= 2 voxels, found {}", o.half_width_voxels));
}

// Stocks: voxel centres at (i + 1/2) voxel_mm, so that faces at round coordinates fall between voxel centres, and
// the stock's low corner at index 16 or so: the band (and everything a cut can reach) then has positive indices and
// stays inside one 4096^3 top-level node for stocks up to 4000 voxels long, instead of straddling index 0, where 8
// top-level nodes (264 kB each) meet.
Eigen::Vector3d stock_origin(double h, const Eigen::Vector3d& lo) {
  Eigen::Vector3d o;
  for (int c = 0; c < 3; ++c) o[c] = 0.5 * h + h * (std::floor(lo[c] / h) - 16);
  return o;
}

const Grid& grid_of(const VdbPart& p) {
  if (p.empty()) throw core::Error("vdb: the part is empty (no level set)");
  return *p.impl().grid;
}

}  // namespace

VdbPart::VdbPart() : impl_(std::make_unique<Impl>()) {}
VdbPart::~VdbPart() = default;
VdbPart::VdbPart(const VdbPart& o) : impl_(std::make_unique<Impl>()) {
  if (o.impl_->grid) impl_->grid = o.impl_->grid->deepCopy();
}
VdbPart& VdbPart::operator=(const VdbPart& o) {
  if (this != &o) impl_->grid = o.impl_->grid ? o.impl_->grid->deepCopy() : nullptr;
  return *this;
}
VdbPart::VdbPart(VdbPart&&) noexcept = default;
VdbPart& VdbPart::operator=(VdbPart&&) noexcept = default;

bool VdbPart::empty() const { return !impl_ || !impl_->grid; }
double VdbPart::voxel_mm() const { return grid_of(*this).voxelSize()[0]; }
double VdbPart::half_width_mm() const { return grid_of(*this).background(); }
std::size_t VdbPart::memory_bytes() const { return empty() ? 0 : static_cast<std::size_t>(impl_->grid->memUsage()); }
std::size_t VdbPart::active_voxels() const {
  return empty() ? 0 : static_cast<std::size_t>(impl_->grid->activeVoxelCount());
}

VdbPart VdbPart::box(const Box& b, const VdbOptions& o) {
  check_options(o);
  vdb_initialize();
  if (!((b.hi - b.lo).array() > 0).all()) throw core::Error("vdb: the stock box is empty");
  const openvdb::math::BBox<openvdb::Vec3d> bb(openvdb::Vec3d(b.lo.x(), b.lo.y(), b.lo.z()),
                                               openvdb::Vec3d(b.hi.x(), b.hi.y(), b.hi.z()));
  return vdb_wrap(openvdb::tools::createLevelSetBox<Grid>(
      bb, *vdb_transform(o.voxel_mm, stock_origin(o.voxel_mm, b.lo)), o.half_width_voxels));
}

VdbPart VdbPart::mesh(const core::TriangleMesh& m, const VdbOptions& o, const std::string& source) {
  check_options(o);
  core::check_closed(m, source);
  vdb_initialize();
  const auto xf = vdb_transform(o.voxel_mm, stock_origin(o.voxel_mm, m.vertices_mm.colwise().minCoeff().transpose()));
  std::vector<openvdb::Vec3s> pts(static_cast<std::size_t>(m.vertices_mm.rows()));
  for (Eigen::Index k = 0; k < m.vertices_mm.rows(); ++k) {
    // meshToLevelSet takes world points in float: 1e-7 relative, 0.01 um at 100 mm.
    pts[static_cast<std::size_t>(k)] =
        openvdb::Vec3s(xf->worldToIndex(openvdb::Vec3d(m.vertices_mm(k, 0), m.vertices_mm(k, 1), m.vertices_mm(k, 2))));
  }
  std::vector<openvdb::Vec3I> tris;
  tris.reserve(static_cast<std::size_t>(m.triangles.rows()));
  for (Eigen::Index k = 0; k < m.triangles.rows(); ++k) {
    const int a = m.triangles(k, 0), b = m.triangles(k, 1), c = m.triangles(k, 2);
    if (a == b || b == c || a == c) continue;  // no area (closed_mesh_problem ignores them too)
    tris.emplace_back(static_cast<unsigned>(a), static_cast<unsigned>(b), static_cast<unsigned>(c));
  }
  // Points are given in index space (meshToVolume's adapter convention), the transform places the grid.
  openvdb::tools::QuadAndTriangleDataAdapter<openvdb::Vec3s, openvdb::Vec3I> adapter(pts, tris);
  const float hw = static_cast<float>(o.half_width_voxels);
  return vdb_wrap(openvdb::tools::meshToVolume<Grid>(adapter, *xf, hw, hw));
}

namespace {

// One thread's ray reader: OpenVDB's intersector (it holds an accessor, so one per thread) and a trilinear sampler.
class RayReader {
 public:
  // The sampler keeps a pointer to the accessor it is given: the accessor is a member declared before it.
  explicit RayReader(const Grid& g)
      : g_(g), rx_(g), acc_(g.getConstAccessor()), sampler_(acc_, g.transform()), h_(g.voxelSize()[0]) {}

  double value(const Eigen::Vector3d& p) const {
    return static_cast<double>(sampler_.wsSample(openvdb::Vec3d(p.x(), p.y(), p.z())));
  }

  double first_crossing(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double length) const {
    auto f = [&](double t) { return value(o + t * u); };
    if (f(0) <= 0) return 0.0;
    const openvdb::math::Ray<double> ray(openvdb::Vec3d(o.x(), o.y(), o.z()), openvdb::Vec3d(u.x(), u.y(), u.z()), 0.0,
                                         length);
    openvdb::Vec3d xyz;
    if (!rx_.intersectsWS(ray, xyz)) return NAN;
    const double t = std::clamp((Eigen::Vector3d(xyz.x(), xyz.y(), xyz.z()) - o).dot(u), 0.0, length);
    // Bracket the crossing of the trilinear interpolant around the intersector's estimate, then bisect.
    double ta = std::max(0.0, t - h_), tb = std::min(length, t + h_);
    for (int k = 0; k < 4 && f(ta) <= 0 && ta > 0; ++k) ta = std::max(0.0, ta - h_);
    for (int k = 0; k < 4 && f(tb) > 0 && tb < length; ++k) tb = std::min(length, tb + h_);
    if (!(f(ta) > 0 && f(tb) <= 0)) return t;  // no clean bracket (a sliver thinner than a voxel): the estimate
    for (int k = 0; k < 60 && tb - ta > 1e-6 * h_; ++k) {
      const double mid = 0.5 * (ta + tb);
      (f(mid) > 0 ? ta : tb) = mid;
    }
    return 0.5 * (ta + tb);
  }

 private:
  const Grid& g_;
  openvdb::tools::LevelSetRayIntersector<Grid> rx_;
  Grid::ConstAccessor acc_;
  openvdb::tools::GridSampler<Grid::ConstAccessor, openvdb::tools::BoxSampler> sampler_;
  double h_;
};

}  // namespace

double VdbPart::first_crossing(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double length) const {
  const Grid& g = grid_of(*this);
  if (g.tree().activeVoxelCount() == 0) return NAN;  // no surface: everything was cut away
  return RayReader(g).first_crossing(o, u, length);
}

core::HeightGrid VdbPart::height_grid(const Box& region, double spacing) const {
  const Grid& g = grid_of(*this);
  const DexelGrid nodes = make_zmap(region, spacing);
  core::HeightGrid out;
  out.x0_mm = region.lo.x();
  out.y0_mm = region.lo.y();
  out.dx_mm = out.dy_mm = spacing;
  out.z_mm.resize(nodes.nv(), nodes.nu());
  // Rays start a voxel above the band's top and run down past its bottom.
  const openvdb::CoordBBox ib = g.evalActiveVoxelBoundingBox();
  if (ib.empty() || g.tree().activeVoxelCount() == 0) {
    out.z_mm.setConstant(NAN);
    return out;
  }
  const openvdb::Vec3d top = g.indexToWorld(ib.max().asVec3d() + openvdb::Vec3d(1.0));
  const openvdb::Vec3d bottom = g.indexToWorld(ib.min().asVec3d() - openvdb::Vec3d(1.0));
  const double z0 = top.z(), len = z0 - bottom.z();
#pragma omp parallel
  {
    const RayReader reader(g);
#pragma omp for schedule(dynamic, 4)
    for (int j = 0; j < nodes.nv(); ++j)
      for (int i = 0; i < nodes.nu(); ++i) {
        const Eigen::Vector3d o(region.lo.x() + i * spacing, region.lo.y() + j * spacing, z0);
        const double t = reader.first_crossing(o, -Eigen::Vector3d::UnitZ(), len);
        out.z_mm(j, i) = std::isnan(t) ? NAN : z0 - t;
      }
  }
  return out;
}

std::vector<double> VdbPart::needle_tops(const NeedleSet& n) const {
  const Grid& g = grid_of(*this);
  std::vector<double> top(n.size(), NAN);
  if (g.tree().activeVoxelCount() == 0) return top;
#pragma omp parallel
  {
    const RayReader reader(g);
#pragma omp for schedule(dynamic, 64)
    for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(n.size()); ++k) {
      const auto kk = static_cast<std::size_t>(k);
      // From the needle's far end backwards: the first crossing is its last material point.
      const double L = n.length(kk);
      const double t = reader.first_crossing(n.origin(kk) + L * n.direction(kk), -n.direction(kk), L);
      top[kk] = std::isnan(t) ? NAN : L - t;
    }
  }
  return top;
}

Eigen::VectorXd VdbPart::signed_distance(const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>& p) const {
  const Grid& g = grid_of(*this);
  const double bg = g.background();
  Eigen::VectorXd out(p.rows());
#pragma omp parallel
  {
    const Grid::ConstAccessor acc = g.getConstAccessor();  // the sampler keeps a pointer to it
    openvdb::tools::GridSampler<Grid::ConstAccessor, openvdb::tools::BoxSampler> sampler(acc, g.transform());
#pragma omp for schedule(static)
    for (Eigen::Index k = 0; k < p.rows(); ++k) {
      const double v = sampler.wsSample(openvdb::Vec3d(p(k, 0), p(k, 1), p(k, 2)));
      out[k] = std::abs(v) < bg * (1 - 1e-6) ? v : NAN;
    }
  }
  return out;
}

core::TriangleMesh VdbPart::mesh(double adaptivity) const {
  const Grid& g = grid_of(*this);
  if (!(adaptivity >= 0 && adaptivity <= 1))
    throw core::Error(fmt::format("vdb: mesh adaptivity must be in [0, 1], found {}", adaptivity));
  std::vector<openvdb::Vec3s> pts;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(g, pts, tris, quads, 0.0, adaptivity);
  core::TriangleMesh m;
  m.vertices_mm.resize(static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t k = 0; k < pts.size(); ++k)
    for (int c = 0; c < 3; ++c) m.vertices_mm(static_cast<Eigen::Index>(k), c) = pts[k][c];
  m.triangles.resize(static_cast<Eigen::Index>(tris.size() + 2 * quads.size()), 3);
  // volumeToMesh orders polygons clockwise seen from outside (negative inside); core meshes are counter-clockwise.
  Eigen::Index r = 0;
  for (const auto& t : tris)
    m.triangles.row(r++) << static_cast<int>(t[0]), static_cast<int>(t[2]), static_cast<int>(t[1]);
  for (const auto& q : quads) {
    m.triangles.row(r++) << static_cast<int>(q[0]), static_cast<int>(q[2]), static_cast<int>(q[1]);
    m.triangles.row(r++) << static_cast<int>(q[0]), static_cast<int>(q[3]), static_cast<int>(q[2]);
  }
  return m;
}

double VdbPart::volume_mm3() const { return openvdb::tools::levelSetVolume(grid_of(*this), true); }

void VdbPart::write_vdb(const std::filesystem::path& path) const {
  const Grid& g = grid_of(*this);
  vdb_initialize();
  std::random_device rd;
  const std::filesystem::path tmp =
      path.parent_path() / ("." + path.filename().string() + ".tmp" + std::to_string(rd()));
  try {
    // A new grid object sharing the tree: the metadata goes on the copy only.
    openvdb::GridPtrVec grids{std::const_pointer_cast<openvdb::GridBase>(g.copyGrid())};
    grids[0]->insertMeta("units", openvdb::StringMetadata("mm"));
    grids[0]->insertMeta("writer", openvdb::StringMetadata("vmsim"));
    openvdb::io::File file(tmp.string());
    file.write(grids);
    file.close();
  } catch (const openvdb::Exception& e) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw core::Error(path.string() + ": cannot write the level set: " + e.what());
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw core::Error(path.string() + ": cannot rename the written level set into place");
  }
}

VdbPart VdbPart::read_vdb(const std::filesystem::path& path) {
  vdb_initialize();
  openvdb::GridPtrVecPtr grids;
  try {
    openvdb::io::File file(path.string());
    file.open();
    grids = file.getGrids();
    file.close();
  } catch (const openvdb::Exception& e) {
    throw core::Error(path.string() + ": cannot read the level set: " + e.what());
  }
  for (const auto& base : *grids) {
    auto g = openvdb::gridPtrCast<Grid>(base);
    if (!g || g->getGridClass() != openvdb::GRID_LEVEL_SET) continue;
    if (!g->hasUniformVoxels()) throw core::Error(path.string() + ": the level set's voxels are not cubes");
    return vdb_wrap(g);
  }
  throw core::Error(path.string() + ": no float level-set grid in the file");
}

double estimate_level_set_bytes(const SurfaceArea& s, double h, double hw) {
  using Node1 = Grid::TreeType::RootNodeType::ChildNodeType::ChildNodeType;
  using Node2 = Grid::TreeType::RootNodeType::ChildNodeType;
  const double leaf_bytes = Grid::TreeType::LeafNodeType::SIZE * sizeof(float) + sizeof(Grid::TreeType::LeafNodeType);
  // Nodes of side n voxels a surface meets: (T A + n P) / (n^3 h^2) (vdb_part.hpp).
  const double T = 2 * hw;
  auto nodes = [&](double n) { return (T * s.area_mm2 + n * s.projected_mm2) / (n * n * n * h * h); };
  return nodes(8) * leaf_bytes + std::max(1.0, nodes(128)) * sizeof(Node1) + std::max(1.0, nodes(4096)) * sizeof(Node2);
}

SurfaceArea surface_area(const core::TriangleMesh& m) {
  SurfaceArea s;
  for (Eigen::Index k = 0; k < m.triangles.rows(); ++k) {
    const Eigen::Vector3d p0 = m.vertices_mm.row(m.triangles(k, 0)).transpose(),
                          p1 = m.vertices_mm.row(m.triangles(k, 1)).transpose(),
                          p2 = m.vertices_mm.row(m.triangles(k, 2)).transpose();
    const Eigen::Vector3d n2 = (p1 - p0).cross(p2 - p0);  // twice the area along the normal
    s.area_mm2 += 0.5 * n2.norm();
    s.projected_mm2 += 0.5 * n2.cwiseAbs().sum();
  }
  return s;
}

SurfaceArea surface_area(const Box& b) {
  const Eigen::Vector3d e = b.hi - b.lo;
  SurfaceArea s;
  s.area_mm2 = s.projected_mm2 = 2 * (e.x() * e.y() + e.y() * e.z() + e.z() * e.x());
  return s;
}

double estimate_mesh_bytes(double area, double h) {
  // Per surface voxel: a float point (12 B) and a quad (16 B) from volumeToMesh, then a double vertex (24 B) and two
  // int triangles (24 B), plus a deviation scalar (8 B).
  return area / (h * h) * 84.0;
}

double mesh_area_mm2(const core::TriangleMesh& m) {
  double a = 0;
  for (Eigen::Index k = 0; k < m.triangles.rows(); ++k) {
    const Eigen::Vector3d p0 = m.vertices_mm.row(m.triangles(k, 0)).transpose(),
                          p1 = m.vertices_mm.row(m.triangles(k, 1)).transpose(),
                          p2 = m.vertices_mm.row(m.triangles(k, 2)).transpose();
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

}  // namespace vmsim::removal
