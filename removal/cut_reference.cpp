#include "removal/cut_reference.hpp"
#include "core/units.hpp"

#include "removal/cut_internal.hpp"
#include "removal/fields.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace vmsim::removal {

namespace {

using namespace detail;

std::size_t cut_row_axial_ball(DexelGrid& g, const AxialBall& b, int j, int i0, int i1) {
  int ia, ib;
  if (!axial_ball_columns(g, b, j, i0, i1, ia, ib)) return 0;
  const double qv = g.v_of(j) - b.cv;
  const RowCutParams p = row_params(g, b);
  constexpr int kChunk = 256;
  double lbs[kChunk], t0s[kChunk], t1s[kChunk];
  int idx[kChunk];
  const bool avx2 = use_avx2();
  for (int c0 = ia; c0 <= ib; c0 += kChunk) {
    const int n = std::min(kChunk, ib - c0 + 1);
    const Interval* head = g.head_row(j) + c0;
    // Keep the rays whose material the sweep may reach (a NaN in place, several intervals: kept), then the exact cut.
    (avx2 ? row_prefilter_avx2 : row_prefilter_generic)(p, qv, c0, n, lbs);
    int m = 0;
    for (int k = 0; k < n; ++k) {
      idx[m] = k;
      m += !(lbs[k] >= head[k].hi);
    }
    if (m == 0) continue;
    (avx2 ? row_bounds_avx2 : row_bounds_generic)(p, qv, c0, idx, m, t0s, t1s);
    for (int q = 0; q < m; ++q) {
      const int k = idx[q];
      if (t0s[q] >= head[k].hi) continue;  // false for NaN: such rays are read properly below
      const int i = c0 + k;
      const double t0 = t0s[q], top = g.top(i, j);
      if (t0 >= top || t0 >= g.length()) continue;
      double t1 = t1s[q];
      if (t1 < top) {
        t1 = axial_ball_top(b, qv, i * g.du() - b.cu);  // material above the tool's lowest top: the exact end
      } else {
        t1 = std::max(top, g.length()) + 1.0;  // past the material: the cut takes everything above t0
      }
      if (t1 <= 0) continue;
      g.subtract(i, j, t0, t1);
    }
  }
  return static_cast<std::size_t>(ib - ia + 1);
}

}  // namespace

CutStats cut_reference(DexelGrid& grid, const std::vector<SweptTool>& sweeps) {
  constexpr int kBlock = 8;  // rows per work item
  const int nblocks = (grid.nv() + kBlock - 1) / kBlock;
  std::vector<Footprint> fp(sweeps.size());
  std::vector<std::pair<double, double>> wext(sweeps.size());
  std::vector<std::vector<int>> bins(static_cast<std::size_t>(nblocks));
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    const Footprint f = footprint(grid, sweeps[k]);
    wext[k] = widened_extent(f.w0, f.w1);
    fp[k] = f;
    if (f.empty()) continue;
    for (int b = f.j0 / kBlock; b <= f.j1 / kBlock; ++b)
      bins[static_cast<std::size_t>(b)].push_back(static_cast<int>(k));
  }
  std::size_t tests = 0, cuts = 0;
  const Eigen::Vector3d W = grid.W();
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : tests, cuts)
  for (int b = 0; b < nblocks; ++b) {
    const int jb0 = b * kBlock, jb1 = std::min(grid.nv() - 1, jb0 + kBlock - 1);
    for (int k : bins[static_cast<std::size_t>(b)]) {
      const Footprint& f = fp[static_cast<std::size_t>(k)];
      const SweptTool& sw = sweeps[static_cast<std::size_t>(k)];
      AxialBall ab;
      if (axial_ball(grid, sw, ab)) {
        for (int j = std::max(jb0, f.j0); j <= std::min(jb1, f.j1); ++j)
          tests += cut_row_axial_ball(grid, ab, j, f.i0, f.i1);
        continue;
      }
      const GeneralRows rows = general_rows(grid, sw);
      for (int j = std::max(jb0, f.j0); j <= std::min(jb1, f.j1); ++j) {
        int ia, ib;
        general_row_range(grid, rows, j, f.i0, f.i1, ia, ib);
        const Interval* head = grid.head_row(j);
        for (int i = ia; i <= ib; ++i) {
          const Interval h = head[i];
          const auto [w0, w1] = wext[static_cast<std::size_t>(k)];
          if (!std::isnan(h.lo) && (!(h.lo <= h.hi) || w1 <= h.lo || w0 >= h.hi)) continue;
          double t0, t1;
          ++tests;
          if (!ray_interval_reference(sw, grid.ray_origin(i, j), W, t0, t1)) continue;
          if (t1 <= 0 || t0 >= grid.length() || t1 - t0 <= 1e-9) continue;  // zero-width contacts cut nothing
          grid.subtract(i, j, t0, t1);
          ++cuts;
        }
      }
    }
  }
  CutStats s;
  s.ray_tests = tests;
  s.cuts = cuts;
  return s;
}

