#pragma once
// Internal to removal/: what the dexel-grid kernel (cut.cpp) and its reference (cut_reference.cpp) share: the
// per-sweep set-up of a ball-end sweep along the rays, the exact end of its cut, and the rows of a general sweep.
#include "removal/dexel_grid.hpp"
#include "removal/row_bounds.hpp"
#include "removal/swept_tool.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::removal::detail {

// A ball-end sweep whose axis is the grid's ray direction (3-axis work on a z-map), with everything that does not
// depend on the ray hoisted: the same closed form as swept_tool.cpp's axial case, about 30 flops and 3 square
// roots per ray, and the exact range of columns the sweep's shadow covers on each row.
struct AxialBall {
  double R, L, cu, cv, cw;  // ball centre at the start, grid frame (relative to the grid origin)
  double eu, ev, ee, el, inv_ee, delta, kk;
};

inline bool axial_ball(const DexelGrid& g, const SweptTool& s, AxialBall& b) {
  if (s.tool.disk_radius() != 0 || (s.axis - g.W()).norm() > 1e-12) return false;
  const Eigen::Vector3d c = s.tip0 + s.tool.radius_mm * s.axis - g.origin();
  b.R = s.tool.radius_mm;
  b.L = s.tool.length_mm;
  b.cu = c.dot(g.U()), b.cv = c.dot(g.V()), b.cw = c.dot(g.W());
  b.eu = s.d.dot(g.U()), b.ev = s.d.dot(g.V()), b.delta = s.d.dot(g.W());
  b.ee = b.eu * b.eu + b.ev * b.ev;
  if (b.ee < 1e-18) return false;  // plunges: the general path
  b.el = std::sqrt(b.ee);
  b.inv_ee = 1 / b.ee;
  const double m = b.delta / b.el;
  b.kk = m / std::sqrt(1 + m * m);
  return true;
}

inline RowCutParams row_params(const DexelGrid& g, const AxialBall& b) {
  RowCutParams p;
  p.R = b.R, p.L = b.L, p.cu = b.cu, p.eu = b.eu, p.ev = b.ev, p.ee = b.ee, p.inv_ee = b.inv_ee, p.inv_el = 1 / b.el;
  p.delta = b.delta, p.kk = b.kk, p.base_w = b.cw - b.R, p.du = g.du();
  return p;
}

// Where the sweep's top ends on the ray at (qu, qv) (relative to the ball centre's start, grid frame): the highest
// point of the tool's rounded top over the move, the mirror of the lowest point's closed form.
inline double axial_ball_top(const AxialBall& b, double qv, double qu) {
  const double R2 = b.R * b.R;
  const double pe = qu * b.eu + qv * b.ev, cr = qu * b.ev - qv * b.eu;
  const double dperp2 = cr * cr * b.inv_ee, rr = std::sqrt(std::max(0.0, R2 - dperp2));
  const double lstar = pe * b.inv_ee, half = rr / b.el;
  const double la = std::max(0.0, lstar - half), lb = std::min(1.0, lstar + half);
  const double lhi = std::clamp(lstar + b.kk * rr / b.el, la, lb);
  const double r2hi = dperp2 + b.ee * (lhi - lstar) * (lhi - lstar);
  return (b.cw - b.R) + b.delta * lhi + b.L - b.R + std::sqrt(std::max(0.0, R2 - r2hi));
}

// The columns [ia, ib] of row j within [i0, i1] whose distance to the centre's segment line is within R and whose
// projection falls within R of it: the sweep's exact shadow on the row. False when it is empty.
inline bool axial_ball_columns(const DexelGrid& g, const AxialBall& b, int j, int i0, int i1, int& ia, int& ib) {
  const double qv = g.v_of(j) - b.cv, Rel = b.R * b.el;
  double lo = i0 * g.du() - b.cu, hi = i1 * g.du() - b.cu;  // q_u range
  if (std::abs(b.ev) > 1e-15) {
    double a1 = (qv * b.eu - Rel) / b.ev, a2 = (qv * b.eu + Rel) / b.ev;
    if (a1 > a2) std::swap(a1, a2);
    lo = std::max(lo, a1), hi = std::min(hi, a2);
  } else if (std::abs(qv * b.eu) > Rel) {
    return false;
  }
  if (std::abs(b.eu) > 1e-15) {
    double a1 = (-Rel - qv * b.ev) / b.eu, a2 = (b.ee + Rel - qv * b.ev) / b.eu;
    if (a1 > a2) std::swap(a1, a2);
    lo = std::max(lo, a1), hi = std::min(hi, a2);
  }
  if (lo > hi) return false;
  ia = std::max(i0, static_cast<int>(std::ceil((lo + b.cu) / g.du() - 1e-9)));
  ib = std::min(i1, static_cast<int>(std::floor((hi + b.cu) / g.du() + 1e-9)));
  return ia <= ib;
}

