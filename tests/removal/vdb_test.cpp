// The OpenVDB level-set kernel (removal/vdb_*) against analytic references:
//   - SweepDistance against tests/removal/tool_reference.hpp's independent swept_sd (the body's exact distance,
//     minimised over the move by golden section): equal outside the sweep; inside, at least as deep as the deepest
//     single pose and no deeper than the nearest point of the sweep's boundary found by bisection;
//   - meshes of cut parts closed and manifold (every edge used by exactly two triangles, once in each direction; one
//     fan per vertex; Euler characteristic 2 per component), their volumes (divergence theorem, independent of
//     OpenVDB's levelSetVolume) against the exact volumes of a box, a flat-end slot, a ball-end slot (circular
//     segment) and a flat-end pocket (rectangle grown by the tool radius);
//   - every mesh vertex within a stated fraction of a voxel of the exact surface (max of the stock's and minus the
//     sweeps' exact distances);
//   - heights by ray casting against the groove circle; a tilted (5-axis) tool against the exact reference;
//   - thread-count independence, .vdb round trip, STL stock = box stock, the memory estimate.
#include "core/stl.hpp"
#include "removal/fields.hpp"
#include "removal/track.hpp"
#include "removal/vdb_part.hpp"
#include "removal/vdb_sweep.hpp"
#include "tool_reference.hpp"

#include "core/error.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <random>
#include <set>

using namespace vmsim::removal;
using vmsim::core::TriangleMesh;