CutStats cut_reference(NeedleSet& n, const std::vector<SweptTool>& sweeps) {
  const std::size_t nblocks = (n.size() + NeedleSet::kBlock - 1) / NeedleSet::kBlock;
  std::vector<Box> sb(sweeps.size());
  std::vector<std::size_t> order(sweeps.size());
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    sweeps[k].bounds(sb[k].lo, sb[k].hi);
    order[k] = k;
  }
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return sb[a].lo.x() < sb[b].lo.x(); });
  double max_width = 0;
  for (const Box& b : sb) max_width = std::max(max_width, b.hi.x() - b.lo.x());
  std::size_t tests = 0, cuts = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : tests, cuts)
  for (std::ptrdiff_t bi = 0; bi < static_cast<std::ptrdiff_t>(nblocks); ++bi) {
    const std::size_t k0 = static_cast<std::size_t>(bi) * NeedleSet::kBlock,
                      k1 = std::min(n.size(), k0 + NeedleSet::kBlock);
    Box bb{Eigen::Vector3d::Constant(1e300), Eigen::Vector3d::Constant(-1e300)};
    for (std::size_t k = k0; k < k1; ++k) {
      const Eigen::Vector3d a = n.origin(k), e = a + n.length(k) * n.direction(k);
      bb.lo = bb.lo.cwiseMin(a.cwiseMin(e));
      bb.hi = bb.hi.cwiseMax(a.cwiseMax(e));
    }
    auto first = std::lower_bound(order.begin(), order.end(), bb.lo.x() - max_width,
                                  [&](std::size_t s, double v) { return sb[s].lo.x() < v; });
    std::vector<std::size_t> cand;
    for (auto it = first; it != order.end() && sb[*it].lo.x() <= bb.hi.x(); ++it) {
      const Box& s = sb[*it];
      if ((s.hi.array() >= bb.lo.array()).all() && (s.lo.array() <= bb.hi.array()).all()) cand.push_back(*it);
    }
    std::sort(cand.begin(), cand.end());
    for (std::size_t k = k0; k < k1; ++k) {
      for (std::size_t s : cand) {
        double t0, t1;
        ++tests;
        if (!ray_interval_reference(sweeps[s], n.origin(k), n.direction(k), t0, t1)) continue;
        if (t1 <= 0 || t0 >= n.length(k) || t1 - t0 <= 1e-9) continue;
        n.store().subtract(k, t0, t1);
        ++cuts;
      }
    }
  }
  CutStats s;
  s.ray_tests = tests;
  s.cuts = cuts;
  return s;
}

