// A mesh stock's material box (issue 24 section 2's leftover): the sweeps of a turning tool count only the tool's
// engaging length within the stock's bounding box (removal/track.hpp TrackOptions::material_box). Reference: a box
// stock with the mesh's bounding box (the path box stocks always took): a mesh stock must give exactly its sweeps, and
// fewer than a stock box far larger than the mesh (the whole body counting). The bound itself holds for any box
// holding all the material (tests/removal/five_axis_test.cpp, MaterialBoxCountsOnlyTheEngagingLength, against the
// brute force); a mesh lies within its bounding box.
#include "core/job.hpp"
#include "core/stl.hpp"
#include "sim/pipeline.hpp"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <cmath>
#include <filesystem>

namespace vmsim::sim {
namespace {

namespace fs = std::filesystem;

TEST(MeshMaterialBox, MeshStockSweepsAsItsBoundingBox) {
  core::Job mesh_job = core::load_job(fs::path(VMSIM_SOURCE_DIR) / "parts" / "five_axis" / "job.toml");
  ASSERT_EQ(mesh_job.stock.kind, core::StockSpec::Kind::Mesh);
  mesh_job.tool.length_mm = 40.0;  // a long body, so that the engaging length matters
  mesh_job.tool.flute_length_mm = 40.0;
  const core::TriangleMesh mesh = core::read_stl(mesh_job.stock.mesh_file);
  const Eigen::Vector3d lo = mesh.vertices_mm.colwise().minCoeff().transpose();
  const Eigen::Vector3d hi = mesh.vertices_mm.colwise().maxCoeff().transpose();
  // A ball's tip crossing the dome's top, its axis turning from vertical to 30 degrees.
  removal::PoseTrack tr;
  const int n = 41;
  tr.tip_mm.resize(n, 3);
  tr.axis_per_sample.resize(n, 3);
  const Eigen::Vector3d c = 0.5 * (lo + hi);
  for (int k = 0; k < n; ++k) {
    const double s = double(k) / (n - 1), phi = s * 30 * M_PI / 180;
    tr.tip_mm.row(k) = Eigen::RowVector3d(c.x() - 10 + 20 * s, c.y(), hi.z() - 0.5);
    tr.axis_per_sample.row(k) = Eigen::RowVector3d(std::sin(phi), 0, std::cos(phi));
  }
  core::Job box_job = mesh_job;
  box_job.stock.kind = core::StockSpec::Kind::Box;
  box_job.stock.min_mm = lo;
  box_job.stock.max_mm = hi;
  core::Job big_job = box_job;
  big_job.stock.min_mm = lo - Eigen::Vector3d::Constant(500);
  big_job.stock.max_mm = hi + Eigen::Vector3d::Constant(500);
  const removal::TrackSweeps m = sweeps_of(mesh_job, tr), b = sweeps_of(box_job, tr), big = sweeps_of(big_job, tr);
  ASSERT_EQ(m.sweeps.size(), b.sweeps.size());
  for (std::size_t k = 0; k < m.sweeps.size(); ++k) {
    Eigen::Vector3d l1, h1, l2, h2;
    m.sweeps[k].bounds(l1, h1);
    b.sweeps[k].bounds(l2, h2);
    ASSERT_EQ(l1, l2) << k;
    ASSERT_EQ(h1, h2) << k;
  }
  EXPECT_EQ(m.error_bound_mm, b.error_bound_mm);
  EXPECT_LT(m.sweeps.size(), big.sweeps.size());
  EXPECT_LE(m.error_bound_mm, mesh_job.removal.track_tolerance_mm * (1 + 1e-9));
  std::printf("[ MESH BOX ] turning ball L40 over the dome: %zu sweeps with the mesh's box, %zu with the whole body\n",
              m.sweeps.size(), big.sweeps.size());
}

}  // namespace
}  // namespace vmsim::sim
