// Sampled motion to sweeps (the merge and the Hermite sub-sampling keep within the stated tolerance), and the
// height-field mesh (closed, consistently oriented, with the volume of the grid's prisms).
#include "removal/surface.hpp"
#include "removal/track.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

using namespace vmsim::removal;

namespace {
double dist_point_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double t = d.squaredNorm() > 0 ? std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}
Tool track_ball() {
  Tool t;
  t.radius_mm = 5;
  t.corner_radius_mm = 5;
  t.length_mm = 30;
  return t;
}
}  // namespace

TEST(Track, StraightSamplesMergeIntoOneSweep) {
  PoseTrack tr;
  tr.tip_mm.resize(1001, 3);
  for (int k = 0; k <= 1000; ++k) tr.tip_mm.row(k) = Eigen::RowVector3d(0.01 * k, 0.002 * k, -0.001 * k);
  const TrackSweeps s = sweeps_from_track(track_ball(), tr);
  ASSERT_EQ(s.sweeps.size(), 1u);
  EXPECT_NEAR((s.sweeps[0].d - Eigen::Vector3d(10, 2, -1)).norm(), 0, 1e-12);
}

// Points on a circle of radius 5 every 0.05 mm: every sample stays within the tolerance of the merged sweeps, and
// the merge is not trivial (far fewer sweeps than samples).
TEST(Track, CircleSamplesStayWithinTheTolerance) {
  PoseTrack tr;
  const int n = 628;
  tr.tip_mm.resize(n + 1, 3);
  for (int k = 0; k <= n; ++k) tr.tip_mm.row(k) = Eigen::RowVector3d(5 * std::cos(0.01 * k), 5 * std::sin(0.01 * k), 0);
  TrackOptions opt;
  opt.tolerance_mm = 1e-3;
  const TrackSweeps s = sweeps_from_track(track_ball(), tr, opt);
  // A chord bowing by 0.5 um on r = 5 mm is 0.141 mm long: about three samples per sweep.
  EXPECT_LE(s.sweeps.size(), static_cast<std::size_t>(n / 3 + 1));
  for (int k = 0; k <= n; ++k) {
    const Eigen::Vector3d p = tr.tip_mm.row(k).transpose();
    double d = 1e9;
    for (const SweptTool& sw : s.sweeps) d = std::min(d, dist_point_segment(p, sw.tip0, sw.tip0 + sw.d));
    ASSERT_LE(d, 0.5e-3 + 1e-12) << k;
  }
}

// With velocities, the motion between samples is the cubic Hermite curve: samples of a circle 0.5 rad apart with
// their true velocities give sweeps within the tolerance of the true circle (the chords alone bow by 0.16 mm).
TEST(Track, HermiteSubsamplingFollowsTheCurveBetweenSamples) {
  PoseTrack tr;
  const double r = 5, w = 0.5;  // rad per sample
  tr.period_s = 1.0;
  const int n = 12;
  tr.tip_mm.resize(n + 1, 3);
  tr.tip_velocity_mm_per_s.resize(n + 1, 3);
  for (int k = 0; k <= n; ++k) {
    tr.tip_mm.row(k) = Eigen::RowVector3d(r * std::cos(w * k), r * std::sin(w * k), 0);
    tr.tip_velocity_mm_per_s.row(k) = Eigen::RowVector3d(-r * w * std::sin(w * k), r * w * std::cos(w * k), 0);
  }
  TrackOptions opt;
  opt.tolerance_mm = 2e-3;
  const TrackSweeps s = sweeps_from_track(track_ball(), tr, opt);
  // The cubic Hermite interpolant of a circle deviates from it by O(h^4): for 0.5 rad steps about 0.4 um.
  for (int k = 0; k <= 600; ++k) {
    const double a = w * n * k / 600.0;
    const Eigen::Vector3d p(r * std::cos(a), r * std::sin(a), 0);
    double d = 1e9;
    for (const SweptTool& sw : s.sweeps) d = std::min(d, dist_point_segment(p, sw.tip0, sw.tip0 + sw.d));
    ASSERT_LE(d, 2e-3) << a;
  }
}

TEST(Surface, HeightfieldMeshIsClosedAndHasThePrismsVolume) {
  vmsim::core::HeightGrid g;
  g.x0_mm = 1, g.y0_mm = 2, g.dx_mm = 0.5, g.dy_mm = 0.25;
  g.z_mm.resize(7, 9);
  for (int j = 0; j < 7; ++j)
    for (int i = 0; i < 9; ++i) g.z_mm(j, i) = 3 + 0.1 * std::sin(i) * std::cos(j);
  const auto m = heightfield_mesh(g, -1.0);
  // Every directed edge once and its reverse once.
  std::map<std::pair<int, int>, int> edges;
  for (Eigen::Index t = 0; t < m.triangles.rows(); ++t)
    for (int e = 0; e < 3; ++e) edges[{m.triangles(t, e), m.triangles(t, (e + 1) % 3)}]++;
  for (const auto& [e, c] : edges) {
    ASSERT_EQ(c, 1);
    ASSERT_EQ(edges.count({e.second, e.first}), 1u);
  }
  // Euler characteristic of a sphere-like closed surface: V - E + F = 2.
  const long V = m.vertices_mm.rows(), F = m.triangles.rows(), E = static_cast<long>(edges.size()) / 2;
  EXPECT_EQ(V - E + F, 2);
  // Volume by the divergence theorem equals the sum over cells of the two triangular prisms.
  double vol = 0, expected = 0;
  for (Eigen::Index t = 0; t < F; ++t) {
    const Eigen::Vector3d a = m.vertices_mm.row(m.triangles(t, 0)), b = m.vertices_mm.row(m.triangles(t, 1)),
                          c = m.vertices_mm.row(m.triangles(t, 2));
    vol += a.dot(b.cross(c)) / 6;
  }
  for (int j = 0; j + 1 < 7; ++j)
    for (int i = 0; i + 1 < 9; ++i) {
      const double h00 = g.z_mm(j, i) + 1, h10 = g.z_mm(j, i + 1) + 1, h11 = g.z_mm(j + 1, i + 1) + 1,
                   h01 = g.z_mm(j + 1, i) + 1;
      expected += 0.5 * g.dx_mm * g.dy_mm * ((h00 + h10 + h11) / 3 + (h00 + h11 + h01) / 3);
    }
  EXPECT_NEAR(vol, expected, 1e-12);
}
