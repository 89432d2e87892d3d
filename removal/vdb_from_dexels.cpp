// VdbPart::from_tridexel: a tri-dexel part as a narrow-band level set, so that it can be meshed (closed and manifold,
// by the same volumeToMesh as the OpenVDB kernel), written as .vdb and compared with the level-set kernel.
//
// Why a level set rather than dual contouring of the dexel Hermite data: dexels store where each ray enters and
// leaves the material, not the surface normal there. Dual contouring needs normals to place its vertices on sharp
// features; estimated from neighbouring rays they are wrong exactly at the edges it should keep. A level set needs
// only distances, which the crossings give, and OpenVDB then supplies a tested mesher (closed, manifold, multiple
// vertices per ambiguous cell), .vdb I/O and measures. The cost is that volumeToMesh places a cell's vertex at the
// mean of its edge crossings, which cuts a 90 degree edge by up to ~0.35 voxel (tests/removal/vdb_test.cpp measures
// it on a box and on the corner part).
//
// One voxel per dexel node (the three grids share origin and spacing h, as make_tridexel makes them). At a node:
//   inside  = majority of its three rays' material at the node (closed intervals);
//   d_x, d_y, d_z = distance along each ray to the nearest interval end (a surface crossing), or none within
//            ceil(sqrt 3 hw) + 1 voxels;
//   phi     = -+ 1 / sqrt(1/d_x^2 + 1/d_y^2 + 1/d_z^2): exact for a plane (d_i = d / |n_i|), and so the linear
//            interpolation between two nodes puts the surface exactly on the ray's crossing wherever the surface is
//            locally planar over the two nodes.
// Nodes up to hw + 1 voxels beyond the lattice (outside the field's region, hence outside the material) are
// included, so material touching the region's boundary gets its face. The interior is then signed by OpenVDB's
// signedFloodFill. Leaves are built in parallel and added in a fixed order: thread-count independent.
#include "removal/vdb_grid.hpp"

#include "core/error.hpp"

