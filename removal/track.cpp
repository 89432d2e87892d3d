#include "removal/track.hpp"
#include "core/units.hpp"

#include "core/error.hpp"
#include "removal/cut_internal.hpp"
#include "removal/row_bounds.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::removal {

namespace {

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

// The largest h in [0, L] with p + h a in the box (slab clipping), or -1 when no such h exists.
double highest_in_box(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& p, const Eigen::Vector3d& a, double L) {
  double h0 = 0, h1 = L;
  for (int c = 0; c < 3; ++c) {
    if (a[c] == 0) {
      if (p[c] < box.min()[c] || p[c] > box.max()[c]) return -1;
      continue;
    }
    double x0 = (box.min()[c] - p[c]) / a[c], x1 = (box.max()[c] - p[c]) / a[c];
    if (x0 > x1) std::swap(x0, x1);
    h0 = std::max(h0, x0), h1 = std::min(h1, x1);
  }
  return h0 <= h1 ? h1 : -1;
}

// The cubic Hermite curve through p0 and p1 with end tangents m0 and m1 (a sample's velocity times Te) at u in [0, 1]:
// the track's sub-samples between two of its samples (the fast path and the general loop of sweeps_from_track).
inline Eigen::Vector3d hermite_point(const Eigen::Vector3d& p0, const Eigen::Vector3d& m0, const Eigen::Vector3d& p1,
                                     const Eigen::Vector3d& m1, double u) {
  const double u2 = u * u, u3 = u2 * u;
  return (2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1;
}

// The Hermite sub-sampling of a 3-axis track (a constant axis) in one pass over its columns: each interval's count
// of chords m (the sub-sampling loop in sweeps_from_track: |p''|max <= 8 eps m^2), with the very operations of that
// loop, so the same m and the same bits of e_hermite (the larger of two norms is the square root of the larger squared
// norm: the square root is correctly rounded and monotone). Returns the intervals with m > 1 (few on a real machine's
// actual motion at 1 ms, none on most tracks) as (interval, m), and the largest bow left in e_hermite.
std::vector<std::pair<Eigen::Index, int>> hermite_substeps(const PoseTrack& track, double eps, double& e_hermite) {
  const Eigen::Index n = track.tip_mm.rows();
  const double* tx = track.tip_mm.col(0).data();
  const double* ty = track.tip_mm.col(1).data();
  const double* tz = track.tip_mm.col(2).data();
  const double* vx = track.tip_velocity_mm_per_s.col(0).data();
  const double* vy = track.tip_velocity_mm_per_s.col(1).data();
  const double* vz = track.tip_velocity_mm_per_s.col(2).data();
  const auto bow = detail::use_avx2() ? hermite_bow_avx2 : hermite_bow_generic;
  std::vector<std::pair<Eigen::Index, int>> out;
  double e = 0;
  // The square roots and divisions vectorised a block of intervals at a time (hermite_bow); m and e from them here.
  constexpr std::size_t kBowBlock = 256;
  double a_of[kBowBlock], r_of[kBowBlock];
  const std::size_t intervals = n > 0 ? static_cast<std::size_t>(n - 1) : 0;
  for (std::size_t k0 = 0; k0 < intervals; k0 += kBowBlock) {
    const std::size_t k1 = std::min(intervals, k0 + kBowBlock);
    bow(tx, ty, tz, vx, vy, vz, k0, k1, track.period_s, eps, a_of, r_of);
    for (std::size_t k = k0; k < k1; ++k) {
      const double a = a_of[k - k0], r = r_of[k - k0];
      if (!(r > 1)) {  // m = 1 (a NaN too, as the clamp made it): (a / 8) / 1.0 is a / 8
        e = std::max(e, a / 8);
        continue;
      }
      const int m = std::clamp(static_cast<int>(std::ceil(r)), 1, 1000);
      e = std::max(e, (a / 8) / (double(m) * m));
      if (m > 1) out.emplace_back(static_cast<Eigen::Index>(k), m);
    }
  }
  e_hermite = e;
  return out;
}

}  // namespace

double orientation_error_bound_mm(const Tool& tool, double phi_rad) { return 2 * tool.reach() * std::sin(phi_rad / 4); }

TrackSweeps sweeps_from_track(const Tool& tool, const PoseTrack& track, const TrackOptions& options) {
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

  // Unit axes per sample (one for a constant axis), and the turn of each interval.
  std::vector<Eigen::Vector3d> axis(per_sample ? static_cast<std::size_t>(n) : 1);
  for (Eigen::Index k = 0; k < static_cast<Eigen::Index>(axis.size()); ++k) {
    const Eigen::Vector3d a = per_sample ? Eigen::Vector3d(track.axis_per_sample.row(k).transpose()) : track.axis;
    const double len = a.norm();
    if (!(len > 0) || !std::isfinite(len))
      throw core::Error(fmt::format("removal: the tool axis at track sample {} is zero or not finite", k));
    axis[static_cast<std::size_t>(k)] = a.normalized();
  }
  std::vector<double> turn(axis.size(), 0.0);
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
  const double chord_cap = 2 * std::sin(kPi / 8);
  auto chord_limit = [&](double r) { return turning ? std::min(e_orient / r, chord_cap) : 0.0; };

  // The reach each track interval counts (track.hpp): reach() without a material box, else reach_k from the engaging
  // length. H_k needs the tip's largest move over the interval: the chord plus twice the Hermite bow (the curve stays
  // within the bow of the chord), plus the sweep's tip error (e_hermite + e_merge <= bow + eps).
  std::vector<double> reach_k(turning ? static_cast<std::size_t>(std::max<Eigen::Index>(n - 1, 1)) : 0, reach);
  if (turning && options.material_box) {
    const double L = tool.length_mm, R = tool.radius_mm;
    for (Eigen::Index k = 0; k + 1 < n; ++k) {
      const std::size_t ks = static_cast<std::size_t>(k);
      const Eigen::Vector3d p0 = track.tip_mm.row(k).transpose(), p1 = track.tip_mm.row(k + 1).transpose();
      double bow = 0;
      if (hermite) {
        const Eigen::Vector3d m0 = track.tip_velocity_mm_per_s.row(k).transpose() * track.period_s;
        const Eigen::Vector3d m1 = track.tip_velocity_mm_per_s.row(k + 1).transpose() * track.period_s;
        bow = std::max((6 * (p1 - p0) - 4 * m0 - 2 * m1).norm(), (-6 * (p1 - p0) + 2 * m0 + 4 * m1).norm()) / 8;
      }
      const double delta = (p1 - p0).norm() + 3 * bow + eps + L * (turn[ks] + std::min(e_orient / R, chord_cap));
      Eigen::AlignedBox3d grown = *options.material_box;
      grown.min().array() -= R + delta;
      grown.max().array() += R + delta;
      const double H = highest_in_box(grown, p0, axis[ks], L);
      // Rounded up a little so that round-off in the distances cannot push a body point past the bound.
      reach_k[ks] = std::min(reach, std::hypot(std::max(H, 0.0), R) * (1 + 1e-9));
    }
  }
  // Interval k's sub-steps answer to the reach of both its end samples (each end's the larger of its two intervals'),
  // so that a run of two neighbouring points (always taken by the merge) meets every point's limit.
  auto interval_reach = [&](std::size_t k) {
    double r = reach_k[k];
    if (k > 0) r = std::max(r, reach_k[k - 1]);
    if (k + 1 < reach_k.size()) r = std::max(r, reach_k[k + 1]);
    return r;
  };

  // 1. Points: the samples, plus points between them where the Hermite curve bows by more than eps or the axis
  //    turns by more than phi_max. The cubic's second derivative is linear in the parameter, so its largest |p''|
  //    is at an end; a chord over 1/m of the parameter bows by at most |p''|max / (8 m^2).
  // The tips as arrays (the merge's distance checks run over them): the track's own columns when the points are the
  // samples (no Hermite sub-samples, a constant axis), else built here. The axes only for a turning tool (a constant
  // one is axis[0] everywhere).
  std::vector<double> bx, by, bz;
  std::vector<Eigen::Vector3d> axs;
  std::vector<double> rch;  // per point (turning only): the reach its sweeps answer to
  double e_hermite = 0;
  // A constant axis on a Hermite track: one pass over the columns finds the intervals that need sub-samples
  // (hermite_substeps); without any, the points are the samples and the merge reads the track's columns.
  bool samples_only = !hermite && !turning;
  if (hermite && !turning) {
    const std::vector<std::pair<Eigen::Index, int>> subs = hermite_substeps(track, eps, e_hermite);
    samples_only = subs.empty();
    if (!samples_only) {  // the samples, and the sub-samples of those intervals (the loop below's expressions)
      std::size_t extra = 0;
      for (const auto& [k, m] : subs) extra += static_cast<std::size_t>(m - 1);
      const std::size_t total = static_cast<std::size_t>(n) + extra;
      bx.resize(total), by.resize(total), bz.resize(total);
      const double* tx = track.tip_mm.col(0).data();
      const double* ty = track.tip_mm.col(1).data();
      const double* tz = track.tip_mm.col(2).data();
      std::size_t q = 0, next = 0;
      bx[q] = tx[0], by[q] = ty[0], bz[q] = tz[0], ++q;
      for (Eigen::Index k = 0; k + 1 < n; ++k) {
        if (next < subs.size() && subs[next].first == k) {
          const int m = subs[next++].second;
          const Eigen::Vector3d p0 = track.tip_mm.row(k).transpose(), p1 = track.tip_mm.row(k + 1).transpose();
          const Eigen::Vector3d m0 = track.tip_velocity_mm_per_s.row(k).transpose() * track.period_s;
          const Eigen::Vector3d m1 = track.tip_velocity_mm_per_s.row(k + 1).transpose() * track.period_s;
          for (int s = 1; s < m; ++s) {
            const Eigen::Vector3d p = hermite_point(p0, m0, p1, m1, double(s) / m);
            bx[q] = p.x(), by[q] = p.y(), bz[q] = p.z(), ++q;
          }
        }
        bx[q] = tx[k + 1], by[q] = ty[k + 1], bz[q] = tz[k + 1], ++q;
      }
    }
  } else if (!samples_only) {
    bx.reserve(static_cast<std::size_t>(n)), by.reserve(static_cast<std::size_t>(n)),
        bz.reserve(static_cast<std::size_t>(n));
    auto push = [&](const Eigen::Vector3d& p) { bx.push_back(p.x()), by.push_back(p.y()), bz.push_back(p.z()); };
    push(track.tip_mm.row(0).transpose());
    if (turning) axs.reserve(static_cast<std::size_t>(n)), axs.push_back(axis[0]), rch.push_back(reach_k[0]);
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
      const double turn_k = per_sample ? turn[ks] : 0.0;
      if (turn_k > 0) {
        const double r = interval_reach(ks);
        const double phi_max = 4 * std::asin(0.5 * chord_limit(r));  // a sub-step's half turn has the chord limit
        const double need = std::ceil(turn_k / phi_max);
        if (need > 1e6)
          throw core::Error(
              fmt::format("removal: the tool axis turns by {:.3g} degrees between track samples {} and {}: "
                          "holding it within {:.3g} mm of a {:.3g} mm tool takes {:.3g} sub-steps (over "
                          "1e6); raise the tolerance or sample the track more finely",
                          turn_k * 180 / kPi, k, k + 1, e_orient, r, need));
        m = std::max(m, static_cast<int>(need));
      }
      e_hermite = std::max(e_hermite, bow / (double(m) * m));
      for (int s = 1; s < m; ++s) {
        const double u = double(s) / m;
        if (hermite) {
          push(hermite_point(p0, m0, p1, m1, u));
        } else {
          push((1 - u) * p0 + u * p1);
        }
        if (turning)
          axs.push_back(turn_k > 0 ? slerp(axis[ks], axis[ks + 1], turn_k, u) : axis[ks]), rch.push_back(reach_k[ks]);
      }
      push(p1);
      if (turning)
        axs.push_back(axis[ks + 1]),
            rch.push_back(ks + 1 < reach_k.size() ? std::max(reach_k[ks], reach_k[ks + 1]) : reach_k[ks]);
    }
  }
  const double* px = samples_only ? track.tip_mm.col(0).data() : bx.data();
  const double* py = samples_only ? track.tip_mm.col(1).data() : by.data();
  const double* pz = samples_only ? track.tip_mm.col(2).data() : bz.data();
  const std::size_t np = samples_only ? static_cast<std::size_t>(n) : bx.size();
  auto pts = [&](std::size_t k) { return Eigen::Vector3d(px[k], py[k], pz[k]); };
  out.points = np;

