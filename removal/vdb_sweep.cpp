#include "removal/vdb_sweep.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::removal {

namespace {

double segment_distance(const Eigen::Vector3d& w, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1) {
  const Eigen::Vector3d f = p1 - p0;
  const double ff = f.squaredNorm();
  const double t = ff > 0 ? std::clamp((w - p0).dot(f) / ff, 0.0, 1.0) : 0.0;
  return (w - p0 - t * f).norm();
}

// Distance from w to the parallelogram {s f1 + l f2 : s, l in [0, 1]} (either side may be zero).
double parallelogram_distance(const Eigen::Vector3d& w, const Eigen::Vector3d& f1, const Eigen::Vector3d& f2) {
  const double g11 = f1.squaredNorm(), g12 = f1.dot(f2), g22 = f2.squaredNorm();
  const double det = g11 * g22 - g12 * g12;
  if (det > 1e-12 * g11 * g22 && g11 > 0 && g22 > 0) {
    const double b1 = w.dot(f1), b2 = w.dot(f2);
    const double s = (g22 * b1 - g12 * b2) / det, l = (g11 * b2 - g12 * b1) / det;
    if (s >= 0 && s <= 1 && l >= 0 && l <= 1) return (w - s * f1 - l * f2).norm();
  }
  const Eigen::Vector3d o = Eigen::Vector3d::Zero();
  return std::min({segment_distance(w, o, f1), segment_distance(w, f2, f2 + f1), segment_distance(w, o, f2),
                   segment_distance(w, f1, f1 + f2)});
}

// Signed distance to a solid cylinder from its radial excess dr (|radial| - radius) and axial excess dz (positive
// beyond the nearer end plane): the rectangle SDF of the meridian section.
double cylinder_sd(double dr, double dz) {
  return std::hypot(std::max(dr, 0.0), std::max(dz, 0.0)) + std::min(std::max(dr, dz), 0.0);
}

double interval_distance(double x, double lo, double hi) { return x < lo ? lo - x : (x > hi ? x - hi : 0.0); }

// Golden-section minimum of f on [lo, hi] (f unimodal there), `iters` reductions.
template <class F>
double golden_min(F&& f, double lo, double hi, int iters) {
  const double g = 0.5 * (std::sqrt(5.0) - 1);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = f(x1), f2 = f(x2);
  for (int it = 0; it < iters; ++it) {
    if (f1 < f2) {
      hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = f(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = f(x2);
    }
  }
  return std::min(f1, f2);
}

}  // namespace

SweepDistance::SweepDistance(const SweptTool& s) : s_(s) {
  a_ = s.axis.normalized();
  rc_ = s.tool.corner_radius_mm;
  rho_ = std::max(0.0, s.tool.disk_radius());
  hgt_ = std::max(0.0, s.tool.length_mm - 2 * rc_);
  c_ = s.tip0 + rc_ * a_;
  d_ = s.d;
  delta_ = a_.dot(d_);
  e_ = d_ - delta_ * a_;
  ee_ = e_.squaredNorm();
  const double dl = d_.norm();
  if (rho_ <= 0) {
    kind_ = Kind::Ball;
  } else if (dl == 0) {
    kind_ = Kind::Still;
  } else if (std::abs(delta_) <= 1e-12 * dl) {
    // Perpendicular to the axis to within 1e-12 rad: the axial drift over the move is below 1e-12 of its length.
    kind_ = Kind::Level;
  } else if (std::sqrt(ee_) <= 1e-12 * dl) {
    kind_ = Kind::Plunge;
  } else {
    kind_ = Kind::Oblique;
    const Eigen::Vector3d dh = d_ / dl;
    u_ = a_.cross(dh).normalized();
    v_ = dh.cross(u_);
    b_ = rho_ * std::abs((e_ / std::sqrt(ee_)).dot(v_));
    h_ = hgt_ * a_.dot(v_);
    if (h_ < 0) {
      v_ = -v_;
      h_ = -h_;
    }
    const double kPi = 3.14159265358979323846;
    for (int i = 0; i <= kEllipseSamples; ++i) {
      const double t = i * kPi / kEllipseSamples;
      ex_[i] = rho_ * std::cos(t);
      ey_[i] = -b_ * std::sin(t);
    }
  }
}

double SweepDistance::operator()(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d w = p - c_;
  const double A = a_.dot(w);
  const Eigen::Vector3d m = w - A * a_;
  switch (kind_) {
    case Kind::Ball:
      return parallelogram_distance(w, hgt_ * a_, d_) - rc_;
    case Kind::Still:
      return cylinder_sd(m.norm() - rho_, std::max(-A, A - hgt_)) - rc_;
    case Kind::Level:
      return cylinder_sd(segment_distance(m, Eigen::Vector3d::Zero(), e_) - rho_, std::max(-A, A - hgt_)) - rc_;
    case Kind::Plunge: {
      const double lo = std::min(0.0, delta_), hi = hgt_ + std::max(0.0, delta_);
      return cylinder_sd(m.norm() - rho_, std::max(lo - A, A - hi)) - rc_;
    }
    case Kind::Oblique:
      break;
  }
  // Inside K iff some l in [0, 1] has the axial (0 <= A - l delta <= hgt) and radial (|m - l e| <= rho) conditions.
  double lo = 0, hi = 1;
  {
    double l1 = (A - hgt_) / delta_, l2 = A / delta_;
    if (l1 > l2) std::swap(l1, l2);
    lo = std::max(lo, l1);
    hi = std::min(hi, l2);
  }
  const double me = m.dot(e_), disc = me * me - ee_ * (m.squaredNorm() - rho_ * rho_);
  bool inside = false;
  if (disc >= 0 && lo <= hi) {
    const double sq = std::sqrt(disc);
    inside = std::max(lo, (me - sq) / ee_) <= std::min(hi, (me + sq) / ee_);
  }
  return (inside ? -core_depth(w, A, m) : core_outside(w, A, m)) - rc_;
}

double SweepDistance::core_outside(const Eigen::Vector3d& /*w*/, double A, const Eigen::Vector3d& m) const {
  // g(l) = dist(p - l d, cylinder)^2: convex in l (the distance to a convex set along a line is convex).
  auto g = [&](double l) {
    const double dr = std::max(0.0, (m - l * e_).norm() - rho_), dz = interval_distance(A - l * delta_, 0.0, hgt_);
    return dr * dr + dz * dz;
  };
  return std::sqrt(std::min({golden_min(g, 0.0, 1.0, 60), g(0.0), g(1.0)}));
}

double SweepDistance::core_depth(const Eigen::Vector3d& w, double A, const Eigen::Vector3d& m) const {
  const double d1 = rho_ - segment_distance(m, Eigen::Vector3d::Zero(), e_);
  const double d2 = std::min(A + std::max(0.0, -delta_), hgt_ + std::max(0.0, delta_) - A);
  double best = std::min(d1, d2);
  // D3: K seen along d is the ellipse (rho, b) about 0 swept to (0, h): its lower arc about 0, its upper arc about h.
  const double x = w.dot(u_), y = w.dot(v_);
  best = std::min(best, half_ellipse_distance(x, y));
  best = std::min(best, half_ellipse_distance(x, h_ - y));
  return best;
}

// Distance from (x, y) to the lower half {(rho cos t, -b sin t) : t in [0, pi]} of the ellipse (rho, b) about 0:
// sampled every pi/32 (tables), each sampled local minimum refined by Newton's method on f'(t) = 0 within its bracket
// of +-pi/32 (quadratic convergence from a start that close; golden section when a step leaves the bracket or f'' <=
// 0), to 1e-10 rad.
double SweepDistance::half_ellipse_distance(double x, double y) const {
  x = std::abs(x);
  auto f = [&](double t) {
    const double dx = rho_ * std::cos(t) - x, dy = -b_ * std::sin(t) - y;
    return dx * dx + dy * dy;
  };
  constexpr int kN = kEllipseSamples;
  const double kPi = 3.14159265358979323846, step = kPi / kN;
  double fs[kN + 1];
  for (int i = 0; i <= kN; ++i) {
    const double dx = ex_[i] - x, dy = ey_[i] - y;
    fs[i] = dx * dx + dy * dy;
  }
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= kN; ++i) {
    if ((i > 0 && fs[i - 1] < fs[i]) || (i < kN && fs[i + 1] < fs[i])) continue;
    best = std::min(best, fs[i]);
    const double lo = std::max(0.0, (i - 1) * step), hi = std::min(kPi, (i + 1) * step);
    double t = i * step;
    bool ok = false;
    for (int it = 0; it < 12; ++it) {
      const double s = std::sin(t), c = std::cos(t);
      // f/2 = ((rho c - x)^2 + (b s + y)^2) / 2: g = f'/2, gp = f''/2.
      const double g = -rho_ * s * (rho_ * c - x) + b_ * c * (b_ * s + y);
      const double gp = -rho_ * c * (rho_ * c - x) + rho_ * rho_ * s * s - b_ * s * (b_ * s + y) + b_ * b_ * c * c;
      if (!(gp > 0)) break;
      const double tn = t - g / gp;
      if (tn < lo || tn > hi) break;
      const double dt = std::abs(tn - t);
      t = tn;
      if (dt < 1e-10) {
        ok = true;
        break;
      }
    }
    best = std::min(best, ok ? f(t) : golden_min(f, lo, hi, 40));
  }
  return std::sqrt(best);
}

}  // namespace vmsim::removal