#include <openvdb/tools/Prune.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <fmt/format.h>

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::removal {

namespace {

using Grid = openvdb::FloatGrid;
using Leaf = Grid::TreeType::LeafNodeType;

// All interval ends of one dexel grid, ray by ray, flat.
struct Ends {
  std::vector<std::size_t> offset;  // rays + 1
  std::vector<float> t;

  explicit Ends(const DexelGrid& g) {
    offset.assign(static_cast<std::size_t>(g.nu()) * g.nv() + 1, 0);
    std::vector<Interval> iv;
    for (int j = 0; j < g.nv(); ++j)
      for (int i = 0; i < g.nu(); ++i) {
        g.intervals(i, j, iv);
        for (const Interval& x : iv) t.insert(t.end(), {x.lo, x.hi});
        offset[g.ray(i, j) + 1] = t.size();
      }
  }
  std::pair<const float*, const float*> ray(std::size_t r) const {
    return {t.data() + offset[r], t.data() + offset[r + 1]};
  }
};

bool is_inside(const float* b, const float* e, double t) {
  // Ends are lo0 hi0 lo1 hi1 ...: inside a closed interval iff an odd number of ends lies below t, or t is an end.
  const float* it = std::upper_bound(b, e, static_cast<float>(t));
  if (((it - b) & 1) == 1) return true;
  return it != b && static_cast<double>(*(it - 1)) == t;
}

double nearest_end(const float* b, const float* e, double t) {
  const float* it = std::lower_bound(b, e, static_cast<float>(t));
  double d = std::numeric_limits<double>::infinity();
  if (it != e) d = std::abs(static_cast<double>(*it) - t);
  if (it != b) d = std::min(d, std::abs(static_cast<double>(*(it - 1)) - t));
  if (it + 1 < e) d = std::min(d, std::abs(static_cast<double>(*(it + 1)) - t));
  return d;
}

}  // namespace

VdbPart VdbPart::from_tridexel(const TriDexel& f, double hw) {
  if (!(hw >= 2)) throw core::Error(fmt::format("vdb: the band half width must be >= 2 voxels, found {}", hw));
  const double h = f.z.du();
  const int NX = f.z.nu(), NY = f.z.nv(), NZ = f.x.nv();
  auto same = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return (a - b).norm() <= 1e-12; };
  const bool lattice = f.x.du() == h && f.x.dv() == h && f.y.du() == h && f.y.dv() == h && f.z.dv() == h &&
                       same(f.x.origin(), f.z.origin()) && same(f.y.origin(), f.z.origin()) &&
                       same(f.x.U(), Eigen::Vector3d::UnitY()) && same(f.x.V(), Eigen::Vector3d::UnitZ()) &&
                       same(f.y.U(), Eigen::Vector3d::UnitZ()) && same(f.y.V(), Eigen::Vector3d::UnitX()) &&
                       same(f.z.U(), Eigen::Vector3d::UnitX()) && same(f.z.V(), Eigen::Vector3d::UnitY()) &&
                       f.x.nu() == NY && f.y.nu() == NZ && f.y.nv() == NX;
  if (!lattice) throw core::Error("vdb: the tri-dexel grids do not share one lattice (make_tridexel makes them so)");
  vdb_initialize();
  const Ends ex(f.x), ey(f.y), ez(f.z);
  const float bg = static_cast<float>(hw * h);
  const int D = static_cast<int>(std::ceil(std::sqrt(3.0) * hw)) + 1;  // nodes a crossing can be within hw of
  const double cap = (D + 1) * h;
  // Lattice node (i, j, k) is voxel (i, j, k) + O: the band (down to -D - 8) keeps positive indices, inside one
  // 4096^3 top-level node instead of straddling index 0 where 8 of them (264 kB each) meet.
  constexpr int O = 16;

  // 1. Leaves holding nodes within D of a crossing along some ray (thread-local masks, then their union).
  const int nthreads = omp_get_max_threads();
  std::vector<openvdb::MaskTree> masks(static_cast<std::size_t>(nthreads));
  auto mark = [&](openvdb::MaskTree& m, int axis, int a, int b, double t) {
    // Nodes n along the ray with |n h - t| <= D h; a, b are the ray's other two lattice coordinates.
    const int n0 = static_cast<int>(std::floor(t / h)) - D, n1 = static_cast<int>(std::ceil(t / h)) + D;
    for (int n = (n0 + O) & ~7; n <= n1 + O; n += 8) {
      openvdb::Coord c;
      c[axis] = n;
      c[(axis + 1) % 3] = a + O;
      c[(axis + 2) % 3] = b + O;
      m.setValueOn(c & ~7);
    }
  };
#pragma omp parallel
  {
    openvdb::MaskTree& m = masks[static_cast<std::size_t>(omp_get_thread_num())];
#pragma omp for schedule(static)
    for (int k = 0; k < NZ; ++k)
      for (int j = 0; j < NY; ++j) {  // X rays: (j, k), along x
        auto [b, e] = ex.ray(f.x.ray(j, k));
        for (const float* p = b; p != e; ++p) mark(m, 0, j, k, *p);
      }
#pragma omp for schedule(static)
    for (int i = 0; i < NX; ++i)
      for (int k = 0; k < NZ; ++k) {  // Y rays: (k, i), along y; axis order y, z, x
        auto [b, e] = ey.ray(f.y.ray(k, i));
        for (const float* p = b; p != e; ++p) mark(m, 1, k, i, *p);
      }
#pragma omp for schedule(static)
    for (int j = 0; j < NY; ++j)
      for (int i = 0; i < NX; ++i) {  // Z rays: (i, j), along z; axis order z, x, y
        auto [b, e] = ez.ray(f.z.ray(i, j));
        for (const float* p = b; p != e; ++p) mark(m, 2, i, j, *p);
      }
  }
  for (std::size_t t = 1; t < masks.size(); ++t) masks[0].topologyUnion(masks[t]);
  std::vector<openvdb::Coord> origins;
  for (auto it = masks[0].cbeginLeaf(); it; ++it) origins.push_back(it->origin());
  masks.clear();

  // 2. Node values, leaf by leaf.
  auto in_lattice = [&](int i, int j, int k) { return i >= 0 && i < NX && j >= 0 && j < NY && k >= 0 && k < NZ; };
  std::vector<Leaf*> leaves(origins.size(), nullptr);
#pragma omp parallel for schedule(dynamic, 16)
  for (std::ptrdiff_t li = 0; li < static_cast<std::ptrdiff_t>(origins.size()); ++li) {
    const openvdb::Coord o = origins[static_cast<std::size_t>(li)];
    auto leaf = std::make_unique<Leaf>(o, bg, false);
    bool any = false;
    for (openvdb::Index n = 0; n < Leaf::SIZE; ++n) {
      const openvdb::Coord c = leaf->offsetToGlobalCoord(n);
      const int i = c.x() - O, j = c.y() - O, k = c.z() - O;
      double inv2 = 0;  // sum of 1 / d^2
      bool on_surface = false;
      int votes = 0;
      auto ray = [&](const Ends& ends, const DexelGrid& g, int u, int v, int nu, int nv, int along) {
        if (u < 0 || u >= nu || v < 0 || v >= nv) return;
        auto [b, e] = ends.ray(g.ray(u, v));
        const double t = along * h;
        const double d = nearest_end(b, e, t);
        if (d == 0)
          on_surface = true;
        else if (d <= cap)
          inv2 += 1 / (d * d);
        votes += is_inside(b, e, t) ? 1 : 0;
      };
      ray(ex, f.x, j, k, NY, NZ, i);
      ray(ey, f.y, k, i, NZ, NX, j);
      ray(ez, f.z, i, j, NX, NY, k);
      if (!on_surface && inv2 == 0) continue;
      const bool inside = in_lattice(i, j, k) && votes >= 2;
      // A node exactly on the surface gets 0, which volumeToMesh (inside: phi < 0) counts as outside. Faces at round
      // coordinates fall on the nodes of a field whose region is the stock's box; edges through such nodes are then
      // bevelled by up to h/2, and 3-face corners by up to 2h/3 (tests/removal/vdb_test.cpp measures it). Calling
      // such nodes inside (a tiny negative value) would keep those edges, but the surface nodes that float offsets
      // put a few ulps off the node then flip, and grazing rays (closed intervals along a face) make outside nodes
      // look inside: tried, and the meshes got worse.
      const double phi = on_surface ? 0.0 : (inside ? -1.0 : 1.0) / std::sqrt(inv2);
      if (std::abs(phi) >= bg) {
        leaf->setValueOnly(n, inside ? -bg : bg);
        continue;
      }
      leaf->setValueOn(n, static_cast<float>(phi));
      any = true;
    }
    if (any) leaves[static_cast<std::size_t>(li)] = leaf.release();
  }

  auto grid = Grid::create(bg);
  grid->setTransform(vdb_transform(h, f.z.origin() - Eigen::Vector3d::Constant(O * h)));
  for (Leaf* l : leaves)
    if (l) grid->tree().addLeaf(l);
  openvdb::tools::signedFloodFill(grid->tree());
  openvdb::tools::pruneLevelSet(grid->tree());
  return vdb_wrap(grid);
}

}  // namespace vmsim::removal
