// The NC interpolator.
//
// Why this design (and not VPOp's per-period search with backtracking, the seeds' anchor): the issue demands
// zero limit violations measured by finite differences of the setpoints, on any path. VPOp meets the limits
// sample by sample but needs backtracking whose cost and termination are hard to bound. Here the motion
// along the path is planned in two provable steps, then checked exactly:
//  1. Geometry: the program is turned into a curvature-continuous path within the corner tolerance
//     (core/smooth_path): every setpoint is a point of it.
//  2. Speed: an acceleration-limited profile v(s) under a velocity-limit curve (feed, axis velocity,
//     centripetal acceleration, and the jerk of a changing curvature), found by forward/backward scans of
//     v^2 — then passed through a moving-average (FIR) filter of length T in time. A moving average of a
//     profile whose acceleration changes by at most A over any window of length T has jerk <= A / T: this is
//     the FIR interpolation of modern NCs (Tajima & Sencer, "Accurate real-time interpolation of rapid
//     trajectories using FIR filters", and Fanuc/Heidenhain "acceleration before interpolation"). Filtering the
//     path parameter, not the axes, keeps every setpoint on the path. Guards make the bounds hold: each point's
//     speed limit holds over v*T/2 on either side (the filter mixes positions that far apart), the acceleration
//     limits are eroded over the filter's reach, and the acceleration never flips sign without a dwell of T
//     (peaks are capped, valleys are the dwells above, exact stops dwell T).
//     The price of this simplicity against a time-optimal jerk-limited planner: about T more at each local
//     speed minimum (corners), measured in bench/README.md.
//  3. Check: axis velocity, acceleration and jerk are computed by finite differences of the setpoints, as the
//     tests and the drives see them; where a limit is exceeded (the continuous bounds above ignore O(Te)
//     discretisation terms), the limits are lowered locally and the plan is redone. The result never leaves
//     this function with a violation.
#include "motion/interp.hpp"

#include "core/error.hpp"
#include "core/huge_pages.hpp"
#include "motion/smooth_path.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <set>