// The vectorised kernels run their AVX2 build when the CPU has it. Tests and benchmarks can ask for the generic build
// instead (set it before a cut, not during one): both give the same bits.
inline bool& generic_kernels_only() {
  static bool only = false;
  return only;
}
// Tests: cut() keeps every block in program order (no order-free pass), or replays every ray the order-free pass cut
// (its exactness net, which real cuts rarely need).
inline bool& program_order_only() {
  static bool only = false;
  return only;
}
inline bool& replay_every_ray() {
  static bool all = false;
  return all;
}
// Tests: cut() and the needles' cut use ray_interval_reference (the bull-nose solver as it was), so that the tests of
// the kernels' culls compare bit for bit with cut_reference; tests/removal/bull_nose_test.cpp compares the solvers.
inline bool& reference_bull_solver() {
  static bool ref = false;
  return ref;
}
// Tests: sweeps_from_track merges a constant-axis track with its general loop (run_ok, one check a call) instead of
// merge_runs, so that the two can be compared.
inline bool& merge_in_place_only() {
  static bool only = false;
  return only;
}
inline bool use_avx2() {
  static const bool cpu = __builtin_cpu_supports("avx2");
  return cpu && !generic_kernels_only();
}

// The columns of row j (v = j dv) whose rays can meet a sweep whose axis is not the rays' direction. The body lies
// within distance R of its axis segment [tip, tip + L a] (swept_tool.hpp: radius R, [0, L] along the axis), so the
// sweep lies within R of the parallelogram {tip0 + s L a + l d}; a ray along W meets it only where its (u, v) is
// within R of the parallelogram's projection on the grid plane, a convex set whose cross-section with the row is one
// interval: the hull of the row's crossings of the stadia round the four projected edges. The bounding box alone
// took every ray of it (a 60 mm oblique pass on the rays across it: most of 50 mm x 60 mm for a band 10 mm wide).
struct GeneralRows {
  double pu[4], pv[4];  // projected parallelogram corners (grid frame, mm), in order round it
  double R;             // radius plus a margin well beyond round-off: the range is a superset of the hit rays
};

inline GeneralRows general_rows(const DexelGrid& g, const SweptTool& s) {
  GeneralRows r;
  const Eigen::Vector3d p0 = s.tip0 - g.origin(), la = s.tool.length_mm * s.axis;
  const Eigen::Vector3d c[4] = {p0, p0 + la, p0 + la + s.d, p0 + s.d};
  for (int k = 0; k < 4; ++k) r.pu[k] = c[k].dot(g.U()), r.pv[k] = c[k].dot(g.V());
  r.R = s.tool.radius_mm * (1 + 1e-9) + 1e-6;
  return r;
}

// The u-range [lo, hi] of the row v within R of the segment (pu0, pv0)-(pu1, pv1), widened into [lo, hi].
inline void stadium_row(double pu0, double pv0, double pu1, double pv1, double R, double v, double& lo, double& hi) {
  for (int e = 0; e < 2; ++e) {  // the end disks
    const double dv = v - (e ? pv1 : pv0), pu = e ? pu1 : pu0;
    if (std::abs(dv) <= R) {
      const double w = std::sqrt(R * R - dv * dv);
      lo = std::min(lo, pu - w), hi = std::max(hi, pu + w);
    }
  }
  const double eu = pu1 - pu0, ev = pv1 - pv0, ee = eu * eu + ev * ev;
  if (ee < 1e-24) return;
  // The strip: 0 <= (x - p0).e <= ee and |e x (x - p0)| <= R |e|, both linear in u on the row.
  double a = -1e300, b = 1e300;
  auto clip = [&](double k, double c0, double cmin, double cmax) {  // cmin <= k u + c0 <= cmax
    if (std::abs(k) < 1e-300) {
      if (c0 < cmin || c0 > cmax) a = 1, b = 0;
      return;
    }
    double x0 = (cmin - c0) / k, x1 = (cmax - c0) / k;
    if (x0 > x1) std::swap(x0, x1);
    a = std::max(a, x0), b = std::min(b, x1);
  };
  const double dv = v - pv0, el = std::sqrt(ee);
  clip(eu, -pu0 * eu + dv * ev, 0, ee);
  clip(-ev, pu0 * ev + eu * dv, -R * el, R * el);
  if (a <= b) lo = std::min(lo, a), hi = std::max(hi, b);
}

// Columns [ia, ib] of row j (empty when ia > ib), within [i0, i1].
inline void general_row_range(const DexelGrid& g, const GeneralRows& r, int j, int i0, int i1, int& ia, int& ib) {
  const double v = g.v_of(j);
  double lo = 1e300, hi = -1e300;
  for (int k = 0; k < 4; ++k) {
    const int n = (k + 1) % 4;
    stadium_row(r.pu[k], r.pv[k], r.pu[n], r.pv[n], r.R, v, lo, hi);
  }
  if (lo > hi) {
    ia = 1, ib = 0;
    return;
  }
  ia = std::max(i0, static_cast<int>(std::floor(lo / g.du())));
  ib = std::min(i1, static_cast<int>(std::ceil(hi / g.du())));
}

// Each sweep's extent along the rays (ray parameter), widened well beyond round-off: a ray whose material lies wholly
// outside it is left unchanged by the sweep.
inline std::pair<double, double> widened_extent(double w0, double w1) {
  return {w0 - 1e-6 * (1 + std::abs(w0)), w1 + 1e-6 * (1 + std::abs(w1))};
}

}  // namespace vmsim::removal::detail
