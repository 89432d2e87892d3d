// The part mesh's size without making it (a run reports it and makes the mesh only when it is written). Reference:
// removal::heightfield_mesh itself, on grids with and without invalid nodes.
#include "core/height_grid.hpp"
#include "removal/surface.hpp"
#include "sim/part_mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace {

vmsim::core::HeightGrid count_test_grid(Eigen::Index nx, Eigen::Index ny, double holes) {
  vmsim::core::HeightGrid g;
  g.x0_mm = 1.0, g.y0_mm = -2.0, g.dx_mm = 0.1, g.dy_mm = 0.1;
  g.z_mm.resize(ny, nx);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (Eigen::Index j = 0; j < ny; ++j)
    for (Eigen::Index i = 0; i < nx; ++i) g.z_mm(j, i) = u(rng) < holes ? NAN : -u(rng);
  return g;
}

TEST(PartMeshCount, EqualsTheMeshBuildersTriangles) {
  for (const double holes : {0.0, 0.05, 0.5})
    for (const auto& [nx, ny] : {std::pair<Eigen::Index, Eigen::Index>{2, 2}, {37, 23}, {1, 9}, {64, 1}}) {
      const vmsim::core::HeightGrid g = count_test_grid(nx, ny, holes);
      EXPECT_EQ(vmsim::sim::heightfield_mesh_triangles(g), vmsim::removal::heightfield_mesh(g, -5.0).triangles.rows())
          << nx << " x " << ny << ", holes " << holes;
    }
}

}  // namespace