namespace vmsim::motion {

namespace {

using core::units::kInf;
constexpr double kEps = 1e-12;

// Fractions of each axis limit the plan may use. The plan's continuous bounds are exact up to O(Te) terms;
// these margins keep the first plan within the limits almost everywhere, so the repair loop rarely runs.
constexpr double kVelocityMargin = 1.0;  // chords are shorter than arcs: finite-difference speed <= v
constexpr double kAccelMargin = kPlanAccelShare;
constexpr double kJerkMargin = kPlanJerkShare;
constexpr double kCurvatureShare = 0.9;      // share of axis acceleration the centripetal term may take
constexpr double kCurvatureRateShare = 0.9;  // share of axis jerk for v^3 dK/ds (blends, where a_t = 0)
// Half-width of the zone around a point of speed limit v* over which the raw profile holds v*: v* T / 2 (a dwell
// of one filter length T; see spread_speed_limits).
constexpr double kSpread = 0.5;

struct Limits6 {
  core::Vec6 v, a, j;  // path units (mm, deg) per s, s^2, s^3; +inf for axes the machine does not have
  const FeedCeiling* ceiling = nullptr;  // the feed ceiling along the path (InterpOptions), or none
};

// Path speed per unit of feed at a point of tangent t: the feed is the X Y Z speed, or the rotary axes' alone.
double feed_gain(const PathPiece& pc, const core::Vec6& t) {
  if (pc.feed_metric == PathPiece::FeedMetric::Abc || t.head<3>().norm() <= kEps) return t.tail<3>().norm();
  return t.head<3>().norm();
}

struct NodeGeom {
  double vlim = kInf;  // speed limit from feed, axis velocity, curvature and its rate (path units / s)
  core::Vec6 t_abs = core::Vec6::Zero();   // |unit tangent| per axis (max over the two sides of a junction)
  core::Vec6 k_abs = core::Vec6::Zero();   // |curvature vector| per axis
  core::Vec6 dk_abs = core::Vec6::Zero();  // |d(curvature vector)/ds| per axis
};

// Geometry and speed limit at curve parameter u of a piece.
NodeGeom node_geometry_u(const PathPiece& pc, double u, const Limits6& lim) {
  NodeGeom g;
  const PathJet j = pc.jet_at_u(u);
  g.t_abs = j.t.cwiseAbs();
  g.k_abs = j.k.cwiseAbs();
  g.dk_abs = j.dk.cwiseAbs();
  double v = kInf;
  // Programmed feed.
  if (std::isfinite(pc.feed_limit)) {
    double gain = 1.0;
    if (pc.feed_metric == PathPiece::FeedMetric::Xyz) gain = j.t.head<3>().norm();
    if (pc.feed_metric == PathPiece::FeedMetric::Abc) gain = j.t.tail<3>().norm();
    if (gain > kEps) v = std::min(v, pc.feed_limit / gain);
  }
  for (int i = 0; i < 6; ++i) {
    const double t = std::abs(j.t[i]), k = std::abs(j.k[i]), dk = std::abs(j.dk[i]);
    if (t > kEps) v = std::min(v, lim.v[i] * kVelocityMargin / t);
    if (k > kEps) v = std::min(v, std::sqrt(kCurvatureShare * lim.a[i] * kAccelMargin / k));
    if (dk > kEps) v = std::min(v, std::cbrt(kCurvatureRateShare * lim.j[i] * kJerkMargin / dk));
  }
  // The feed ceiling at this point (its smallest value between nodes is taken where the nodes are laid out).
  if (lim.ceiling && !lim.ceiling->empty()) {
    const double gain = feed_gain(pc, j.t);
    if (gain > kEps) v = std::min(v, lim.ceiling->at(pc.s_begin + pc.s_at(u)) / gain);
  }
  g.vlim = v;
  return g;
}

NodeGeom node_geometry(const PathPiece& pc, double s_local, const Limits6& lim) {
  return node_geometry_u(pc, pc.u_at(s_local), lim);
}

// Smallest speed limit on [u0, u1] of a curved piece, by bisection while the limit changes by more than 2 %
// between neighbouring points (depth <= 8: 1/256 of a node interval).
double min_speed_limit(const PathPiece& pc, double u0, double v0, double u1, double v1, const Limits6& lim, int depth) {
  const double um = 0.5 * (u0 + u1);
  const double vm = node_geometry_u(pc, um, lim).vlim;
  double v = std::min({v0, v1, vm});
  if (depth < 8 && (std::abs(vm - v0) > 0.02 * v || std::abs(vm - v1) > 0.02 * v)) {
    v = std::min(v, min_speed_limit(pc, u0, v0, um, vm, lim, depth + 1));
    v = std::min(v, min_speed_limit(pc, um, vm, u1, v1, lim, depth + 1));
  }
  return v;
}

// Largest tangential acceleration at a node moving at speed v, such that each axis keeps
//   |T_i| a_t + |K_i| v^2 <= a_i                              (acceleration), and
//   |T_i| a_t / T + 3 |K_i| v a_t + |dK_i| v^3 <= j_i         (jerk: the filter ramps a_t over T; the rate of
//                                                              v^2 K has a tangential and a geometric part).
// The geometric parts are within the limits at the node's speed limit (node_geometry), so a share of each axis'
// budget is always left for the tangential motion.
double tangential_accel(const NodeGeom& g, double v, double filter_s, const Limits6& lim) {
  double a = kInf;
  for (int i = 0; i < 6; ++i) {
    const double t = g.t_abs[i], k = g.k_abs[i], dk = g.dk_abs[i];
    const double ai = lim.a[i] * kAccelMargin, ji = lim.j[i] * kJerkMargin;
    if (t > kEps) a = std::min(a, std::max(0.0, ai - k * v * v) / t);
    const double den = t / filter_s + 3 * k * v;
    if (den > kEps) a = std::min(a, std::max(0.0, ji - dk * v * v * v) / den);
  }
  return a;
}

struct Plan {
  // Planning nodes along the path.
  std::vector<double> s;                 // arc length
  std::vector<double> vlim;              // velocity-limit curve
  std::vector<double> alim;              // tangential acceleration limit
  std::vector<char> stop;                // the axes must be at rest here (path ends, exact-stop corners)
  std::vector<double> scale_v, scale_a;  // local reductions made by the repair loop
};

// Sliding minimum of f over the windows [s_j - back_j, s_j + ahead_j]; window ends move monotonically.
std::vector<double> erode(const std::vector<double>& s, const std::vector<double>& f, const std::vector<double>& back,
                          const std::vector<double>& ahead, const std::vector<char>& skip) {
  const std::size_t n = s.size();
  std::vector<double> out(n);
  std::deque<std::size_t> dq;  // indices with increasing f
  std::size_t hi = 0, lo = 0;
  double prev_left = -kInf, prev_right = -kInf;
  for (std::size_t j = 0; j < n; ++j) {
    const double left = std::max(prev_left, s[j] - back[j]);
    const double right = std::max(prev_right, s[j] + ahead[j]);
    prev_left = left;
    prev_right = right;
    while (hi < n && s[hi] <= right) {
      if (!skip[hi]) {
        while (!dq.empty() && f[dq.back()] >= f[hi]) dq.pop_back();
        dq.push_back(hi);
      }
      ++hi;
    }
    while (lo < n && s[lo] < left) ++lo;
    while (!dq.empty() && dq.front() < lo) dq.pop_front();
    out[j] = dq.empty() ? f[j] : std::min(f[j], f[dq.front()]);
  }
  return out;
}

// Speed limits as the filter needs them. The filtered speed at time t is the mean of the raw speeds over the
// window [t - T, t], at the window's mean position. Around a point s* of limit v*, the raw profile must hold
// v <= v* long enough for a whole window to fit: over [s* - v* T / 2, s* + v* T / 2] (a dwell of T at v*,
// which is also what keeps the acceleration from flipping sign inside one window at a valley). So each node's
// limit v_j spreads over that distance: slow points spread over short distances. Computed smallest limit first,
// each node taking the first (smallest) value that reaches it. Windows that straddle a zone's edge can still
// see faster raw motion; the finite-difference check and repair below catch what this misses.
struct SpreadNodes {
  std::vector<double> s, vlim;  // planning nodes plus the zone edges, with the spread limits
  std::vector<char> stop;
  std::vector<std::size_t> base;  // the planning node at or before each node
  std::vector<char> inserted;     // a zone edge (not a planning node)
};

SpreadNodes spread_speed_limits(const std::vector<double>& s, const std::vector<double>& v,
                                const std::vector<char>& stop, double filter_s) {
  const std::size_t n = s.size();
  // Lower envelope of the zones [s_j - r_j, s_j + r_j] with value v_j, by a sweep over their edges. The profile is
  // linear in v^2 between nodes, so each edge inside an interval becomes a node: otherwise the profile could
  // accelerate into a zone from a node outside it.
  struct Event {
    double x;
    int open;  // 1 opens, 0 closes (closing sorts after opening at the same x: zones are closed intervals)
    double v;
  };
  std::vector<Event> ev;
  core::reserve_huge(ev, 2 * n);
  const double s_end = s.back();
  for (std::size_t j = 0; j < n; ++j) {
    if (stop[j] || !std::isfinite(v[j])) continue;
    const double r = kSpread * v[j] * filter_s;
    ev.push_back({std::max(0.0, s[j] - r), 1, v[j]});
    ev.push_back({std::min(s_end, s[j] + r), 0, v[j]});
  }
  std::sort(ev.begin(), ev.end(),
            [](const Event& a, const Event& b) { return a.x < b.x || (a.x == b.x && a.open > b.open); });
  // Breakpoints of the envelope: (x, value just left, value just right).
  struct Break {
    double x, left, right;
  };
  std::vector<Break> br;
  std::multiset<double> active;
  auto current = [&] { return active.empty() ? kInf : *active.begin(); };
  for (std::size_t i = 0; i < ev.size();) {
    const double x = ev[i].x, before = current();
    for (; i < ev.size() && ev[i].x == x && ev[i].open; ++i) active.insert(ev[i].v);
    const double at = current();  // zones closed at x still count at x
    for (; i < ev.size() && ev[i].x == x && !ev[i].open; ++i) active.erase(active.find(ev[i].v));
    const double after = current();
    if (at != before || at != after) br.push_back({x, before, after});
  }
  SpreadNodes out;
  core::reserve_huge(out.s, n + br.size());
  core::reserve_huge(out.vlim, n + br.size());
  std::size_t b = 0;
  double env_right = kInf;  // envelope value on the right of the last breakpoint passed
  auto push = [&](double x, double value, char st, std::size_t base, char ins) {
    out.s.push_back(x), out.vlim.push_back(value), out.stop.push_back(st), out.base.push_back(base),
        out.inserted.push_back(ins);
  };
  for (std::size_t j = 0; j < n; ++j) {
    // Edges strictly between node j-1 and node j.
    for (; b < br.size() && br[b].x < s[j]; ++b) {
      if (j > 0 && br[b].x > s[j - 1]) push(br[b].x, std::min(br[b].left, br[b].right), 0, j - 1, 1);
      env_right = br[b].right;
    }
    double e = env_right;
    for (; b < br.size() && br[b].x == s[j]; ++b) {
      e = std::min({e, br[b].left, br[b].right});
      env_right = br[b].right;
    }
    push(s[j], stop[j] ? 0.0 : std::min(v[j], e), stop[j], j, 0);
  }
  return out;
}

// Acceleration-limited profile q = v^2 under vmax with per-interval tangential acceleration limits.
std::vector<double> scan_profile(const std::vector<double>& s, const std::vector<double>& vmax,
                                 const std::vector<double>& amax) {
  const std::size_t n = s.size();
  std::vector<double> q(n);
  for (std::size_t j = 0; j < n; ++j) q[j] = vmax[j] * vmax[j];
  q.front() = 0;
  q.back() = 0;
  for (std::size_t j = 0; j + 1 < n; ++j) {
    const double a = std::min(amax[j], amax[j + 1]);
    q[j + 1] = std::min(q[j + 1], q[j] + 2 * a * (s[j + 1] - s[j]));
  }
  for (std::size_t j = n - 1; j > 0; --j) {
    const double a = std::min(amax[j], amax[j - 1]);
    q[j - 1] = std::min(q[j - 1], q[j] + 2 * a * (s[j] - s[j - 1]));
  }
  return q;
}

// Node times of a profile (constant acceleration between nodes), with a dwell at every interior stop.
std::vector<double> node_times(const std::vector<double>& s, const std::vector<double>& q,
                               const std::vector<char>& stop, double dwell_s) {
  const std::size_t n = s.size();
  std::vector<double> t(n, 0.0);
  for (std::size_t j = 0; j + 1 < n; ++j) {
    const double vs = std::sqrt(q[j]) + std::sqrt(q[j + 1]);
    const double h = s[j + 1] - s[j];
    double dt = h > 0 ? 2 * h / vs : 0.0;
    if (!std::isfinite(dt)) throw core::Error("interpolator: internal error (two consecutive stops on a path piece)");
    if (j > 0 && stop[j]) dt += dwell_s;
    t[j + 1] = t[j] + dt;
  }
  return t;
}

// A profile ready for sampling: nodes, v^2 at each (linear in s between nodes) and stop flags.
struct Profile {
  std::vector<double> s, q;
  std::vector<char> stop;
};

// Caps every peak of the profile so that the speed stays constant for at least T there: the acceleration then
// never goes from + to - inside one filter window, which would double the filtered jerk. The plateau's ends
// fall inside intervals in general; nodes are inserted there (v^2 stays linear in s on each side).
Profile cap_peaks(const std::vector<double>& s, const std::vector<double>& q_in, const std::vector<char>& stop,
                  double filter_s) {
  const std::size_t n = s.size();
  std::vector<double> q = q_in;
  const double rel = 1e-12;
  struct Cap {
    std::size_t a, b;  // nodes [a, b] are at or above the cap
    double qc, s_left, s_right;
  };
  std::vector<Cap> caps;
  // Plateau [a, b] at or above qc around [p0, p1], not crossing the valleys lo_k and hi_k on either side.
  auto reach = [&](std::size_t p0, std::size_t p1, std::size_t lo_k, std::size_t hi_k, double qc, Cap& c) {
    std::size_t a = p0, b = p1;
    while (a > lo_k && q[a - 1] >= qc) --a;
    while (b < hi_k && q[b + 1] >= qc) ++b;
    // Crossings of v^2 = qc inside the neighbouring intervals (v^2 is linear in s there).
    const double sl = (a > 0 && q[a] > q[a - 1] && q[a - 1] < qc)
                          ? s[a - 1] + (qc - q[a - 1]) / (q[a] - q[a - 1]) * (s[a] - s[a - 1])
                          : s[a];
    const double sr = (b + 1 < n && q[b] > q[b + 1] && q[b + 1] < qc)
                          ? s[b + 1] - (qc - q[b + 1]) / (q[b] - q[b + 1]) * (s[b + 1] - s[b])
                          : s[b];
    c = {a, b, qc, sl, sr};
    return (sr - sl) >= filter_s * std::sqrt(qc);
  };
  // Repeat until no peak is too short: a peak that cannot get its plateau between its two valleys is lowered to
  // the higher valley and so merges with its neighbour, which the next round treats as one hump. A plateau made
  // long enough is marked done: its crossings lie inside intervals, where the next round cannot see them.
  std::vector<char> done(n, 0);
  for (bool changed = true; changed;) {
    changed = false;
    std::size_t j = 1;
    while (j + 1 < n) {
      // A plateau [p0, p1] of equal q that is a strict local maximum.
      std::size_t p0 = j, p1 = j;
      while (p1 + 1 < n && std::abs(q[p1 + 1] - q[p0]) <= rel * q[p0]) ++p1;
      const bool peak = q[p0] > 0 && q[p0 - 1] < q[p0] * (1 - rel) && p1 + 1 < n && q[p1 + 1] < q[p0] * (1 - rel);
      if (!peak || done[p0]) {
        j = p1 + 1;
        continue;
      }
      std::size_t lo_k = p0, hi_k = p1;
      while (lo_k > 0 && q[lo_k - 1] <= q[lo_k]) --lo_k;
      while (hi_k + 1 < n && q[hi_k + 1] <= q[hi_k]) ++hi_k;
      Cap c;
      if (reach(p0, p1, lo_k, hi_k, q[p0], c)) {
        j = p1 + 1;
        continue;
      }
      const double floor_q = std::max(q[lo_k], q[hi_k]);
      double lo = floor_q, hi = q[p0];
      const bool fits = reach(p0, p1, lo_k, hi_k, floor_q, c);
      if (!fits) {
        hi = lo;  // not even the higher valley gives a long enough plateau: merge with that side
      } else {
        for (int it = 0; it < 60; ++it) {
          const double mid = 0.5 * (lo + hi);
          if (reach(p0, p1, lo_k, hi_k, mid, c))
            lo = mid;
          else
            hi = mid;
        }
      }
      reach(p0, p1, lo_k, hi_k, lo, c);
      for (std::size_t k = c.a; k <= c.b; ++k) {
        q[k] = std::min(q[k], lo);
        done[k] = fits;
      }
      caps.push_back(c);
      changed = true;
      j = c.b + 1;
    }
  }
  // The capped profile: the scanned nodes and every cap's two crossings, each at the lowest cap covering it
  // (a later cap may reach back over an earlier one's plateau and crossings).
  struct Pt {
    double s, q;
    char stop;
  };
  std::vector<Pt> pts;
  core::reserve_huge(pts, n + 2 * caps.size());
  for (std::size_t k = 0; k < n; ++k) pts.push_back({s[k], q[k], stop[k]});
  for (const Cap& c : caps) {
    pts.push_back({c.s_left, c.qc, 0});
    pts.push_back({c.s_right, c.qc, 0});
  }
  std::stable_sort(pts.begin(), pts.end(), [](const Pt& a, const Pt& b) { return a.s < b.s; });
  std::vector<const Cap*> by_left(caps.size());
  for (std::size_t i = 0; i < caps.size(); ++i) by_left[i] = &caps[i];
  std::sort(by_left.begin(), by_left.end(), [](const Cap* a, const Cap* b) { return a->s_left < b->s_left; });
  std::multimap<double, double> active;  // s_right -> qc of the caps covering the sweep position
  std::multiset<double> levels;
  std::size_t next_cap = 0;
  Profile out;
  out.s.reserve(pts.size());
  out.q.reserve(pts.size());
  out.stop.reserve(pts.size());
  for (const Pt& p : pts) {
    for (; next_cap < by_left.size() && by_left[next_cap]->s_left <= p.s; ++next_cap) {
      active.emplace(by_left[next_cap]->s_right, by_left[next_cap]->qc);
      levels.insert(by_left[next_cap]->qc);
    }
    while (!active.empty() && active.begin()->first < p.s) {
      levels.erase(levels.find(active.begin()->second));
      active.erase(active.begin());
    }
    const double qv = levels.empty() ? p.q : std::min(p.q, *levels.begin());
    if (!out.s.empty() && p.s <= out.s.back()) {  // coincident points: keep one, the lower value and any stop
      out.q.back() = std::min(out.q.back(), qv);
      out.stop.back() = out.stop.back() || p.stop;
      continue;
    }
    out.s.push_back(p.s);
    out.q.push_back(qv);
    out.stop.push_back(p.stop);
  }
  return out;
}

struct Sampled {
  std::vector<double> s_raw;  // unfiltered path parameter per sample
  std::vector<double> s;      // filtered
};

// Samples the profile every Te, then applies the moving average of M samples.
Sampled sample_and_filter(const std::vector<double>& s, const std::vector<double>& q, const std::vector<double>& t,
                          const std::vector<char>& stop, double dwell_s, double te, int m, double length) {
  Sampled out;
  const std::size_t n = s.size();
  const double total = t.back();
  const std::size_t count = static_cast<std::size_t>(std::ceil(total / te - 1e-9)) + 1;
  core::reserve_huge(out.s_raw, count);
  out.s_raw.resize(count);
  std::size_t j = 0;
  // Interval j's start, speed and acceleration, computed when the samples enter it (the same expressions as per
  // sample before: a square root and a division per interval, not per sample).
  std::size_t j_done = static_cast<std::size_t>(-1);
  double start = 0.0, v0 = 0.0, acc_j = 0.0;
  for (std::size_t k = 0; k < count; ++k) {
    const double tk = k * te;
    while (j + 1 < n - 1 && t[j + 1] <= tk) ++j;
    double sk;
    if (tk >= total) {
      sk = length;
    } else {
      // Interval j: starts at t[j] (+ dwell when node j is an interior stop), constant acceleration.
      if (j != j_done) {
        j_done = j;
        start = t[j] + ((j > 0 && stop[j]) ? dwell_s : 0.0);
        v0 = std::sqrt(q[j]);
        const double h = s[j + 1] - s[j];
        acc_j = h > 0 ? (q[j + 1] - q[j]) / (2 * h) : 0.0;
      }
      const double tau = std::max(0.0, tk - start);
      sk = std::min(s[j] + v0 * tau + 0.5 * acc_j * tau * tau, s[j + 1]);
    }
    out.s_raw[k] = sk;
  }
  // Moving average as a running window sum of offsets from the path start, recomputed from scratch every
  // 1024 samples so round-off cannot drift; its per-sample noise (~1e-13 mm) is far below what the jerk
  // (a third difference over Te^3) can see.
  const std::size_t total_count = count + static_cast<std::size_t>(m) - 1;
  core::reserve_huge(out.s, total_count);
  out.s.resize(total_count);
  auto raw = [&](std::ptrdiff_t idx) {
    return idx < 0 ? 0.0 : (static_cast<std::size_t>(idx) < count ? out.s_raw[static_cast<std::size_t>(idx)] : length);
  };
  double acc = 0.0;
  for (std::size_t k = 0; k < total_count; ++k) {
    const auto kk = static_cast<std::ptrdiff_t>(k);
    if (k % 1024 == 0) {
      acc = 0.0;
      for (int i = 0; i < m; ++i) acc += raw(kk - i);
    } else {
      acc += raw(kk) - raw(kk - m);
    }
    out.s[k] = std::clamp(acc / m, 0.0, length);
  }
  out.s.back() = length;
  return out;
}

struct Violation {
  Eigen::Index sample;
  int axis;
  int order;  // 1 velocity, 2 acceleration, 3 jerk
  double value, limit;
};

// The path-space axes by index, as messages name them.
constexpr const char* kPathAxisNames[] = {"X", "Y", "Z", "A", "B", "C"};

// The error for a limit the interpolator's passes could not keep: the first violation, at its move's line.
core::Error limit_error(const core::ToolPath& path, const Eigen::ArrayXi& move_of, const Violation& v,
                        const std::string& after) {
  const core::Move& mv =
      path.moves[static_cast<std::size_t>(move_of[std::min<Eigen::Index>(v.sample, move_of.size() - 1)])];
  return core::Error(core::located(path.source_path, mv.source_line,
                                   fmt::format("interpolator could not keep axis {} within its {} limit ({:.6g} > "
                                               "{:.6g}) {}",
                                               kPathAxisNames[v.axis],
                                               v.order == 1   ? "velocity"
                                               : v.order == 2 ? "acceleration"
                                                              : "jerk",
                                               std::abs(v.value), v.limit, after)));
}

// The setpoints of a sampled profile, written straight into `out` and checked as they are made: the path's points at
// arc lengths s (path space; the last is the path's end exactly), each sample's move (a blend: the move it leaves, then
// the one it enters), path length and speed, and the axes' positions (first and last exactly the program's points).
// Only the last four path-space points are held (issue 21: the whole path-space array was 48 B per setpoint at the
// run's memory peak). Returns the violations of the axes' limits by finite differences (rest before the first and
// after the last sample), axis by axis in sample order, at most max_report.
struct SetpointWriter {
  const core::ToolPath& path;
  const core::Machine& machine;
  double te;
  const Limits6& lim;