namespace {

using vmsim::core::units::kPi;

Tool make(double R, double rc, double L = 40) {
  Tool t;
  t.radius_mm = R;
  t.corner_radius_mm = rc;
  t.length_mm = L;
  return t;
}

SweptTool vdb_line(const Tool& t, Eigen::Vector3d a, Eigen::Vector3d b,
                   Eigen::Vector3d axis = Eigen::Vector3d::UnitZ()) {
  SweptTool s;
  s.tool = t;
  s.tip0 = a;
  s.d = b - a;
  s.axis = axis.normalized();
  return s;
}

Box vdb_box(double x0, double y0, double z0, double x1, double y1, double z1) {
  return Box{Eigen::Vector3d(x0, y0, z0), Eigen::Vector3d(x1, y1, z1)};
}

// Exact signed distance to a box (negative inside).
double box_sd(const Box& b, const Eigen::Vector3d& p) {
  const Eigen::Vector3d c = 0.5 * (b.lo + b.hi), e = 0.5 * (b.hi - b.lo);
  const Eigen::Vector3d q = (p - c).cwiseAbs() - e;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

struct Topology {
  long V = 0, E = 0, F = 0;
  int components = 0;
  long bad_edges = 0;     // edges not used by exactly two triangles in opposite directions
  long bad_vertices = 0;  // vertices whose triangles do not form one closed fan (or are unused)
  long chi() const { return V - E + F; }
};

// Topology of a triangle mesh, written from the definitions (no code shared with core::closed_mesh_problem).
Topology topology(const TriangleMesh& m) {
  Topology t;
  t.V = m.vertices_mm.rows();
  t.F = m.triangles.rows();
  std::map<std::pair<int, int>, int> directed;
  for (Eigen::Index f = 0; f < m.triangles.rows(); ++f)
    for (int e = 0; e < 3; ++e) ++directed[{m.triangles(f, e), m.triangles(f, (e + 1) % 3)}];
  std::set<std::pair<int, int>> undirected;
  for (const auto& [k, n] : directed) {
    undirected.insert({std::min(k.first, k.second), std::max(k.first, k.second)});
    const auto rev = directed.find({k.second, k.first});
    if (n != 1 || rev == directed.end() || rev->second != 1) ++t.bad_edges;
  }
  t.E = static_cast<long>(undirected.size());
  // Fans: around vertex v, each triangle (v, a, b) links a -> b; a closed disk is one cycle through all of them.
  std::vector<std::map<int, int>> next(static_cast<std::size_t>(t.V));
  std::vector<int> count(static_cast<std::size_t>(t.V), 0);
  for (Eigen::Index f = 0; f < m.triangles.rows(); ++f)
    for (int e = 0; e < 3; ++e) {
      const int v = m.triangles(f, e), a = m.triangles(f, (e + 1) % 3), b = m.triangles(f, (e + 2) % 3);
      next[static_cast<std::size_t>(v)][a] = b;
      ++count[static_cast<std::size_t>(v)];
    }
  for (std::size_t v = 0; v < next.size(); ++v) {
    if (count[v] == 0 || static_cast<int>(next[v].size()) != count[v]) {
      ++t.bad_vertices;
      continue;
    }
    const int start = next[v].begin()->first;
    int a = start, steps = 0;
    do {
      const auto it = next[v].find(a);
      if (it == next[v].end()) break;
      a = it->second;
      ++steps;
    } while (a != start && steps <= count[v]);
    if (a != start || steps != count[v]) ++t.bad_vertices;
  }
  // Components (union-find over triangle edges).
  std::vector<int> parent(static_cast<std::size_t>(t.V));
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<int>(i);
  auto find = [&](int x) {
    while (parent[static_cast<std::size_t>(x)] != x)
      x = parent[static_cast<std::size_t>(x)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
    return x;
  };
  for (const auto& e : undirected) parent[static_cast<std::size_t>(find(e.first))] = find(e.second);
  for (std::size_t i = 0; i < parent.size(); ++i) t.components += find(static_cast<int>(i)) == static_cast<int>(i);
  return t;
}

// Volume by the divergence theorem (sum of signed tetrahedra from the origin).
double mesh_volume(const TriangleMesh& m) {
  double v = 0;
  for (Eigen::Index f = 0; f < m.triangles.rows(); ++f) {
    const Eigen::Vector3d a = m.vertices_mm.row(m.triangles(f, 0)).transpose(),
                          b = m.vertices_mm.row(m.triangles(f, 1)).transpose(),
                          c = m.vertices_mm.row(m.triangles(f, 2)).transpose();
    v += a.dot(b.cross(c)) / 6;
  }
  return v;
}

// Exact signed distance of the machined part: max(stock, -sweep_k) with the reference's sweep distances. Outside
// every sweep the reference is the exact distance; near a cut surface the point lies within the distance of it.
double part_sd(const Box& stock, const std::vector<SweptTool>& sweeps, const Eigen::Vector3d& p) {
  double v = box_sd(stock, p);
  for (const SweptTool& s : sweeps) v = std::max(v, -testref::swept_sd(s.tool, s.tip0, s.axis, s.d, p));
  return v;
}

void expect_closed_manifold(const TriangleMesh& m, const char* what) {
  const Topology t = topology(m);
  EXPECT_GT(t.F, 0) << what;
  EXPECT_EQ(t.bad_edges, 0) << what;
  EXPECT_EQ(t.bad_vertices, 0) << what;
  EXPECT_EQ(t.chi(), 2 * t.components) << what << ": V " << t.V << " E " << t.E << " F " << t.F;
  EXPECT_EQ(t.components, 1) << what;
}

double max_vertex_error(const TriangleMesh& m, const Box& stock, const std::vector<SweptTool>& sweeps) {
  double worst = 0;
#pragma omp parallel for reduction(max : worst)
  for (Eigen::Index k = 0; k < m.vertices_mm.rows(); ++k)
    worst = std::max(worst, std::abs(part_sd(stock, sweeps, m.vertices_mm.row(k).transpose())));
  return worst;
}

VdbOptions voxel(double h) {
  VdbOptions o;
  o.voxel_mm = h;
  return o;
}

// The tolerances, stated once for every analytic case (h = voxel size):
//   vertex: volumeToMesh puts a vertex at the mean of its cell's edge crossings, each on the trilinear interpolant of
//           exact distances; on a plane that is exact, but in a cell across a 90-degree edge the mean of the
//           crossings on the two faces lies inside, about h/3 off each face, and more where three faces meet (a
//           pocket's floor at its rounded wall): we allow h/2;
//   volume: the planes are exact, so the error is the material the mesh's bevels add or cut along the sharp edges:
//           a bevel of legs <= h/3 over the edge's length gives at most (h/3)^2 / 2 per mm; with trilinear crossings
//           near the edge on top, we allow 0.3 h^2 per mm of sharp edge (mesh and levelSetVolume alike), which a
//           uniform offset of the faces by 0.01 h would already exceed on these parts.
constexpr double kVertexTol = 0.5;        // x h (measured: 1/3 on 90-degree edges, up to 0.44 where three faces meet)
constexpr double kVolumePerEdge = 0.3;    // x h^2 per mm of sharp edge
constexpr double kAdaptivePerEdge = 1.0;  // the same for meshes at adaptivity 0.1 (see below)

}  // namespace

// SweepDistance = the independent reference outside the sweep, for ball, flat and bull-nose ends, on level, plunging,
// oblique and tilted moves; inside, between the deepest single pose (a lower bound on the depth) and the distance to
// a boundary point found by bisection along a random direction (an upper bound).
TEST(VdbSweep, SignedDistanceAgreesWithTheIndependentReference) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  const Tool tools[] = {make(5, 5, 30), make(5, 0, 30), make(5, 1.5, 30)};
  const Eigen::Vector3d moves[] = {{20, 0, 0}, {0, 0, -8}, {12, 5, -4}, {0, 0, 0}, {7, -3, 9}};
  const Eigen::Vector3d axes[] = {Eigen::Vector3d::UnitZ(), Eigen::Vector3d(0.3, -0.2, 1).normalized(),
                                  Eigen::Vector3d(1, 0.2, 0.4).normalized()};
  double worst_out = 0, worst_lo = 0, worst_hi = 0;
  int inside = 0, outside = 0;
  for (const Tool& t : tools)
    for (const Eigen::Vector3d& d : moves)
      for (const Eigen::Vector3d& a : axes) {
        const SweptTool s = vdb_line(t, {1, 2, 3}, Eigen::Vector3d(1, 2, 3) + d, a);
        const SweepDistance sd(s);
        for (int k = 0; k < 400; ++k) {
          const Eigen::Vector3d p = Eigen::Vector3d(1, 2, 3) + 0.5 * d + 0.5 * t.length_mm * a +
                                    Eigen::Vector3d(U(rng), U(rng), U(rng)) * (0.5 * d.norm() + 0.5 * t.length_mm + 4);
          const double got = sd(p), ref = testref::swept_sd(t, s.tip0, s.axis, s.d, p);
          if (ref > 0) {
            ++outside;
            worst_out = std::max(worst_out, std::abs(got - ref));
            continue;
          }
          ++inside;
          worst_lo = std::max(worst_lo, got - ref);  // got <= ref: at least as deep as the deepest pose
          // Upper bound on the depth: bisection to the boundary along a random direction.
          Eigen::Vector3d u(U(rng), U(rng), U(rng));
          u.normalize();
          double lo = 0, hi = 100;
          for (int it = 0; it < 80; ++it) {
            const double mid = 0.5 * (lo + hi);
            (testref::swept_sd(t, s.tip0, s.axis, s.d, p + mid * u) <= 0 ? lo : hi) = mid;
          }
          worst_hi = std::max(worst_hi, -got - hi);
        }
      }
  EXPECT_GT(inside, 500);
  EXPECT_GT(outside, 500);
  EXPECT_LT(worst_out, 1e-8);
  EXPECT_LT(worst_lo, 1e-8);
  EXPECT_LT(worst_hi, 1e-8);
}

// A box stock: the mesh is closed and manifold, the volume that of the box, vertices on its faces.
TEST(VdbKernel, BoxStockMeshIsClosedWithTheBoxVolume) {
  const double h = 0.25;
  const Box b = vdb_box(0, 0, 0, 20, 10, 8);
  const VdbPart part = VdbPart::box(b, voxel(h));
  const TriangleMesh m = part.mesh(0.0);
  expect_closed_manifold(m, "box");
  const double exact = 20 * 10 * 8;
  EXPECT_NEAR(mesh_volume(m), exact, kVolumePerEdge * h * h * 4 * (20 + 10 + 8));
  EXPECT_NEAR(part.volume_mm3(), exact, kVolumePerEdge * h * h * 4 * (20 + 10 + 8));
  EXPECT_LT(max_vertex_error(m, b, {}), kVertexTol * h);
}

struct VdbCase {
  const char* name;
  Box stock;
  std::vector<SweptTool> sweeps;
  double removed_mm3;  // exact
  double edges_mm;     // total length of the part's sharp edges (for the volume tolerance)
};

std::vector<VdbCase> analytic_cases() {
  std::vector<VdbCase> cases;
  const Box stock = vdb_box(0, 0, 0, 40, 20, 10);
  const double stock_edges = 4 * (40 + 20 + 10);
  {  // Flat end R 3 along X, 2 mm deep, through the whole stock: a 6 x 2 rectangular slot.
    cases.push_back(
        {"flat slot", stock, {vdb_line(make(3, 0), {-10, 10, 8}, {50, 10, 8})}, 6 * 2 * 40.0, stock_edges + 4 * 40.0});
  }
  {  // Ball end R 3, tip 2 mm below the top: a circular segment (chord 1 mm from the centre).
    const double R = 3, dd = 1, seg = R * R * std::acos(dd / R) - dd * std::sqrt(R * R - dd * dd);
    cases.push_back(
        {"ball slot", stock, {vdb_line(make(3, 3), {-10, 10, 8}, {50, 10, 8})}, seg * 40, stock_edges + 2 * 40.0});
  }
  {  // Flat end R 3, 3 mm deep: a zigzag over the rectangle [12, 28] x [7, 13] (stepover 2 < 2R) and a contour of
     // it; the pocket is the rectangle grown by R: 22 x 12 with corners of radius 3.
    const Tool t = make(3, 0);
    const double z = 7;
    std::vector<Eigen::Vector3d> pts = {{12, 7, z},  {28, 7, z},  {28, 9, z},  {12, 9, z}, {12, 11, z},
                                        {28, 11, z}, {28, 13, z}, {12, 13, z}, {12, 7, z}};
    std::vector<SweptTool> s;
    for (std::size_t k = 0; k + 1 < pts.size(); ++k) s.push_back(vdb_line(t, pts[k], pts[k + 1]));
    s.push_back(vdb_line(t, {28, 7, z}, {28, 13, z}));
    const double area2d = 22 * 12 - (4 - kPi) * 9, perim = 2 * (16 + 6) + 2 * kPi * 3;
    cases.push_back({"flat pocket", stock, s, 3 * area2d, stock_edges + 2 * perim});
  }
  return cases;
}

// Slots and a pocket at two voxel sizes: closed, manifold meshes, the exact volume within the stated tolerance (mesh
// and levelSetVolume), every vertex within h/3 of the exact surface; the volume error falls with h^2 (the bevels).
TEST(VdbKernel, SlotsAndPocketHaveTheExactVolume) {
  for (const VdbCase& c : analytic_cases()) {
    double err[2] = {0, 0};
    int n = 0;
    for (double h : {0.4, 0.2}) {
      VdbPart part = VdbPart::box(c.stock, voxel(h));
      part.cut(c.sweeps);
      const TriangleMesh m = part.mesh(0.0);
      const std::string what = std::string(c.name) + " h " + std::to_string(h);
      expect_closed_manifold(m, what.c_str());
      const Eigen::Vector3d e = c.stock.hi - c.stock.lo;
      const double exact = e.prod() - c.removed_mm3, tol = kVolumePerEdge * h * h * c.edges_mm;
      const double vm = mesh_volume(m) - exact, vl = part.volume_mm3() - exact,
                   ve = max_vertex_error(m, c.stock, c.sweeps);
      EXPECT_LT(std::abs(vm), tol) << what;
      EXPECT_LT(std::abs(vl), tol) << what;
      EXPECT_LT(ve, kVertexTol * h) << what;
      err[n++] = std::abs(vm);
      // Adaptive meshing merges flat regions but stays closed and within the same volume tolerance.
      // Adaptive meshing (0.1) merges flat regions into large polygons; the mesh stays closed and manifold, its
      // vertices as close, but the bevels along edges widen where big polygons meet them: measured 0.2-0.6 h^2 per
      // mm of edge at adaptivity 0.01-0.2 (1.1-1.25 at 0.5), so the adaptive tolerance is kAdaptivePerEdge.
      const TriangleMesh ma = part.mesh(0.1);
      expect_closed_manifold(ma, (what + " adaptive").c_str());
      EXPECT_LT(ma.triangles.rows(), m.triangles.rows() / 4) << what;
      EXPECT_LT(std::abs(mesh_volume(ma) - exact), kAdaptivePerEdge * h * h * c.edges_mm) << what;
      EXPECT_LT(max_vertex_error(ma, c.stock, c.sweeps), kVertexTol * h) << what;
      std::printf(
          "%s: volume error %.4f mm3 (mesh) %.4f (levelSetVolume) %.4f (adaptive 0.1), tolerance %.4f; "
          "vertex error %.4f h; triangles %ld, adaptive %ld\n",
          what.c_str(), vm, vl, mesh_volume(ma) - exact, tol, ve / h, static_cast<long>(m.triangles.rows()),
          static_cast<long>(ma.triangles.rows()));
    }
    EXPECT_GT(err[0] / err[1], 2.5) << c.name << ": the volume error should fall as h^2";
  }
}

// Heights by ray casting the level set: one ball-end pass leaves the groove circle z = z_tip + R - sqrt(R^2 - dy^2).
// Away from the groove's rims (2 voxels), the trilinear interpolant of exact distances to a cylinder of radius R
// puts the crossing within h^2 / (2 R) of it (the distance's second derivative across the surface is <= 1/R); the
// flat top is exact. Within the rims (the CSG max of two distances) the error is bounded by the vertex tolerance.
TEST(VdbKernel, HeightsOfABallPassFollowTheGrooveCircle) {
  const double h = 0.1, R = 3, top = 10, z_tip = 8, y0 = 10;
  const Box stock = vdb_box(0, 0, 0, 20, 20, top);
  VdbPart part = VdbPart::box(stock, voxel(h));
  part.cut({vdb_line(make(R, R), {-10, y0, z_tip}, {30, y0, z_tip})});
  const vmsim::core::HeightGrid g = part.height_grid(vdb_box(2, 2, 0, 18, 18, top), 0.13);
  const double rim = std::sqrt(R * R - (z_tip + R - top) * (z_tip + R - top));
  double worst_smooth = 0, worst_rim = 0;
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i) {
      const double dy = g.y(j) - y0;
      const double expected = std::abs(dy) < rim ? z_tip + R - std::sqrt(R * R - dy * dy) : top;
      const double err = std::abs(g.z_mm(j, i) - expected);
      double& worst = std::abs(std::abs(dy) - rim) > 2 * h ? worst_smooth : worst_rim;
      worst = std::max(worst, err);
    }
  std::printf("groove: worst %.2e mm away from the rims (bound %.2e), %.2e within 2 voxels of them\n", worst_smooth,
              h * h / (2 * R), worst_rim);
  EXPECT_LT(worst_smooth, h * h / (2 * R));
  EXPECT_LT(worst_rim, kVertexTol * h);
}