// sweeps_from_track as it was before issue 21 (removal/track.cpp).
namespace track_ref {

using core::units::kPi;

double point_segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double dd = d.squaredNorm();
  const double t = dd > 0 ? std::clamp((p - a).dot(d) / dd, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

// Angle between unit vectors, accurate for tiny angles too (acos of the dot product is not).
double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// The axis a fraction u of the way from a to b on their great circle (theta = their angle, < pi / 2 here).
Eigen::Vector3d slerp(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double theta, double u) {
  if (theta < 1e-9) return ((1 - u) * a + u * b).normalized();  // the chord's midpoint error is theta^2 / 8 < 1e-18
  const double s = std::sin(theta);
  return ((std::sin((1 - u) * theta) / s) * a + (std::sin(u * theta) / s) * b).normalized();
}

}  // namespace track_ref

using namespace track_ref;

TrackSweeps sweeps_from_track_reference(const Tool& tool, const PoseTrack& track, const TrackOptions& options) {
  const Eigen::Index n = track.tip_mm.rows();
  TrackSweeps out;
  if (n == 0) return out;
  if (!(options.tolerance_mm > 0)) throw core::Error("removal: the track tolerance must be > 0");
  if (track.tip_mm.cols() != 3) throw core::Error("removal: track tips must be samples x 3");
  const bool per_sample = track.axis_per_sample.size() > 0;
  if (per_sample && (track.axis_per_sample.rows() != n || track.axis_per_sample.cols() != 3))
    throw core::Error(fmt::format("removal: the track has {} tip samples but {} x {} tool axes (expected {} x 3)", n,
                                  track.axis_per_sample.rows(), track.axis_per_sample.cols(), n));
  const bool hermite = track.tip_velocity_mm_per_s.rows() == n;

  // Unit axes per sample, and the turn of each interval.
  std::vector<Eigen::Vector3d> axis(static_cast<std::size_t>(n));
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Vector3d a = per_sample ? Eigen::Vector3d(track.axis_per_sample.row(k).transpose()) : track.axis;
    const double len = a.norm();
    if (!(len > 0) || !std::isfinite(len))
      throw core::Error(fmt::format("removal: the tool axis at track sample {} is zero or not finite", k));
    axis[static_cast<std::size_t>(k)] = a.normalized();
  }
  std::vector<double> turn(static_cast<std::size_t>(n), 0.0);
  bool turning = false;
  for (std::size_t k = 0; k + 1 < axis.size(); ++k) {
    // Bitwise equality: a constant axis must leave the 3-axis budget and sweeps untouched.
    if (axis[k] == axis[k + 1]) continue;
    turning = true;
    turn[k] = angle_between(axis[k], axis[k + 1]);
    if (turn[k] >= 0.5 * kPi)
      throw core::Error(
          fmt::format("removal: the tool axis turns by {:.1f} degrees between track samples {} and {} "
                      "(at most 90 between samples)",
                      turn[k] * 180 / kPi, k, k + 1));
  }

  // Budget (track.hpp): a constant axis keeps the 3-axis split; a turning one gives half to the orientation.
  const double e_orient = turning ? 0.5 * options.tolerance_mm : 0.0;
  const double eps = 0.5 * (options.tolerance_mm - e_orient);  // e_hermite = e_merge
  const double reach = tool.reach();
  // Largest |a - a*| of a sweep; capped at 45 degrees so that a run's axes stay in a cap where the largest distance
  // to a* along each slerp arc is at an end of the arc (checking the points then checks the arcs).
  const double chord_max = turning ? std::min(e_orient / reach, 2 * std::sin(kPi / 8)) : 0.0;
  const double phi_max = 4 * std::asin(0.5 * chord_max);  // a sub-step's turn: its half turn has chord chord_max