  std::vector<Violation> write(const SmoothPath& sp, const std::vector<double>& s, core::Setpoints& out,
                               std::size_t max_report) const {
    const Eigen::Index n = static_cast<Eigen::Index>(s.size());
    const auto axes = static_cast<Eigen::Index>(machine.axes.size());
    out.position.resize(n, axes);
    out.path_length_mm.resize(n);
    out.path_speed_mm_per_s.resize(n);
    out.move_index.resize(n);
    core::advise_huge_pages(out.position);
    core::advise_huge_pages(out.path_length_mm);
    core::advise_huge_pages(out.path_speed_mm_per_s);
    core::advise_huge_pages(out.move_index);
    // The path-space rows k-3..k as four rows x[0] (row k) .. x[3] (row k-3), rows before the first being the first
    // and rows after the last the last (the axes at rest outside the motion).
    double x[4][6];
    std::array<std::vector<Violation>, 6> per_axis;
    // Each axis' limits as the check compares them, and a cheaper bound that decides most samples without the three
    // divisions: with the reciprocals rounded, |d| * (1 / te) stays within 3 ulp of the quotient |d| / te, so a
    // product below the threshold by the relative margin kSure gives the same verdict as the quotient; the others go
    // through the divisions as before (issue 21: the divisions were most of this check's time).
    constexpr double kSlack = 1 + 1e-9;  // round-off in the differences is ~1e-12 relative; 1e-9 keeps it from repairs
    constexpr double kSure = 1 - 1e-14;
    const double inv_te = 1 / te, inv_te2 = 1 / (te * te), inv_te3 = 1 / (te * te * te);
    double tv[6], ta[6], tj[6], sv[6], sa[6], sj[6];
    bool checked[6];
    for (int i = 0; i < 6; ++i) {
      checked[i] = std::isfinite(lim.v[i]);
      tv[i] = lim.v[i] * kSlack, ta[i] = lim.a[i] * kSlack, tj[i] = lim.j[i] * kSlack;
      sv[i] = tv[i] * kSure, sa[i] = ta[i] * kSure, sj[i] = tj[i] * kSure;
    }
    // The differences ending at sample k (k up to n + 2: the axes come to rest after the last sample).
    auto check = [&](Eigen::Index k) {
      for (int i = 0; i < 6; ++i) {
        if (!checked[i] || per_axis[i].size() >= max_report) continue;
        const double x0 = x[0][i], x1 = x[1][i], x2 = x[2][i], x3 = x[3][i];
        const double d1 = x0 - x1, d2 = x0 - 2 * x1 + x2, d3 = x0 - 3 * x1 + 3 * x2 - x3;
        if (std::abs(d1) * inv_te <= sv[i] && std::abs(d2) * inv_te2 <= sa[i] && std::abs(d3) * inv_te3 <= sj[i])
          continue;
        const double v = d1 / te;
        const double a = d2 / (te * te);
        const double j = d3 / (te * te * te);
        if (std::abs(v) > tv[i])
          per_axis[i].push_back({k, i, 1, v, lim.v[i]});
        else if (std::abs(a) > ta[i])
          per_axis[i].push_back({k, i, 2, a, lim.a[i]});
        else if (std::abs(j) > tj[i])
          per_axis[i].push_back({k, i, 3, j, lim.j[i]});
      }
    };
    auto shift_in = [&x](const double* row) {
      for (int i = 0; i < 6; ++i) {
        x[3][i] = x[2][i];
        x[2][i] = x[1][i];
        x[1][i] = x[0][i];
        x[0][i] = row[i];
      }
    };
    // Each machine axis' path-space column and unit factor.
    std::array<int, 6> axis_column{};
    std::array<double, 6> axis_factor{};
    for (Eigen::Index a = 0; a < axes; ++a) {
      const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(a)];
      axis_column[static_cast<std::size_t>(a)] = ax.program_axis;
      axis_factor[static_cast<std::size_t>(a)] = ax.kind == core::AxisKind::Rotary ? core::units::kDegToRad : 1.0;
    }
    SmoothPath::Cursor cursor;
    for (Eigen::Index k = 0; k < n; ++k) {
      const double sk = s[static_cast<std::size_t>(k)];
      core::Vec6 p = sp.point(sk, cursor);
      const PathPiece& pc = sp.pieces[sp.piece_at(sk, cursor.piece)];
      out.move_index[k] = (pc.move_index == pc.move_index_next || sk < pc.s_begin + 0.5 * pc.length)
                              ? pc.move_index
                              : pc.move_index_next;
      if (k == n - 1) p = sp.end;
      if (k == 0) {
        for (int h = 0; h < 3; ++h) shift_in(p.data());
      }
      shift_in(p.data());
      for (Eigen::Index a = 0; a < axes; ++a)
        out.position(k, a) = p[axis_column[static_cast<std::size_t>(a)]] * axis_factor[static_cast<std::size_t>(a)];
      out.path_length_mm[k] = sk;
      if (k == 0) {
        out.path_speed_mm_per_s[k] = 0.0;
      } else {
        out.path_speed_mm_per_s[k] =
            (Eigen::Map<const Eigen::Vector3d>(x[0]) - Eigen::Map<const Eigen::Vector3d>(x[1])).norm() / te;
      }
      if (k >= 1) check(k);
    }
    if (n >= 1) {
      double last[6];
      for (int i = 0; i < 6; ++i) last[i] = x[0][i];
      for (Eigen::Index k = n; k < n + 3; ++k) {
        shift_in(last);
        check(k);
      }
    }
    // The motion starts and ends exactly at the program's points, without a round trip through path space.
    for (Eigen::Index a = 0; a < axes; ++a) {
      const int pa = machine.axes[static_cast<std::size_t>(a)].program_axis;
      out.position(0, a) = path.initial_position[pa];
      if (!path.moves.empty()) out.position(n - 1, a) = path.moves.back().end[pa];
    }
    std::vector<Violation> bad;
    for (const std::vector<Violation>& v : per_axis)
      for (std::size_t q = 0; q < v.size() && bad.size() < max_report; ++q) bad.push_back(v[q]);
    return bad;
  }
};

// Filter length of the interpolator's jerk model for a direction of travel: the natural jerk time A / J of the
// axes it moves (the moving average of a profile whose acceleration steps by at most A has jerk <= A / T).
double natural_jerk_time(const core::Vec6& t_abs, const Limits6& lim) {
  double at = kInf, jt = kInf;
  for (int i = 0; i < 6; ++i) {
    if (t_abs[i] <= kEps) continue;
    at = std::min(at, lim.a[i] * kAccelMargin / t_abs[i]);
    jt = std::min(jt, lim.j[i] * kJerkMargin / t_abs[i]);
  }
  return std::isfinite(at) && std::isfinite(jt) ? at / jt : 0.0;
}

// Half-width of a followed profile's repair dip, in time at the local speed: wide enough that the dip's own curvature
// adds little jerk (v depth pi^2 / (4 tau^2): 1 % of 5 m/s^3 for a 2 % dip at 50 mm/s).
constexpr double kFollowDipTime = 0.2;

struct Followed {
  Sampled smp;
  int passes = 0;
  std::vector<Violation> bad;  // what the last pass still exceeds (empty: none)
};

// A followed feed profile (FeedCeiling::follow): the profile's v^2 is linear in s between its points (constant
// tangential acceleration), played in time exactly, then passed through the moving average of the interpolator's
// jerk model (T = A / J): a profile made within the axes' acceleration and jerk limits keeps them through it, and the
// average only adds T to the cycle time. It does not spread minima or erode acceleration limits as the planner does
// (those guard a ceiling that is not a profile). Where a finite difference of the setpoints still exceeds a limit
// (the profile's model is continuous, the setpoints are sampled), the profile is lowered locally and smoothly (a
// raised-cosine dip in v^2, as deep as that limit needs, as wide as kFollowDipTime of travel), and played again.
// The setpoints go into `out` (the last pass's).
Followed follow_profile(const SmoothPath& sp, const FeedCeiling& c, const SetpointWriter& writer,
                        core::Setpoints& out_sp, int max_passes) {
  const Limits6& lim = writer.lim;
  const double te = writer.te;
  const double length = sp.length;
  const double tol = 1e-6 * std::max(1.0, length);
  if (sp.exact_stops > 0)
    throw core::Error(
        "interpolator: a followed feed profile needs a path without exact stops inside (give the plan as a ceiling)");
  const std::size_t n = c.s_mm.size();
  if (n < 3 || std::abs(c.s_mm.front()) > tol || c.feed_mm_per_s.front() != 0.0 ||
      std::abs(c.s_mm.back() - length) > tol || c.feed_mm_per_s.back() != 0.0)
    throw core::Error(fmt::format(
        "interpolator: a followed feed profile must start at rest at the path's start and end at rest at its end "
        "(s from 0 to {:.9g} mm, feed 0 at both); it has {} points from {:.9g} to {:.9g} mm",
        length, n, n ? c.s_mm.front() : 0.0, n ? c.s_mm.back() : 0.0));
  std::vector<double> s(c.s_mm), q(n);
  s.front() = 0.0;
  s.back() = length;
  double filter_s = te;
  std::size_t hint = 0;
  for (std::size_t j = 0; j < n; ++j) {
    hint = sp.piece_at(s[j], hint);
    const PathPiece& pc = sp.pieces[hint];
    const PathJet jet = pc.jet_s(std::clamp(s[j] - pc.s_begin, 0.0, pc.length));
    const double gain = feed_gain(pc, jet.t);
    const double v = gain > kEps ? c.feed_mm_per_s[j] / gain : c.feed_mm_per_s[j];
    q[j] = v * v;
    filter_s = std::max(filter_s, natural_jerk_time(jet.t.cwiseAbs(), lim));
  }
  const int m = std::max(1, static_cast<int>(std::ceil(filter_s / te - 1e-9)));
  std::vector<char> stop(n, 0);
  stop.front() = stop.back() = 1;
  Followed out;
  std::vector<double> w(n);
  for (int pass = 0;; ++pass) {
    const std::vector<double> t = node_times(s, q, stop, 0.0);
    out.smp = sample_and_filter(s, q, t, stop, 0.0, te, m, length);
    out.bad = writer.write(sp, out.smp.s, out_sp, 100000);
    out.passes = pass;
    if (out.bad.empty() || pass + 1 >= max_passes) return out;
    // A dip around each offending sample's stretch of the path (the filter window and the differences behind it),
    // deep enough to bring that limit back with 2 % to spare: velocity scales with sqrt(v^2), acceleration with v^2,
    // jerk with v^3 along a given stretch.
    std::fill(w.begin(), w.end(), 0.0);
    const Eigen::Index nraw = static_cast<Eigen::Index>(out.smp.s_raw.size());
    const Eigen::Index ns = static_cast<Eigen::Index>(out.smp.s.size());
    for (const Violation& v : out.bad) {
      const double ratio = std::abs(v.value) / v.limit;
      const double keep = 0.98 * (v.order == 1   ? 1 / (ratio * ratio)
                                  : v.order == 2 ? 1 / ratio
                                                 : std::pow(ratio, -2.0 / 3));
      const double depth = std::clamp(1 - keep, 0.02, 0.5);
      const Eigen::Index k_hi = std::min<Eigen::Index>(v.sample, nraw - 1);
      const Eigen::Index k_lo = std::clamp<Eigen::Index>(v.sample - 3 - m, 0, nraw - 1);
      const double s_lo = std::min(out.smp.s_raw[k_lo], out.smp.s[std::clamp<Eigen::Index>(v.sample - 3, 0, ns - 1)]);
      const double s_hi = std::max(out.smp.s_raw[k_hi], out.smp.s[std::min(v.sample, ns - 1)]);
      const auto a = static_cast<std::size_t>(std::lower_bound(s.begin(), s.end(), s_lo) - s.begin());
      const auto b = static_cast<std::size_t>(std::upper_bound(s.begin(), s.end(), s_hi) - s.begin());
      double vmax = 0.0;
      for (std::size_t j = a > 0 ? a - 1 : 0; j < std::min(n, b + 1); ++j) vmax = std::max(vmax, std::sqrt(q[j]));
      const double r = std::max(kFollowDipTime * vmax, 4 * (s_hi - s_lo) + 1e-3);  // mm
      const double mid = 0.5 * (s_lo + s_hi), half = 0.5 * (s_hi - s_lo);
      const auto ja = static_cast<std::size_t>(std::lower_bound(s.begin(), s.end(), mid - half - r) - s.begin());
      for (std::size_t j = ja; j < n && s[j] <= mid + half + r; ++j) {
        const double d = std::max(0.0, std::abs(s[j] - mid) - half) / r;
        w[j] = std::max(w[j], depth * 0.5 * (1 + std::cos(core::units::kPi * std::min(1.0, d))));
      }
    }
    for (std::size_t j = 0; j < n; ++j) q[j] *= 1.0 - w[j];
  }
}

// Axis limits in path space (rotary axes in degrees); +inf for axes the machine lacks (they must not move).
Limits6 path_limits(const core::Machine& machine) {
  Limits6 lim;
  lim.v.setConstant(kInf);
  lim.a.setConstant(kInf);
  lim.j.setConstant(kInf);
  for (const core::MachineAxis& ax : machine.axes) {
    const double f = ax.kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0;
    lim.v[ax.program_axis] = ax.max_velocity * f;
    lim.a[ax.program_axis] = ax.max_acceleration * f;
    lim.j[ax.program_axis] = ax.max_jerk * f;
  }
  return lim;
}

SmoothPathOptions smooth_path_options(const Limits6& lim, const InterpOptions& options) {
  SmoothPathOptions sopt;
  sopt.tolerance_mm = options.tolerance_mm;
  sopt.axis_jerk = lim.j;
  sopt.axis_accel = lim.a;
  sopt.rapid_speed = lim.v.head<3>().minCoeff();
  sopt.feed_scale = options.feed_scale;
  sopt.period_s = options.period_s;
  sopt.axis_velocity = lim.v;
  sopt.plan_accel_share = kAccelMargin;
  sopt.plan_jerk_share = kJerkMargin;
  return sopt;
}

// Travel limits of the machine.
void check_travel(const core::Setpoints& out, const core::Machine& machine, const core::ToolPath& path) {
  for (std::size_t a = 0; a < machine.axes.size(); ++a) {
    const core::MachineAxis& ax = machine.axes[a];
    if (ax.continuous) continue;
    const auto col = out.position.col(static_cast<Eigen::Index>(a));
    for (Eigen::Index k = 0; k < col.size(); ++k) {
      if (col[k] < ax.travel_min - 1e-9 || col[k] > ax.travel_max + 1e-9) {
        const double f = ax.kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0;
        const char* unit = ax.kind == core::AxisKind::Rotary ? "deg" : "mm";
        const core::Move& mv = path.moves[static_cast<std::size_t>(std::max(0, out.move_index[k]))];
        throw core::Error(core::located(
            path.source_path, mv.source_line,
            fmt::format("axis {} reaches {:.4f} {}, outside its travel [{:g}, {:g}] {} ({})", ax.name, col[k] * f, unit,
                        ax.travel_min * f, ax.travel_max * f, unit, machine.source_file)));
      }
    }
  }
}

// A geometry given in the options must be the moves' path: contiguous pieces naming existing moves, from the path's
// start to its end.
void check_geometry(const SmoothPath& sp, const core::ToolPath& path) {
  const std::string& src = path.source_path;
  if (path.moves.empty()) {
    if (!sp.pieces.empty())
      throw core::Error(core::located(src, 0, "interpolator: a path geometry for a program without moves"));
    return;
  }
  if (sp.pieces.empty()) throw core::Error(core::located(src, 0, "interpolator: the path geometry has no pieces"));
  double s = 0.0;
  for (const PathPiece& pc : sp.pieces) {
    if (pc.move_index < 0 || pc.move_index_next < 0 || static_cast<std::size_t>(pc.move_index) >= path.moves.size() ||
        static_cast<std::size_t>(pc.move_index_next) >= path.moves.size())
      throw core::Error(
          core::located(src, 0, "interpolator: a piece of the path geometry names a move the program does not have"));
    if (std::abs(pc.s_begin - s) > 1e-9 * std::max(1.0, s) || !(pc.length > 0))
      throw core::Error(
          core::located(src, 0, "interpolator: the path geometry's pieces are not contiguous in arc length"));
    s += pc.length;
  }
  const core::Vec6 a = to_path_space(path.initial_position), b = to_path_space(path.moves.back().end);
  if ((sp.pieces.front().point_u(sp.pieces.front().u_begin) - a).cwiseAbs().maxCoeff() > 1e-6 ||
      (sp.pieces.back().point_u(sp.pieces.back().u_end) - b).cwiseAbs().maxCoeff() > 1e-6)
    throw core::Error(
        core::located(src, 0, "interpolator: the path geometry does not start and end where the moves do"));
}

}  // namespace