// A tilted flat end and a tilted bull-nose (constant orientation, 5-axis positioning) on straight oblique moves: the
// mesh is closed and every vertex within h/2 of the exact surface (the reference's distances to the tilted sweeps).
TEST(VdbKernel, TiltedToolsCutTheExactSweep) {
  const double h = 0.2;
  const Box stock = vdb_box(0, 0, 0, 30, 20, 10);
  const std::vector<SweptTool> sweeps = {
      vdb_line(make(4, 0, 30), {-5, 6, 8.5}, {35, 8, 7.0}, Eigen::Vector3d(0.4, -0.3, 1)),
      vdb_line(make(3, 1, 30), {10, -5, 9}, {16, 25, 6.5}, Eigen::Vector3d(-0.5, 0.2, 1)),
      vdb_line(make(3, 1, 30), {22, 10, 12}, {22, 10, 4}, Eigen::Vector3d(0.3, 0.3, 1))};  // a tilted plunge
  VdbPart part = VdbPart::box(stock, voxel(h));
  part.cut(sweeps);
  const TriangleMesh m = part.mesh(0.0);
  expect_closed_manifold(m, "tilted");
  const double ve = max_vertex_error(m, stock, sweeps);
  std::printf("tilted tools: vertex error %.3f h\n", ve / h);
  EXPECT_LT(ve, kVertexTol * h);
}

