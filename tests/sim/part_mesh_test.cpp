// The part mesh simplified where flat (sim/part_mesh.hpp). References: the height grid itself (every node sampled
// against the simplified mesh's surface, found by point location in its triangles, must lie within the stated
// bound), removal::heightfield_mesh (the full mesh: same triangles where nothing is flat) and the closed-solid rule
// that every edge of a closed triangle mesh is shared by exactly two triangles in opposite directions.
#include "sim/part_mesh.hpp"

#include "core/error.hpp"
#include "removal/surface.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>

namespace vmsim::sim {
namespace {

// 20 x 16 mm at 0.1 mm: a flat stock top (x < 6.4 mm from the grid's edge), a tilted plane (to 12.8 mm) with 40 nm
// of ripple (flat to 0.1 um), and a scalloped, curved floor, which no block of 0.8 mm is flat in.
core::HeightGrid part() {
  core::HeightGrid g;
  g.x0_mm = -3, g.y0_mm = 2, g.dx_mm = g.dy_mm = 0.1;
  g.z_mm.resize(161, 201);
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i) {
      const double x = i * 0.1, y = g.y(j);
      g.z_mm(j, i) = i < 64    ? 0.0
                     : i < 128 ? -0.05 * (x - 6.4) + 4e-5 * std::sin(7 * x + 3 * y)
                               : -0.32 - 0.01 * (x - 12.8) * (x - 12.8) + 0.002 * std::cos(2 * M_PI * y / 0.4);
    }
  return g;
}

// z of the mesh's upward-facing triangles at (x, y), NaN where none covers it.
double mesh_z(const core::TriangleMesh& m, double x, double y) {
  for (Eigen::Index t = 0; t < m.triangles.rows(); ++t) {
    const Eigen::Vector3d a = m.vertices_mm.row(m.triangles(t, 0)), b = m.vertices_mm.row(m.triangles(t, 1)),
                          c = m.vertices_mm.row(m.triangles(t, 2));
    const double det = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (det <= 1e-12) continue;  // walls, bottom (facing down), degenerate
    const double u = ((x - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (y - a.y())) / det;
    const double v = ((b.x() - a.x()) * (y - a.y()) - (x - a.x()) * (b.y() - a.y())) / det;
    if (u < -1e-9 || v < -1e-9 || u + v > 1 + 1e-9) continue;
    return a.z() + u * (b.z() - a.z()) + v * (c.z() - a.z());
  }
  return NAN;
}

TEST(PartMesh, SimplifiedMeshIsWithinItsBoundOfEveryNodeAndClosed) {
  const core::HeightGrid g = part();
  core::HeightGrid dev = g;
  dev.z_mm = g.z_mm * 0.01;  // a deviation grid: flat where the part is
  const double tol = 1e-4;
  const SimplifiedMesh s = simplified_heightfield_mesh(g, -5.0, &dev, tol);
  const core::TriangleMesh full = removal::heightfield_mesh(g, -5.0, &dev);
  EXPECT_DOUBLE_EQ(s.error_bound_mm, 2 * tol);
  // The flat top and the plane: 15 of 25 block columns (the floor's first touches its scallops), all 20 rows.
  EXPECT_EQ(s.blocks, 25 * 20);
  EXPECT_EQ(s.flat_blocks, 15 * 20);
  EXPECT_LT(s.mesh.triangles.rows(), full.triangles.rows() * 2 / 3);
  std::printf("triangles: %ld simplified, %ld full\n", static_cast<long>(s.mesh.triangles.rows()),
              static_cast<long>(full.triangles.rows()));
  // Every node of the grid against the simplified surface (a bucket of candidate triangles would be faster; the brute
  // force is the plainest reference), every 3rd node in each direction and all on block edges.
  const Eigen::VectorXd& d = s.mesh.point_data.at(0).second;
  double worst = 0;
  for (Eigen::Index j = 0; j < g.ny(); j += 3)
    for (Eigen::Index i = 0; i < g.nx(); i += 3) {
      const double z = mesh_z(s.mesh, g.x(i), g.y(j));
      ASSERT_TRUE(std::isfinite(z)) << "no triangle over node " << i << ", " << j;
      worst = std::max(worst, std::abs(z - g.z_mm(j, i)));
    }
  EXPECT_LE(worst, s.error_bound_mm);
  EXPECT_GT(worst, 1e-6);  // the ripple of the plane was merged: the bound is not trivially met by keeping every node
  // The per-vertex deviation of the kept nodes is the grid's.
  for (Eigen::Index k = 0; k < s.mesh.vertices_mm.rows(); ++k) {
    const Eigen::Vector3d p = s.mesh.vertices_mm.row(k);
    if (p.z() == -5.0) continue;
    const auto i = static_cast<Eigen::Index>(std::lround((p.x() - g.x0_mm) / g.dx_mm)),
               j = static_cast<Eigen::Index>(std::lround((p.y() - g.y0_mm) / g.dy_mm));
    ASSERT_DOUBLE_EQ(d[k], dev.z_mm(j, i));
  }
  // Closed: every directed edge appears once and its reverse once.
  std::map<std::pair<int, int>, int> edges;
  for (Eigen::Index t = 0; t < s.mesh.triangles.rows(); ++t)
    for (int c = 0; c < 3; ++c) ++edges[{s.mesh.triangles(t, c), s.mesh.triangles(t, (c + 1) % 3)}];
  for (const auto& [e, n] : edges) {
    ASSERT_EQ(n, 1) << e.first << "-" << e.second;
    ASSERT_EQ(edges.count({e.second, e.first}), 1u) << "open edge " << e.first << "-" << e.second;
  }
}

TEST(PartMesh, NothingFlatIsTheFullMeshAndBadArgumentsAreErrors) {
  core::HeightGrid g = part();
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i) g.z_mm(j, i) = 0.01 * std::sin(i * 0.7) * std::cos(j * 0.9);
  const SimplifiedMesh s = simplified_heightfield_mesh(g, -1.0, nullptr, 1e-4);
  const core::TriangleMesh full = removal::heightfield_mesh(g, -1.0);
  EXPECT_EQ(s.flat_blocks, 0);
  EXPECT_EQ(s.mesh.triangles, full.triangles);
  EXPECT_EQ(s.mesh.vertices_mm, full.vertices_mm);
  EXPECT_THROW(simplified_heightfield_mesh(g, -1.0, nullptr, 0.0), core::Error);
  EXPECT_THROW(simplified_heightfield_mesh(g, -1.0, nullptr, 1e-4, 3), core::Error);
}

}  // namespace
}  // namespace vmsim::sim