double FeedCeiling::at(double s) const {
  const std::size_t n = s_mm.size();
  if (n == 0) return kInf;
  if (s <= s_mm.front()) return feed_mm_per_s.front();
  if (s >= s_mm.back()) return feed_mm_per_s.back();
  const std::size_t k = static_cast<std::size_t>(std::upper_bound(s_mm.begin(), s_mm.end(), s) - s_mm.begin()) - 1;
  const double w = (s - s_mm[k]) / (s_mm[k + 1] - s_mm[k]);
  const double qa = feed_mm_per_s[k] * feed_mm_per_s[k], qb = feed_mm_per_s[k + 1] * feed_mm_per_s[k + 1];
  return std::sqrt(qa + w * (qb - qa));
}

double FeedCeiling::min_over(double s0, double s1) const {
  if (s_mm.empty()) return kInf;
  if (s1 < s0) std::swap(s0, s1);
  double v = std::min(at(s0), at(s1));
  // Breakpoints strictly inside: v^2 is linear between them, so the smallest value is at one of them or an end.
  auto it = std::upper_bound(s_mm.begin(), s_mm.end(), s0);
  for (; it != s_mm.end() && *it < s1; ++it)
    v = std::min(v, feed_mm_per_s[static_cast<std::size_t>(it - s_mm.begin())]);
  return v;
}

