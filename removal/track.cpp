#include "removal/track.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::removal {

namespace {

double point_segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double dd = d.squaredNorm();
  const double t = dd > 0 ? std::clamp((p - a).dot(d) / dd, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

}  // namespace

TrackSweeps sweeps_from_track(const Tool& tool, const PoseTrack& track, const TrackOptions& options) {
  const Eigen::Index n = track.tip_mm.rows();
  TrackSweeps out;
  if (n == 0) return out;
  if (!(options.tolerance_mm > 0)) throw core::Error("removal: the track tolerance must be > 0");
  const double eps = 0.5 * options.tolerance_mm;
  const bool hermite = track.tip_velocity_mm_per_s.rows() == n;

  // 1. Points: the samples, plus points on the Hermite curve between them where its bow exceeds eps. The cubic's
  //    second derivative is linear in the parameter, so its largest |p''| is at an end; a chord over 1/m of the
  //    parameter bows by at most |p''|max / (8 m^2).
  std::vector<Eigen::Vector3d> pts;
  pts.reserve(static_cast<std::size_t>(n));
  pts.push_back(track.tip_mm.row(0).transpose());
  for (Eigen::Index k = 0; k + 1 < n; ++k) {
    const Eigen::Vector3d p0 = track.tip_mm.row(k).transpose(), p1 = track.tip_mm.row(k + 1).transpose();
    if (hermite) {
      const Eigen::Vector3d m0 = track.tip_velocity_mm_per_s.row(k).transpose() * track.period_s,
                            m1 = track.tip_velocity_mm_per_s.row(k + 1).transpose() * track.period_s;
      // p''(0) = 6(p1 - p0) - 4 m0 - 2 m1, p''(1) = -6(p1 - p0) + 2 m0 + 4 m1.
      const double a0 = (6 * (p1 - p0) - 4 * m0 - 2 * m1).norm(), a1 = (-6 * (p1 - p0) + 2 * m0 + 4 * m1).norm();
      const int m = std::clamp(static_cast<int>(std::ceil(std::sqrt(std::max(a0, a1) / (8 * eps)))), 1, 1000);
      for (int s = 1; s < m; ++s) {
        const double u = double(s) / m, u2 = u * u, u3 = u2 * u;
        pts.push_back((2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1);
      }
    }
    pts.push_back(p1);
  }
  out.points = pts.size();

  // 2. Merge: the longest run of points that all stay within eps of the chord from its first point (greedy, with
  //    a doubling search for the run's end, then a bisection: O(n log n) checks of short runs).
  auto run_ok = [&](std::size_t a, std::size_t b) {
    for (std::size_t k = a + 1; k < b; ++k)
      if (point_segment_distance(pts[k], pts[a], pts[b]) > eps) return false;
    return true;
  };
  std::size_t a = 0;
  const std::size_t last = pts.size() - 1;
  if (last == 0) {
    SweptTool s;
    s.tool = tool;
    s.tip0 = pts[0];
    s.axis = track.axis.normalized();
    out.sweeps.push_back(s);
    return out;
  }
  while (a < last) {
    std::size_t good = a + 1, step = 1;
    while (good + step <= last && run_ok(a, good + step)) {
      good += step;
      step *= 2;
    }
    std::size_t lo = good, hi = std::min(last, good + step);  // lo ok, hi unknown or bad
    while (hi > lo + 1) {
      const std::size_t mid = (lo + hi) / 2;
      if (run_ok(a, mid)) lo = mid; else hi = mid;
    }
    if (hi <= last && hi > lo && run_ok(a, hi)) lo = hi;
    SweptTool s;
    s.tool = tool;
    s.tip0 = pts[a];
    s.axis = track.axis.normalized();
    s.d = pts[lo] - pts[a];
    out.sweeps.push_back(s);
    a = lo;
  }
  return out;
}

}  // namespace vmsim::removal