  // 2. Merge: the longest run of points whose tips all stay within eps of the chord from its first point and whose
  //    axes stay within their chord limit (e_orient / reach at the point, at most 45 degrees) of its mid-axis (greedy,
  //    with a doubling search for the run's end, then a
  //    bisection: O(n log n) checks of short runs). A run of two neighbouring points is always taken: its chord is
  //    the track's (or within e_hermite of it) and its axes are a sub-step apart, within both points' limits of their
  //    middle.
  auto run_axis = [&](std::size_t a, std::size_t b) -> Eigen::Vector3d {
    if (!turning) return axis[0];
    return axs[a] == axs[b] ? axs[a] : Eigen::Vector3d((axs[a] + axs[b]).normalized());
  };
  // Each tip's squared distance to the chord (vectorised, removal/row_bounds.hpp) decides, except within a band
  // round the threshold (far wider than the round-off by which it may differ from point_segment_distance's: ~1e-12 mm
  // on coordinates of 1e3 mm), where the exact test decides as it always did. No square root per tip.
  const auto dist2 = detail::use_avx2() ? chord_dist2_avx2 : chord_dist2_generic;
  struct Chord {
    double ax, ay, az, dx, dy, dz, inv, band;
  };
  auto chord_of = [&](std::size_t a, std::size_t b) {
    Chord c{px[a], py[a], pz[a], px[b] - px[a], py[b] - py[a], pz[b] - pz[a], 0, 0};
    const double dd = c.dx * c.dx + c.dy * c.dy + c.dz * c.dz;
    c.inv = dd > 0 ? 1 / dd : 0.0;
    const double scale =
        std::max({std::abs(c.ax), std::abs(c.ay), std::abs(c.az), std::abs(c.dx), std::abs(c.dy), std::abs(c.dz)});
    c.band = 1e-14 * (1 + scale);
    return c;
  };
  auto tips_ok = [&](std::size_t a, std::size_t b) {
    const Chord c = chord_of(a, b);
    const double band = c.band + 1e-6 * eps;
    const double lo2 = eps > band ? (eps - band) * (eps - band) : 0.0, hi2 = (eps + band) * (eps + band);
    for (std::size_t k0 = a + 1; k0 < b; k0 += 32) {
      const std::size_t k1 = std::min(b, k0 + 32);
      const double m = dist2(px, py, pz, k0, k1, c.ax, c.ay, c.az, c.dx, c.dy, c.dz, c.inv);
      if (m < lo2) continue;
      if (m > hi2) return false;
      for (std::size_t k = k0; k < k1; ++k)  // a tip in the band: the exact test, tip by tip
        if (point_segment_distance(pts(k), pts(a), pts(b)) > eps) return false;
    }
    return true;
  };
  // Each point's limit on |a - a*|, with slack for round-off: sub-steps are sized to sit exactly at the limit.
  std::vector<double> chord_ok(rch.size());
  for (std::size_t k = 0; k < rch.size(); ++k) chord_ok[k] = chord_limit(rch[k]) * (1 + 1e-9);
  auto run_ok = [&](std::size_t a, std::size_t b) {
    if (!tips_ok(a, b)) return false;
    if (turning) {
      const Eigen::Vector3d c = run_axis(a, b);
      for (std::size_t k = a; k <= b; ++k)
        if ((axs[k] - c).norm() > chord_ok[k]) return false;
    }
    return true;
  };
  double e_merge = 0, e_orient_left = 0;
  const double kNoBound = std::numeric_limits<double>::infinity();
  // max_d2: a bound the caller has on the run's tips' squared distances to its chord (chord_dist2's), or infinity.
  auto emit = [&](std::size_t a, std::size_t b, double max_d2) {
    SweptTool s;
    s.tool = tool;
    s.tip0 = pts(a);
    s.axis = run_axis(a, b);
    s.d = pts(b) - pts(a);
    // The largest tip distance, exactly as before: only tips whose squared distance may reach the largest so far.
    if (b > a + 1 && !(std::sqrt(max_d2) + chord_of(a, b).band < e_merge)) {
      const Chord c = chord_of(a, b);
      for (std::size_t k0 = a + 1; k0 < b; k0 += 32) {
        const std::size_t k1 = std::min(b, k0 + 32);
        const double m = dist2(px, py, pz, k0, k1, c.ax, c.ay, c.az, c.dx, c.dy, c.dz, c.inv);
        if (std::sqrt(m) + c.band < e_merge) continue;
        for (std::size_t k = k0; k < k1; ++k)
          e_merge = std::max(e_merge, point_segment_distance(pts(k), pts(a), pts(b)));
      }
    }
    if (turning)
      for (std::size_t k = a; k <= b; ++k) e_orient_left = std::max(e_orient_left, rch[k] * (axs[k] - s.axis).norm());
    out.sweeps.push_back(s);
  };
  std::size_t a = 0;
  const std::size_t last = np - 1;
  if (last == 0) emit(0, 0, kNoBound);
  if (!turning && !detail::merge_in_place_only()) {
    // A constant axis: the same search with its checks inlined (merge_runs, removal/track_kernel.inc), a batch of
    // runs at a time; the tips in the band go to the exact test here.
    struct Exact {
      const double *x, *y, *z;
      double eps;
    } const ex{px, py, pz, eps};
    const MergeExactTest far = [](const void* ctx, std::size_t k, std::size_t s, std::size_t e) {
      const Exact& c = *static_cast<const Exact*>(ctx);
      auto p = [&](std::size_t q) { return Eigen::Vector3d(c.x[q], c.y[q], c.z[q]); };
      return point_segment_distance(p(k), p(s), p(e)) > c.eps;
    };
    const auto merge = detail::use_avx2() ? merge_runs_avx2 : merge_runs_generic;
    // Room for runs of four points on average (flower_mold's actual motion: ~11), so that the sweeps are not copied as
    // they grow; the pages beyond the sweeps made are never touched.
    out.sweeps.reserve(np / 4 + 1);
    std::size_t ends[512];
    double max_d2[512];
    while (a < last) {
      const std::size_t n = merge(px, py, pz, np, eps, far, &ex, a, ends, max_d2, 512);
      for (std::size_t q = 0; q < n; ++q) emit(a, ends[q], max_d2[q]), a = ends[q];
    }
  }
  while (a < last) {
    std::size_t good = a + 1, step = 1;
    while (good + step <= last && run_ok(a, good + step)) {
      good += step;
      step *= 2;
    }
    std::size_t lo = good, hi = std::min(last, good + step);  // lo ok, hi unknown or bad
    bool hi_bad = good + step <= last;  // the doubling stopped at a run that failed (else hi is the last point)
    while (hi > lo + 1) {
      const std::size_t mid = (lo + hi) / 2;
      if (run_ok(a, mid))
        lo = mid;
      else
        hi = mid, hi_bad = true;
    }
    // hi checked only when no check has failed it yet (checks are pure: asking again gives the same answer).
    if (!hi_bad && hi > lo && run_ok(a, hi)) lo = hi;
    emit(a, lo, kNoBound);
    a = lo;
  }
  out.orientation_error_mm = e_orient_left;
  out.error_bound_mm = e_hermite + e_merge + out.orientation_error_mm;
  out.runs.push_back({0, 0, out.sweeps.size()});
  return out;
}