void FeedCeiling::check() const {
  if (s_mm.size() != feed_mm_per_s.size())
    throw core::Error(fmt::format("feed ceiling: {} positions for {} feeds", s_mm.size(), feed_mm_per_s.size()));
  for (std::size_t i = 0; i < s_mm.size(); ++i) {
    if (!std::isfinite(s_mm[i]) || (i > 0 && !(s_mm[i] > s_mm[i - 1])))
      throw core::Error(fmt::format("feed ceiling: position {} ({} mm) does not increase", i, s_mm[i]));
    // A followed profile may come to rest at a point (the ends, a cusp), never over an interval.
    const bool at_rest = follow && feed_mm_per_s[i] == 0.0 && (i == 0 || feed_mm_per_s[i - 1] != 0.0);
    if (!at_rest && (!(feed_mm_per_s[i] > 0) || !std::isfinite(feed_mm_per_s[i])))
      throw core::Error(
          fmt::format("feed ceiling: feed {} at {} mm (expected > 0: the interpolator starts and stops at "
                      "rest by itself; a followed profile may be 0 at single points)",
                      feed_mm_per_s[i], s_mm[i]));
  }
}

SmoothPath smooth_path_for(const core::ToolPath& path, const core::Machine& machine, const InterpOptions& options) {
  if (options.geometry) {
    check_geometry(*options.geometry, path);
    return *options.geometry;
  }
  return build_smooth_path(path, smooth_path_options(path_limits(machine), options));
}