// The cut does not depend on the thread count: bit-identical level sets (sampled at every voxel centre of the
// region, and the meshes) with 1 and 2 threads.
TEST(VdbKernel, ResultDoesNotDependOnTheThreadCount) {
  const std::vector<VdbCase> cases = analytic_cases();
  std::vector<TriangleMesh> meshes;
  for (int threads : {1, 2}) {
    omp_set_num_threads(threads);
    VdbPart part = VdbPart::box(cases[2].stock, voxel(0.3));
    for (const VdbCase& c : cases) part.cut(c.sweeps);
    meshes.push_back(part.mesh(0.0));
  }
  omp_set_num_threads(omp_get_num_procs());
  ASSERT_EQ(meshes[0].vertices_mm.rows(), meshes[1].vertices_mm.rows());
  ASSERT_EQ(meshes[0].triangles.rows(), meshes[1].triangles.rows());
  EXPECT_TRUE(meshes[0].vertices_mm == meshes[1].vertices_mm);
  EXPECT_TRUE(meshes[0].triangles == meshes[1].triangles);
}

// .vdb written atomically and read back: the same grid (voxel, band, active voxels, volume); a missing file and a
// file that is not a .vdb are errors naming the path.
TEST(VdbKernel, VdbFileRoundTrip) {
  const auto dir = std::filesystem::temp_directory_path() / ("vmsim_vdb_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  VdbPart part = VdbPart::box(vdb_box(0, 0, 0, 10, 8, 5), voxel(0.25));
  part.cut(analytic_cases()[0].sweeps);
  part.write_vdb(dir / "part.vdb");
  const VdbPart back = VdbPart::read_vdb(dir / "part.vdb");
  EXPECT_EQ(back.voxel_mm(), part.voxel_mm());
  EXPECT_EQ(back.half_width_mm(), part.half_width_mm());
  EXPECT_EQ(back.active_voxels(), part.active_voxels());
  EXPECT_EQ(back.volume_mm3(), part.volume_mm3());
  std::size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);  // no temporary left behind
  try {
    (void)VdbPart::read_vdb(dir / "missing.vdb");
    ADD_FAILURE() << "no error for a missing file";
  } catch (const vmsim::core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.vdb"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

// An STL stock equal to the box gives the box stock's level set (meshToLevelSet's exact distances to the triangles
// vs createLevelSetBox's), to float round-off in the band.
TEST(VdbKernel, MeshStockEqualsBoxStock) {
  const Box b = vdb_box(1, 2, 3, 11, 9, 8);
  TriangleMesh m;
  m.vertices_mm.resize(8, 3);
  for (int k = 0; k < 8; ++k)
    m.vertices_mm.row(k) << (k & 1 ? b.hi.x() : b.lo.x()), (k & 2 ? b.hi.y() : b.lo.y()), (k & 4 ? b.hi.z() : b.lo.z());
  m.triangles.resize(12, 3);
  m.triangles << 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1,
      7, 5;
  const double h = 0.25;
  const VdbPart a = VdbPart::box(b, voxel(h)), s = VdbPart::mesh(m, voxel(h), "box.stl");
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> p(4000, 3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0, 1);
  for (int k = 0; k < p.rows(); ++k)
    for (int c = 0; c < 3; ++c) p(k, c) = b.lo[c] - 1 + U(rng) * (b.hi[c] - b.lo[c] + 2);
  const Eigen::VectorXd da = a.signed_distance(p), ds = s.signed_distance(p);
  int compared = 0;
  double worst = 0;
  for (int k = 0; k < p.rows(); ++k) {
    // Near the band's edge one grid may hold the background where the other holds a value: compare the core band.
    if (std::isnan(da[k]) || std::isnan(ds[k]) || std::abs(da[k]) > 2 * h) continue;
    ++compared;
    worst = std::max(worst, std::abs(da[k] - ds[k]));
  }
  EXPECT_GT(compared, 500);
  EXPECT_LT(worst, 1e-5);
  // An open mesh is refused, naming its source.
  TriangleMesh open = m;
  open.triangles.conservativeResize(11, 3);
  try {
    (void)VdbPart::mesh(open, voxel(h), "open.stl");
    ADD_FAILURE() << "open mesh accepted";
  } catch (const vmsim::core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("open.stl"), std::string::npos) << e.what();
  }
}

// The memory estimate stated before a run (removal/vdb_part.hpp: the band's nodes from the surface's area and its
// projections on the axis planes) against OpenVDB's memUsage of the grid it predicts: the box stock (its own faces),
// the slotted and pocketed part (its surface measured on its mesh), and a sphere (every orientation). It models the
// mean, so it is checked within a factor 1.5 either way; the parts' runs (bench/README.md) compare it on real jobs.
TEST(VdbKernel, MemoryEstimateMatchesTheGrid) {
  for (double h : {0.4, 0.2}) {
    const Box b = vdb_box(0, 0, 0, 40, 20, 10);
    VdbPart part = VdbPart::box(b, voxel(h));
    const double est0 = estimate_level_set_bytes(surface_area(b), h);
    const double got0 = static_cast<double>(part.memory_bytes());
    for (const VdbCase& c : analytic_cases()) part.cut(c.sweeps);
    const double est = estimate_level_set_bytes(surface_area(part.mesh(0.0)), h);
    const double got = static_cast<double>(part.memory_bytes());
    // A spherical cavity of radius 8 in a cube (a still ball-end tool 16 mm long, its body a ball): the cube's faces
    // and the sphere's surface in every orientation.
    VdbPart sphere_part = VdbPart::box(vdb_box(-12, -12, -12, 12, 12, 12), voxel(h));
    SweptTool ball;
    ball.tool = make(8, 8, 16);
    ball.tip0 = Eigen::Vector3d(0, 0, -8);
    sphere_part.cut({ball});
    const double est_s = estimate_level_set_bytes(surface_area(sphere_part.mesh(0.0)), h);
    const double got_s = static_cast<double>(sphere_part.memory_bytes());
    std::printf(
        "h %.2f: box estimate %.0f kB, grid %.0f kB (%.2f); cut part %.0f kB, %.0f kB (%.2f); box with a ball "
        "%.0f kB, %.0f kB (%.2f)\n",
        h, est0 / 1024, got0 / 1024, est0 / got0, est / 1024, got / 1024, est / got, est_s / 1024, got_s / 1024,
        est_s / got_s);
    for (const auto& [e, g] : {std::pair{est0, got0}, std::pair{est, got}, std::pair{est_s, got_s}}) {
      EXPECT_GT(e, g / 1.5) << h;
      EXPECT_LT(e, 1.5 * g) << h;
    }
  }
}

// A turning tool (5-axis): a flat end tilting from -17 to +17 degrees about Y while its tip moves along X, given as a
// PoseTrack with an axis per sample and cut through removal/track's sweeps (the same sweeps the dexel kernel
// removes). Reference: the union of 4000 tool instances along the track's motion (tip on the chord, axis on the
// great circle), distances from tool_reference.hpp; consecutive instances move no point by more than
// (16 mm + 0.6 rad x reach 30.2 mm) / 4000 = 0.0085 mm, so the union is within 0.01 mm of the swept volume. Every mesh
// vertex lies within h/2 + the track's stated bound + 0.01 mm of the reference part.
TEST(VdbKernel, TurningToolWithinTheTrackBoundOfTheBruteForce) {
  const double h = 0.2;
  const Box stock = vdb_box(0, 0, 0, 20, 10, 8);
  const Tool t = make(3, 0, 30);
  const int n = 17;
  PoseTrack track;
  track.tip_mm.resize(n, 3);
  track.axis_per_sample.resize(n, 3);
  for (int k = 0; k < n; ++k) {
    const double u = static_cast<double>(k) / (n - 1), phi = (-0.3 + 0.6 * u);
    track.tip_mm.row(k) << 2 + 16 * u, 5, 6.5;
    track.axis_per_sample.row(k) << std::sin(phi), 0, std::cos(phi);
  }
  TrackOptions opt;
  opt.tolerance_mm = 0.05;  // a quarter voxel: finer sub-steps are invisible at h = 0.2 mm
  const TrackSweeps ts = sweeps_from_track(t, track, opt);
  VdbPart part = VdbPart::box(stock, voxel(h));
  part.cut(ts.sweeps);
  const TriangleMesh m = part.mesh(0.0);
  expect_closed_manifold(m, "turning tool");
  const int dense = 4000;
  double worst = 0;
#pragma omp parallel for reduction(max : worst)
  for (Eigen::Index v = 0; v < m.vertices_mm.rows(); ++v) {
    const Eigen::Vector3d p = m.vertices_mm.row(v).transpose();
    auto tool_sd = [&](int N) {
      double tool = 1e300;
      for (int k = 0; k <= N; ++k) {
        const double u = static_cast<double>(k) / N, phi = (-0.3 + 0.6 * u);
        tool = std::min(tool, testref::body_sd(t, Eigen::Vector3d(2 + 16 * u, 5, 6.5),
                                               Eigen::Vector3d(std::sin(phi), 0, std::cos(phi)), p));
      }
      return tool;
    };
    // 100 instances are within 0.2 mm of the swept volume: a vertex 0.5 mm from them is on the stock's faces only.
    double tool = tool_sd(100);
    if (tool < 0.5) tool = tool_sd(dense);
    worst = std::max(worst, std::abs(std::max(box_sd(stock, p), -tool)));
  }
  std::printf("turning tool: %zu sweeps, track bound %.4f mm, vertex error %.4f mm = %.3f h\n", ts.sweeps.size(),
              ts.error_bound_mm, worst, worst / h);
  EXPECT_LT(worst, kVertexTol * h + ts.error_bound_mm + 0.01);
}

// ---- Dexel -> mesh: tri-dexel parts as level sets (VdbPart::from_tridexel), meshed by volumeToMesh. ----

namespace {

constexpr double kDexelVertexTol = 0.7;      // x h
constexpr double kDexelVolumePerEdge = 0.4;  // x h^2 per mm of sharp edge

TriDexel tridexel_part(const Box& stock, const std::vector<SweptTool>& sweeps, double spacing) {
  // The field's region one node beyond the stock, so that every face lies strictly inside the lattice.
  Box region = stock;
  region.lo.array() -= spacing;
  region.hi.array() += spacing;
  TriDexel f = make_tridexel(region, spacing);
  for (DexelGrid* g : {&f.x, &f.y, &f.z}) {
    fill_box(*g, stock);
    cut(*g, sweeps);
  }
  return f;
}

// An outside vertical 90-degree corner, flank-milled as parts/corner does it: block x, y in [-12, 0] (plus the 0.2 mm
// allowance), z in [-15, 0]; a flat end D10, tip at z -10, runs along the wall x = 0 in +Y, rolls round the edge (a
// quarter circle of radius R about it), and runs along y = 0 in -X: the walls x = 0 and y = 0 meet in a sharp edge.
std::vector<SweptTool> corner_sweeps(const Tool& t, double z_tip) {
  const double R = t.radius_mm;
  std::vector<SweptTool> s;
  s.push_back(vdb_line(t, {R, -20, z_tip}, {R, 0, z_tip}));
  const int n = 64;  // chords of the quarter circle: the flank comes R (1 - cos(pi / 128)) = 1.5 um closer to the edge
                     // (the reference below uses the same sweeps)
  for (int k = 0; k < n; ++k) {
    const double a0 = -kPi / 2 + (kPi / 2) * k / n, a1 = -kPi / 2 + (kPi / 2) * (k + 1) / n;
    s.push_back(vdb_line(t, {R * std::cos(a0 + kPi / 2), R * std::sin(a0 + kPi / 2), z_tip},
                         {R * std::cos(a1 + kPi / 2), R * std::sin(a1 + kPi / 2), z_tip}));
  }
  s.push_back(vdb_line(t, {0, R, z_tip}, {-20, R, z_tip}));
  return s;
}

}  // namespace

// A box and the analytic cases in tri-dexel fields, meshed through the level set: closed and manifold. The
// conversion's distances are exact for planes (d_i = d / |n_i| along each ray), but here every face lies on the
// lattice's nodes (the worst case: the field's region is the stock's box grown by one node, faces at multiples of
// h), where a node with phi = 0 counts as outside and edges are bevelled by up to h/2, 3-face corners by up to 2h/3:
// vertices within kDexelVertexTol, volume within kDexelVolumePerEdge (measured 0.28-0.33 h^2 per mm of edge).
TEST(DexelMesh, TriDexelPartsGiveClosedMeshesOfTheRightVolume) {
  const double h = 0.2;
  std::vector<VdbCase> cases = analytic_cases();
  cases.insert(cases.begin(),
               VdbCase{"box", vdb_box(0.13, 0.27, 0.31, 20.13, 10.27, 8.31), {}, 0.0, 4 * (20 + 10 + 8.0)});
  for (const VdbCase& c : cases) {
    const TriDexel f = tridexel_part(c.stock, c.sweeps, h);
    const VdbPart part = VdbPart::from_tridexel(f);
    const TriangleMesh m = part.mesh(0.0);
    expect_closed_manifold(m, c.name);
    const double exact = (c.stock.hi - c.stock.lo).prod() - c.removed_mm3, tol = kVolumePerEdge * h * h * c.edges_mm;
    const double vm = mesh_volume(m) - exact, ve = max_vertex_error(m, c.stock, c.sweeps);
    std::printf("tri-dexel %s: volume error %.4f mm3 (level-set kernel tolerance %.4f), vertex error %.3f h\n", c.name,
                vm, tol, ve / h);
    EXPECT_LT(std::abs(vm), kDexelVolumePerEdge * h * h * c.edges_mm) << c.name;
    EXPECT_LT(ve, kDexelVertexTol * h) << c.name;
  }
}

// The corner part's sharp vertical edge from a tri-dexel field: every vertex within 0.7 h of the exact walls (the
// largest, 2h/3, at 3-face corners on the lattice's nodes), and the vertices near the edge (within 2 h of it, below
// the cut's top) within that too: the edge is kept to a fraction of the cell size.
TEST(DexelMesh, CornerEdgeStaysWithinAFractionOfTheCell) {
  const double h = 0.2;
  const Box stock = vdb_box(-12, -12, -15, 0.2, 0.2, 0);
  const std::vector<SweptTool> sweeps = corner_sweeps(make(5, 0, 50), -10);
  const TriDexel f = tridexel_part(stock, sweeps, h);
  const TriangleMesh m = VdbPart::from_tridexel(f).mesh(0.0);
  expect_closed_manifold(m, "corner");
  double worst = 0, worst_edge = 0;
  int near_edge = 0;
  for (Eigen::Index v = 0; v < m.vertices_mm.rows(); ++v) {
    const Eigen::Vector3d p = m.vertices_mm.row(v).transpose();
    const double e = std::abs(part_sd(stock, sweeps, p));
    worst = std::max(worst, e);
    if (std::hypot(p.x(), p.y()) < 2 * h && p.z() < -1 && p.z() > -9) {
      ++near_edge;
      worst_edge = std::max(worst_edge, e);
    }
  }
  std::printf("corner from tri-dexels: vertex error %.3f h, near the edge %.3f h (%d vertices)\n", worst / h,
              worst_edge / h, near_edge);
  EXPECT_GT(near_edge, 20);
  EXPECT_LT(worst, kDexelVertexTol * h);
  EXPECT_LT(worst_edge, kDexelVertexTol * h);
  // The level-set kernel on the same cut, for comparison (same bound).
  VdbPart direct = VdbPart::box(stock, voxel(h));
  direct.cut(sweeps);
  EXPECT_LT(max_vertex_error(direct.mesh(0.0), stock, sweeps), kVertexTol * h);
}