TrackSweeps sweeps_from_track(const std::vector<Tool>& tools, const PoseTrack& track, const TrackOptions& options) {
  if (tools.empty()) throw core::Error("removal: no tool to cut the track with");
  const Eigen::Index n = track.tip_mm.rows();
  if (track.tool.empty()) return sweeps_from_track(tools[0], track, options);
  if (static_cast<Eigen::Index>(track.tool.size()) != n)
    throw core::Error(fmt::format("removal: the track has {} tip samples but {} tool indices", n, track.tool.size()));
  for (std::size_t k = 0; k < track.tool.size(); ++k)
    if (track.tool[k] < 0 || track.tool[k] >= static_cast<int>(tools.size()))
      throw core::Error(fmt::format("removal: track sample {} names tool {} of {}", k, track.tool[k], tools.size()));
  const bool per_sample = track.axis_per_sample.rows() == n && n > 0;
  const bool hermite = track.tip_velocity_mm_per_s.rows() == n && n > 0;
  TrackSweeps out;
  for (Eigen::Index a = 0; a < n;) {
    Eigen::Index b = a;
    while (b + 1 < n && track.tool[static_cast<std::size_t>(b + 1)] == track.tool[static_cast<std::size_t>(a)]) ++b;
    // The run's own track: from the sample before it (the new tool starts where the axes stood) to its last.
    const Eigen::Index first = std::max<Eigen::Index>(0, a - 1), rows = b - first + 1;
    PoseTrack part;
    part.period_s = track.period_s;
    part.axis = track.axis;
    part.tip_mm = track.tip_mm.middleRows(first, rows);
    if (per_sample) part.axis_per_sample = track.axis_per_sample.middleRows(first, rows);
    if (hermite) part.tip_velocity_mm_per_s = track.tip_velocity_mm_per_s.middleRows(first, rows);
    const int t = track.tool[static_cast<std::size_t>(a)];
    TrackSweeps r = sweeps_from_track(tools[static_cast<std::size_t>(t)], part, options);
    out.runs.push_back({t, out.sweeps.size(), r.sweeps.size()});
    out.sweeps.insert(out.sweeps.end(), r.sweeps.begin(), r.sweeps.end());
    out.points += r.points;
    out.error_bound_mm = std::max(out.error_bound_mm, r.error_bound_mm);
    out.orientation_error_mm = std::max(out.orientation_error_mm, r.orientation_error_mm);
    a = b + 1;
  }
  return out;
}

}  // namespace vmsim::removal