InterpResult interpolate(const core::ToolPath& path, const core::Machine& machine, const InterpOptions& options) {
  if (!(options.period_s > 0) || !(options.tolerance_mm > 0) || !(options.feed_scale > 0))
    throw core::Error("interpolator: the period, the tolerance and the feed scale must be > 0");
  const double te = options.period_s;
  options.feed_ceiling.check();

  // Axis limits in path space (rotary axes in degrees); axes the machine lacks must not move.
  Limits6 lim = path_limits(machine);
  if (!options.feed_ceiling.empty()) lim.ceiling = &options.feed_ceiling;
  for (const core::Move& m : path.moves) {
    for (int i = 0; i < 6; ++i) {
      if (machine.axis_index(i) < 0 && std::abs(m.end[i] - m.start[i]) > 1e-12)
        throw core::Error(
            core::located(path.source_path, m.source_line,
                          fmt::format("the program moves axis {}, which machine \"{}\" ({}) does not have",
                                      kPathAxisNames[i], machine.name, machine.source_file)));
    }
    for (const auto* axis : {&m.tool_axis_start, &m.tool_axis_end}) {
      if (*axis && machine.kinematics == "xyz" && ((**axis) - Eigen::Vector3d::UnitZ()).norm() > 1e-9)
        throw core::Error(
            core::located(path.source_path, m.source_line,
                          "the program tilts the tool axis, which a 3-axis machine (kinematics \"xyz\") cannot do"));
    }
  }

  // The path must be continuous in axis space (readers and motion::toolpath_in_axis_space guarantee it).
  core::Vec6 at = path.initial_position;
  for (const core::Move& m : path.moves) {
    if ((m.start - at).cwiseAbs().maxCoeff() > 1e-6)
      throw core::Error(
          core::located(path.source_path, m.source_line,
                        fmt::format("move starts at ({:.6f}, {:.6f}, {:.6f}) but the axes are at ({:.6f}, {:.6f}, "
                                    "{:.6f}); was the tool path converted to axis coordinates?",
                                    m.start[0], m.start[1], m.start[2], at[0], at[1], at[2])));
    at = m.end;
  }

  SmoothPath built;
  if (options.geometry)
    check_geometry(*options.geometry, path);
  else
    built = build_smooth_path(path, smooth_path_options(lim, options));
  const SmoothPath& sp = options.geometry ? *options.geometry : built;
  if (options.check_estimate) options.check_estimate(estimate_setpoints(sp, machine, te));

  InterpResult result;
  result.stats.moves = static_cast<int>(path.moves.size());
  result.stats.blends = sp.blends;
  result.stats.exact_stops = sp.exact_stops;
  core::Setpoints& out = result.setpoints;
  out.period_s = te;
  for (const core::MachineAxis& ax : machine.axes) out.axis_names.push_back(ax.name);

  const SetpointWriter writer{path, machine, te, lim};
  if (sp.pieces.empty()) {
    // One setpoint, at the program's start (its end when it has moves: they go nowhere).
    const auto axes = static_cast<Eigen::Index>(machine.axes.size());
    out.position.resize(1, axes);
    for (Eigen::Index a = 0; a < axes; ++a) {
      const int pa = machine.axes[static_cast<std::size_t>(a)].program_axis;
      out.position(0, a) = path.moves.empty() ? path.initial_position[pa] : path.moves.back().end[pa];
    }
    out.path_length_mm = Eigen::ArrayXd::Zero(1);
    out.path_speed_mm_per_s = Eigen::ArrayXd::Zero(1);
    out.move_index = Eigen::ArrayXi::Constant(1, path.moves.empty() ? -1 : 0);
    return result;
  }

  if (lim.ceiling && lim.ceiling->follow) {
    constexpr int kMaxFollowPasses = 60;
    Followed f = follow_profile(sp, *lim.ceiling, writer, out, kMaxFollowPasses);
    if (!f.bad.empty()) {
      throw limit_error(path, out.move_index, f.bad.front(),
                        fmt::format("following the feed profile after {} passes; is the profile within the "
                                    "machine's limits?",
                                    kMaxFollowPasses));
    }
    result.stats.repair_passes = f.passes;
    result.stats.cycle_time_s = out.duration_s();
    check_travel(out, machine, path);
    return result;
  }

  // Planning nodes: 16 per blend, arcs every 5 degrees, and at most 0.5 mm apart (a feed ceiling's mean spacing
  // where it is finer).
  double node_spacing = 0.5;
  if (lim.ceiling) {
    const FeedCeiling& c = *lim.ceiling;
    if (c.s_mm.size() > 1) node_spacing = std::clamp((c.s_mm.back() - c.s_mm.front()) / (c.s_mm.size() - 1), 0.01, 0.5);
  }
  auto node_intervals = [node_spacing](const PathPiece& pc) {
    int n = 2;
    if (pc.kind == PathPiece::Kind::Quintic) n = 16;
    if (pc.kind == PathPiece::Kind::Arc)
      n = std::max(
          4, static_cast<int>(std::ceil(std::abs(pc.dtheta * (pc.u_end - pc.u_begin)) / (core::units::kPi / 36))));
    return std::max(n, static_cast<int>(std::ceil(pc.length / node_spacing)));
  };
  Plan plan;
  std::vector<NodeGeom> geom;
  {
    // The nodes' room at once (flower_mold: ~100 MB of node geometry, grown by doubling before).
    std::size_t nodes = 1;
    for (const PathPiece& pc : sp.pieces) nodes += static_cast<std::size_t>(node_intervals(pc));
    core::reserve_huge(geom, nodes);
    core::reserve_huge(plan.s, nodes);
    core::reserve_huge(plan.stop, nodes);
  }
  for (std::size_t pi = 0; pi < sp.pieces.size(); ++pi) {
    const PathPiece& pc = sp.pieces[pi];
    const int n = node_intervals(pc);
    const bool curved = pc.kind != PathPiece::Kind::Line;
    // Nodes evenly spaced in the curve parameter (no arc-length inversion; blends are nearly uniform anyway).
    const double span = pc.u_end - pc.u_begin;
    std::vector<NodeGeom> gk(n + 1);
    for (int k = 0; k <= n; ++k) gk[k] = node_geometry_u(pc, pc.u_begin + span * k / n, lim);
    // The limit between two nodes: on curved pieces, the smallest over points bisected until the limit varies by
    // less than 2 % from one point to the next (a blend's curvature can peak sharply between its nodes).
    std::vector<double> between(n, kInf);
    if (curved) {
      for (int k = 0; k < n; ++k)
        between[k] = min_speed_limit(pc, pc.u_begin + span * k / n, gk[k].vlim, pc.u_begin + span * (k + 1) / n,
                                     gk[k + 1].vlim, lim, 0);
    }
    std::vector<double> sk(n + 1);
    for (int k = 0; k <= n; ++k) sk[k] = k == 0 ? 0.0 : (k == n ? pc.length : pc.s_at(pc.u_begin + span * k / n));
    if (lim.ceiling) {
      // The ceiling's smallest value between two nodes holds at both (v^2 is linear between nodes, so the profile
      // then stays under the ceiling everywhere between them).
      for (int k = 0; k < n; ++k) {
        const double gain = std::max(feed_gain(pc, pc.jet_at_u(pc.u_begin + span * k / n).t),
                                     feed_gain(pc, pc.jet_at_u(pc.u_begin + span * (k + 1) / n).t));
        if (gain > kEps)
          between[k] = std::min(between[k], lim.ceiling->min_over(pc.s_begin + sk[k], pc.s_begin + sk[k + 1]) / gain);
      }
    }
    for (int k = 0; k <= n; ++k) {
      const double sl = sk[k];
      NodeGeom g = gk[k];
      if (k > 0) g.vlim = std::min(g.vlim, between[k - 1]);
      if (k < n) g.vlim = std::min(g.vlim, between[k]);
      if (k == 0 && !plan.s.empty()) {  // junction: the stricter of both sides
        NodeGeom& prev = geom.back();
        prev.vlim = std::min(prev.vlim, g.vlim);
        prev.t_abs = prev.t_abs.cwiseMax(g.t_abs);
        prev.k_abs = prev.k_abs.cwiseMax(g.k_abs);
        prev.dk_abs = prev.dk_abs.cwiseMax(g.dk_abs);
        continue;
      }
      plan.s.push_back(pc.s_begin + sl);
      plan.stop.push_back(0);
      geom.push_back(g);
    }
    if (pc.stop_after) plan.stop.back() = 1;
  }
  plan.stop.front() = plan.stop.back() = 1;
  const std::size_t nn = plan.s.size();

  // Filter length: the longest natural jerk time A/J of the directions travelled, in whole periods.
  double filter_s = te;
  for (const NodeGeom& g : geom) {
    double at = kInf, jt = kInf;
    for (int i = 0; i < 6; ++i) {
      if (g.t_abs[i] <= kEps) continue;
      at = std::min(at, lim.a[i] * kAccelMargin / g.t_abs[i]);
      jt = std::min(jt, lim.j[i] * kJerkMargin / g.t_abs[i]);
    }
    if (std::isfinite(at) && std::isfinite(jt)) filter_s = std::max(filter_s, at / jt);
  }
  const int m = std::max(1, static_cast<int>(std::ceil(filter_s / te - 1e-9)));
  filter_s = m * te;
  const double dwell_s = filter_s;

  plan.scale_v.assign(nn, 1.0);
  plan.scale_a.assign(nn, 1.0);
  plan.vlim.resize(nn);
  plan.alim.resize(nn);

  constexpr int kMaxPasses = 60;
  for (int pass = 0;; ++pass) {
    for (std::size_t j = 0; j < nn; ++j) {
      plan.vlim[j] = plan.stop[j] ? 0.0 : geom[j].vlim * plan.scale_v[j];
      plan.alim[j] = tangential_accel(geom[j], plan.vlim[j], filter_s, lim) * plan.scale_a[j];
      if (!(plan.alim[j] > 0)) plan.alim[j] = 1e-9;  // keeps the scans moving on degenerate nodes
    }
    // Speed limits spread for the filter, a first profile to learn how far the filter window reaches at each
    // node, the acceleration limits eroded over those windows, and the final profile (slower than the first,
    // so its windows are shorter and the erosion stays valid).
    const SpreadNodes sn = spread_speed_limits(plan.s, plan.vlim, plan.stop, filter_s);
    const std::size_t na = sn.s.size();
    std::vector<double> alim(na);
    for (std::size_t i = 0; i < na; ++i) {
      if (!sn.inserted[i]) {
        alim[i] = plan.alim[sn.base[i]];
        continue;
      }
      const PathPiece& pc = sp.pieces[sp.piece_at(sn.s[i])];
      const NodeGeom g = node_geometry(pc, sn.s[i] - pc.s_begin, lim);
      alim[i] = std::max(1e-9, tangential_accel(g, std::min(g.vlim, sn.vlim[i]), filter_s, lim) *
                                   std::min(plan.scale_a[sn.base[i]], plan.scale_a[std::min(sn.base[i] + 1, nn - 1)]));
    }
    const std::vector<double> q1 = scan_profile(sn.s, sn.vlim, alim);
    const std::vector<double> t1 = node_times(sn.s, q1, sn.stop, dwell_s);
    std::vector<double> back(na), ahead(na);
    {
      std::size_t lo = 0, hi = 0;
      for (std::size_t j = 0; j < na; ++j) {
        while (hi + 1 < na && t1[hi + 1] <= t1[j] + filter_s) ++hi;
        while (t1[lo] < t1[j] - filter_s) ++lo;
        // One node beyond each end: the window's true reach lies inside the next interval.
        ahead[j] = sn.s[std::min(hi + 1, na - 1)] - sn.s[j];
        back[j] = sn.s[j] - sn.s[lo > 0 ? lo - 1 : 0];
      }
    }
    const std::vector<double> ae = erode(sn.s, alim, back, ahead, std::vector<char>(na, 0));
    const Profile prof = cap_peaks(sn.s, scan_profile(sn.s, sn.vlim, ae), sn.stop, filter_s);
    std::vector<double> t = node_times(prof.s, prof.q, prof.stop, dwell_s);
    Sampled smp = sample_and_filter(prof.s, prof.q, t, prof.stop, dwell_s, te, m, sp.length);

    // The setpoints, checked as they are written.
    const Eigen::Index ns = static_cast<Eigen::Index>(smp.s.size());
    const std::vector<Violation> bad = writer.write(sp, smp.s, out, 100000);
    if (bad.empty()) {
      result.stats.repair_passes = pass;
      break;
    }
    if (pass + 1 >= kMaxPasses) {
      throw limit_error(path, out.move_index, bad.front(),
                        fmt::format("after {} passes; please report this program", kMaxPasses));
    }
    // Lower the limits on the nodes that fed the offending samples (the filter window and the differences).
    std::vector<char> touched(nn, 0);
    const Eigen::Index nraw = static_cast<Eigen::Index>(smp.s_raw.size());
    for (const Violation& v : bad) {
      const Eigen::Index k_hi = std::min<Eigen::Index>(v.sample, nraw - 1);
      const Eigen::Index k_lo = std::clamp<Eigen::Index>(v.sample - 3 - m, 0, nraw - 1);
      const double s_lo = smp.s_raw[k_lo], s_hi = std::max(smp.s_raw[k_hi], smp.s[std::min(v.sample, ns - 1)]);
      auto a = std::lower_bound(plan.s.begin(), plan.s.end(), s_lo) - plan.s.begin();
      auto b = std::upper_bound(plan.s.begin(), plan.s.end(), s_hi) - plan.s.begin();
      for (auto j = std::max<std::ptrdiff_t>(0, a - 1); j < std::min<std::ptrdiff_t>(nn, b + 1); ++j) touched[j] = 1;
    }
    for (std::size_t j = 0; j < nn; ++j) {
      if (!touched[j]) continue;
      plan.scale_v[j] *= 0.9;
      plan.scale_a[j] *= 0.8;
    }
  }

  result.stats.cycle_time_s = out.duration_s();

  check_travel(out, machine, path);
  return result;
}

}  // namespace vmsim::motion