  // 1. Points: the samples, plus points between them where the Hermite curve bows by more than eps or the axis
  //    turns by more than phi_max. The cubic's second derivative is linear in the parameter, so its largest |p''|
  //    is at an end; a chord over 1/m of the parameter bows by at most |p''|max / (8 m^2).
  std::vector<Eigen::Vector3d> pts, axs;
  pts.reserve(static_cast<std::size_t>(n));
  axs.reserve(static_cast<std::size_t>(n));
  pts.push_back(track.tip_mm.row(0).transpose());
  axs.push_back(axis[0]);
  double e_hermite = 0;
  for (Eigen::Index k = 0; k + 1 < n; ++k) {
    const std::size_t ks = static_cast<std::size_t>(k);
    const Eigen::Vector3d p0 = track.tip_mm.row(k).transpose(), p1 = track.tip_mm.row(k + 1).transpose();
    Eigen::Vector3d m0 = Eigen::Vector3d::Zero(), m1 = Eigen::Vector3d::Zero();
    int m = 1;
    double bow = 0;  // |p''|max / 8
    if (hermite) {
      m0 = track.tip_velocity_mm_per_s.row(k).transpose() * track.period_s;
      m1 = track.tip_velocity_mm_per_s.row(k + 1).transpose() * track.period_s;
      // p''(0) = 6(p1 - p0) - 4 m0 - 2 m1, p''(1) = -6(p1 - p0) + 2 m0 + 4 m1.
      const double a0 = (6 * (p1 - p0) - 4 * m0 - 2 * m1).norm(), a1 = (-6 * (p1 - p0) + 2 * m0 + 4 * m1).norm();
      bow = std::max(a0, a1) / 8;
      m = std::clamp(static_cast<int>(std::ceil(std::sqrt(std::max(a0, a1) / (8 * eps)))), 1, 1000);
    }
    if (turn[ks] > 0) {
      const double need = std::ceil(turn[ks] / phi_max);
      if (need > 1e6)
        throw core::Error(
            fmt::format("removal: the tool axis turns by {:.3g} degrees between track samples {} and {}: "
                        "holding it within {:.3g} mm of a {:.3g} mm tool takes {:.3g} sub-steps (over 1e6); "
                        "raise the tolerance or sample the track more finely",
                        turn[ks] * 180 / kPi, k, k + 1, e_orient, reach, need));
      m = std::max(m, static_cast<int>(need));
    }
    e_hermite = std::max(e_hermite, bow / (double(m) * m));
    for (int s = 1; s < m; ++s) {
      const double u = double(s) / m, u2 = u * u, u3 = u2 * u;
      if (hermite) {
        pts.push_back((2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1);
      } else {
        pts.push_back((1 - u) * p0 + u * p1);
      }
      axs.push_back(turn[ks] > 0 ? slerp(axis[ks], axis[ks + 1], turn[ks], u) : axis[ks]);
    }
    pts.push_back(p1);
    axs.push_back(axis[ks + 1]);
  }
  out.points = pts.size();

  // 2. Merge: the longest run of points whose tips all stay within eps of the chord from its first point and whose
  //    axes stay within chord_max of its mid-axis (greedy, with a doubling search for the run's end, then a
  //    bisection: O(n log n) checks of short runs). A run of two neighbouring points is always taken: its chord is
  //    the track's (or within e_hermite of it) and its axes are phi_max apart, within chord_max of their middle.
  auto run_axis = [&](std::size_t a, std::size_t b) -> Eigen::Vector3d {
    return axs[a] == axs[b] ? axs[a] : Eigen::Vector3d((axs[a] + axs[b]).normalized());
  };
  // Slack for round-off: sub-steps are sized to sit exactly at chord_max.
  const double chord_ok = chord_max * (1 + 1e-9);
  auto run_ok = [&](std::size_t a, std::size_t b) {
    for (std::size_t k = a + 1; k < b; ++k)
      if (point_segment_distance(pts[k], pts[a], pts[b]) > eps) return false;
    if (turning) {
      const Eigen::Vector3d c = run_axis(a, b);
      for (std::size_t k = a; k <= b; ++k)
        if ((axs[k] - c).norm() > chord_ok) return false;
    }
    return true;
  };
  double e_merge = 0, chord = 0;
  auto emit = [&](std::size_t a, std::size_t b) {
    SweptTool s;
    s.tool = tool;
    s.tip0 = pts[a];
    s.axis = run_axis(a, b);
    s.d = pts[b] - pts[a];
    for (std::size_t k = a + 1; k < b; ++k) e_merge = std::max(e_merge, point_segment_distance(pts[k], pts[a], pts[b]));
    if (turning)
      for (std::size_t k = a; k <= b; ++k) chord = std::max(chord, (axs[k] - s.axis).norm());
    out.sweeps.push_back(s);
  };
  std::size_t a = 0;
  const std::size_t last = pts.size() - 1;
  if (last == 0) emit(0, 0);
  while (a < last) {
    std::size_t good = a + 1, step = 1;
    while (good + step <= last && run_ok(a, good + step)) {
      good += step;
      step *= 2;
    }
    std::size_t lo = good, hi = std::min(last, good + step);  // lo ok, hi unknown or bad
    while (hi > lo + 1) {
      const std::size_t mid = (lo + hi) / 2;
      if (run_ok(a, mid))
        lo = mid;
      else
        hi = mid;
    }
    if (hi <= last && hi > lo && run_ok(a, hi)) lo = hi;
    emit(a, lo);
    a = lo;
  }
  out.orientation_error_mm = reach * chord;
  out.error_bound_mm = e_hermite + e_merge + out.orientation_error_mm;
  return out;
}

}  // namespace vmsim::removal
