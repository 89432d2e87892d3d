#include "removal/cut.hpp"

#include "removal/row_bounds.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::removal {

namespace {

// A ball-end sweep whose axis is the grid's ray direction (3-axis work on a z-map), with everything that does not
// depend on the ray hoisted: the same closed form as swept_tool.cpp's axial case, about 30 flops and 3 square
// roots per ray, and the exact range of columns the sweep's shadow covers on each row.
struct AxialBall {
  double R, L, cu, cv, cw;   // ball centre at the start, grid frame (relative to the grid origin)
  double eu, ev, ee, el, inv_ee, delta, kk;
};

bool axial_ball(const DexelGrid& g, const SweptTool& s, AxialBall& b) {
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

// The exact cut on each ray of a row chunk (removal/row_bounds.inc, built twice: plain and for AVX2; the AVX2 build
// is chosen at run time when the CPU has it; both give the same bits).
// Where the sweep's top ends on the ray at (qu, qv) (relative to the ball centre's start, grid frame): the highest
// point of the tool's rounded top over the move, the mirror of the lowest point's closed form.
double axial_ball_top(const AxialBall& b, double qv, double qu) {
  const double R2 = b.R * b.R;
  const double pe = qu * b.eu + qv * b.ev, cr = qu * b.ev - qv * b.eu;
  const double dperp2 = cr * cr * b.inv_ee, rr = std::sqrt(std::max(0.0, R2 - dperp2));
  const double lstar = pe * b.inv_ee, half = rr / b.el;
  const double la = std::max(0.0, lstar - half), lb = std::min(1.0, lstar + half);
  const double lhi = std::clamp(lstar + b.kk * rr / b.el, la, lb);
  const double r2hi = dperp2 + b.ee * (lhi - lstar) * (lhi - lstar);
  return (b.cw - b.R) + b.delta * lhi + b.L - b.R + std::sqrt(std::max(0.0, R2 - r2hi));
}

bool use_avx2() {
  static const bool yes = __builtin_cpu_supports("avx2");
  return yes;
}

std::size_t cut_row_axial_ball(DexelGrid& g, const AxialBall& b, int j, int i0, int i1) {
  const double qv = g.v_of(j) - b.cv, Rel = b.R * b.el;
  // Columns whose distance to the centre's segment line is within R, and whose projection falls within R of it.
  double lo = i0 * g.du() - b.cu, hi = i1 * g.du() - b.cu;  // q_u range
  if (std::abs(b.ev) > 1e-15) {
    double a1 = (qv * b.eu - Rel) / b.ev, a2 = (qv * b.eu + Rel) / b.ev;
    if (a1 > a2) std::swap(a1, a2);
    lo = std::max(lo, a1), hi = std::min(hi, a2);
  } else if (std::abs(qv * b.eu) > Rel) {
    return 0;
  }
  if (std::abs(b.eu) > 1e-15) {
    double a1 = (-Rel - qv * b.ev) / b.eu, a2 = (b.ee + Rel - qv * b.ev) / b.eu;
    if (a1 > a2) std::swap(a1, a2);
    lo = std::max(lo, a1), hi = std::min(hi, a2);
  }
  if (lo > hi) return 0;
  const int ia = std::max(i0, static_cast<int>(std::ceil((lo + b.cu) / g.du() - 1e-9)));
  const int ib = std::min(i1, static_cast<int>(std::floor((hi + b.cu) / g.du() + 1e-9)));
  if (ia > ib) return 0;
  RowCutParams p;
  p.R = b.R, p.L = b.L, p.cu = b.cu, p.eu = b.eu, p.ev = b.ev, p.ee = b.ee, p.inv_ee = b.inv_ee, p.inv_el = 1 / b.el;
  p.delta = b.delta, p.kk = b.kk, p.base_w = b.cw - b.R, p.du = g.du();
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

GeneralRows general_rows(const DexelGrid& g, const SweptTool& s) {
  GeneralRows r;
  const Eigen::Vector3d p0 = s.tip0 - g.origin(), la = s.tool.length_mm * s.axis;
  const Eigen::Vector3d c[4] = {p0, p0 + la, p0 + la + s.d, p0 + s.d};
  for (int k = 0; k < 4; ++k) r.pu[k] = c[k].dot(g.U()), r.pv[k] = c[k].dot(g.V());
  r.R = s.tool.radius_mm * (1 + 1e-9) + 1e-6;
  return r;
}

// The u-range [lo, hi] of the row v within R of the segment (pu0, pv0)-(pu1, pv1), widened into [lo, hi].
void stadium_row(double pu0, double pv0, double pu1, double pv1, double R, double v, double& lo, double& hi) {
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
void general_row_range(const DexelGrid& g, const GeneralRows& r, int j, int i0, int i1, int& ia, int& ib) {
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

}  // namespace

Footprint footprint(const DexelGrid& grid, const SweptTool& sweep) {
  Eigen::Vector3d lo, hi;
  sweep.bounds(lo, hi);
  double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300, wmin = 1e300, wmax = -1e300;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d p((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d q = p - grid.origin();
    umin = std::min(umin, q.dot(grid.U())), umax = std::max(umax, q.dot(grid.U()));
    vmin = std::min(vmin, q.dot(grid.V())), vmax = std::max(vmax, q.dot(grid.V()));
    wmin = std::min(wmin, q.dot(grid.W())), wmax = std::max(wmax, q.dot(grid.W()));
  }
  // Lattice rows first (a window's rows are the lattice's from v_first on), clamped in double so far-away sweeps
  // cannot overflow an int.
  const double lattice_j0 = std::ceil(vmin / grid.dv()), lattice_j1 = std::floor(vmax / grid.dv());
  Footprint f;
  f.i0 = std::max(0, static_cast<int>(std::ceil(umin / grid.du())));
  f.i1 = std::min(grid.nu() - 1, static_cast<int>(std::floor(umax / grid.du())));
  f.j0 = static_cast<int>(std::clamp(lattice_j0 - grid.v_first(), 0.0, double(grid.nv())));
  f.j1 = static_cast<int>(std::clamp(lattice_j1 - grid.v_first(), -1.0, double(grid.nv() - 1)));
  f.w0 = wmin, f.w1 = wmax;
  return f;
}

std::vector<SweptTool> sweeps_reaching(const DexelGrid& grid, const std::vector<SweptTool>& sweeps) {
  std::vector<SweptTool> out;
  for (const SweptTool& s : sweeps)
    if (!footprint(grid, s).empty()) out.push_back(s);
  return out;
}

CutStats cut(DexelGrid& grid, const std::vector<SweptTool>& sweeps) {
  constexpr int kBlock = 8;  // rows per work item
  const int nblocks = (grid.nv() + kBlock - 1) / kBlock;
  // Each sweep's footprint on the grid (the rays whose line can meet its bounding box), binned by row block.
  std::vector<Footprint> fp(sweeps.size());
  // Each sweep's extent along the rays (ray parameter), widened well beyond round-off: rays whose material lies wholly
  // outside it are left alone below.
  std::vector<std::pair<double, double>> wext(sweeps.size());
  std::vector<std::vector<int>> bins(static_cast<std::size_t>(nblocks));
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    const Footprint f = footprint(grid, sweeps[k]);
    wext[k] = {f.w0 - 1e-6 * (1 + std::abs(f.w0)), f.w1 + 1e-6 * (1 + std::abs(f.w1))};
    fp[k] = f;
    if (f.empty()) continue;
    for (int b = f.j0 / kBlock; b <= f.j1 / kBlock; ++b) bins[static_cast<std::size_t>(b)].push_back(static_cast<int>(k));
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
        for (int j = std::max(jb0, f.j0); j <= std::min(jb1, f.j1); ++j) tests += cut_row_axial_ball(grid, ab, j, f.i0, f.i1);
        continue;
      }
      const GeneralRows rows = general_rows(grid, sw);
      for (int j = std::max(jb0, f.j0); j <= std::min(jb1, f.j1); ++j) {
        int ia, ib;
        general_row_range(grid, rows, j, f.i0, f.i1, ia, ib);
        const Interval* head = grid.head_row(j);
        for (int i = ia; i <= ib; ++i) {
          // A ray whose material lies wholly before or after the sweep's extent along it is left as it is (subtract
          // would not change it): no exact test. Most rays across a tool's shank run through air.
          const Interval h = head[i];
          const auto [w0, w1] = wext[static_cast<std::size_t>(k)];
          if (!std::isnan(h.lo) && (!(h.lo <= h.hi) || w1 <= h.lo || w0 >= h.hi)) continue;
          double t0, t1;
          ++tests;
          if (!ray_interval(sw, grid.ray_origin(i, j), W, t0, t1)) continue;
          if (t1 <= 0 || t0 >= grid.length() || t1 - t0 <= 1e-9) continue;  // zero-width contacts cut nothing
          grid.subtract(i, j, t0, t1);
          ++cuts;
        }
      }
    }
  }
  return {tests, cuts};
}

}  // namespace vmsim::removal
