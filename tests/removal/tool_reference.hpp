#pragma once
// Independent geometry of a tool body for the removal tests: written from the body's definition (a solid of
// revolution about the axis whose meridian section is the rectangle [0, R - rc] x [rc, L - rc] grown by rc), with
// no code shared with removal/swept_tool.cpp's Minkowski-sum solvers.
//   body_sd:   signed distance of a point to the body at one pose (exact: the nearest point of a solid of
//              revolution lies in the point's meridian half-plane, so it is the 2-D distance to the section).
//   body_ray:  exact ray interval of a ball end (capsule: two spheres and a finite cylinder) or a flat end
//              (cylinder: a slab along the axis and an infinite cylinder), by the textbook quadratics.
//   swept_sd:  signed distance-like function of the body translated along d (<= 0 inside, the exact distance
//              outside): min over l in [0, 1] of body_sd(x - l d), convex in l (a convex body's signed distance
//              is convex), so golden section finds it.
//   ray_ref:   the interval of a ray in a convex set given by a convex function f (<= 0 inside): golden section
//              for the minimum of f along the ray, then bisection outwards to f = 0.
#include "removal/swept_tool.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <functional>
#include <utility>

namespace vmsim::removal::testref {

// Largest distance from the tip to a point of the body (the top rim of a flat end, the top of a ball end).
inline double reach(const Tool& t) {
  const double rc = t.corner_radius_mm;
  return std::hypot(t.length_mm - rc, t.radius_mm - rc) + rc;
}

inline double body_sd(const Tool& t, const Eigen::Vector3d& tip, const Eigen::Vector3d& axis,
                      const Eigen::Vector3d& x) {
  const Eigen::Vector3d w = x - tip;
  const double z = w.dot(axis), r = (w - z * axis).norm();
  const double rc = t.corner_radius_mm, rho = t.radius_mm - rc;
  // Rectangle [-rho, rho] x [rc, L - rc] (centre (0, L/2), half sizes (rho, L/2 - rc)), then grown by rc.
  const double qx = r - rho, qz = std::abs(z - 0.5 * t.length_mm) - (0.5 * t.length_mm - rc);
  const double outside = std::hypot(std::max(qx, 0.0), std::max(qz, 0.0)), inside = std::min(std::max(qx, qz), 0.0);
  return outside + inside - rc;
}

// Real roots of a x^2 + b x + c = 0 with a > 0; false when there are none.
inline bool roots(double a, double b, double c, double& x0, double& x1) {
  const double disc = b * b - 4 * a * c;
  if (disc < 0) return false;
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  x0 = q / a;
  x1 = q != 0 ? c / q : x0;
  if (x0 > x1) std::swap(x0, x1);
  return true;
}

// Ray o + t u (u unit) against the infinite cylinder of radius r about the line c + s a, cut to s in [s0, s1].
inline bool finite_cylinder(const Eigen::Vector3d& o, const Eigen::Vector3d& u, const Eigen::Vector3d& c,
                            const Eigen::Vector3d& a, double r, double s0, double s1, double& t0, double& t1) {
  const Eigen::Vector3d w = o - c;
  const double A = w.dot(a), B = u.dot(a);
  const Eigen::Vector3d m = w - A * a, n = u - B * a;
  double lo = -1e300, hi = 1e300;
  if (B != 0) {
    lo = (s0 - A) / B, hi = (s1 - A) / B;
    if (lo > hi) std::swap(lo, hi);
  } else if (A < s0 || A > s1) {
    return false;
  }
  const double nn = n.squaredNorm();
  if (nn > 0) {
    double r0, r1;
    if (!roots(nn, 2 * m.dot(n), m.squaredNorm() - r * r, r0, r1)) return false;
    lo = std::max(lo, r0), hi = std::min(hi, r1);
  } else if (m.squaredNorm() > r * r) {
    return false;
  }
  t0 = lo, t1 = hi;
  return lo <= hi;
}

inline bool body_ray(const Tool& t, const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, const Eigen::Vector3d& o,
                     const Eigen::Vector3d& u, double& t0, double& t1) {
  const double R = t.radius_mm, L = t.length_mm;
  if (t.corner_radius_mm == 0) return finite_cylinder(o, u, tip, axis, R, 0, L, t0, t1);
  // Capsule: the union of its cylinder and its two end spheres is convex, so the pieces' hull is the interval.
  double lo = 1e300, hi = -1e300, a, b;
  if (finite_cylinder(o, u, tip, axis, R, R, L - R, a, b)) lo = std::min(lo, a), hi = std::max(hi, b);
  for (double s : {R, L - R}) {
    const Eigen::Vector3d w = o - (tip + s * axis);
    if (roots(1.0, 2 * w.dot(u), w.squaredNorm() - R * R, a, b)) lo = std::min(lo, a), hi = std::max(hi, b);
  }
  t0 = lo, t1 = hi;
  return lo <= hi;
}

// Minimum of a convex function on [lo, hi] by golden section; returns the minimiser, value in fmin.
template <class F>
double golden(F&& f, double lo, double hi, double& fmin, double tol = 1e-13) {
  const double g = 0.5 * (std::sqrt(5.0) - 1);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = f(x1), f2 = f(x2);
  while (hi - lo > tol * std::max(1.0, std::abs(lo) + std::abs(hi))) {
    if (f1 < f2)
      hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = f(x1);
    else
      lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = f(x2);
  }
  double best = f1 < f2 ? x1 : x2;
  fmin = std::min(f1, f2);
  for (double e : {lo, hi}) {
    const double fe = f(e);
    if (fe < fmin) fmin = fe, best = e;
  }
  return best;
}

inline double swept_sd(const Tool& t, const Eigen::Vector3d& tip0, const Eigen::Vector3d& axis,
                       const Eigen::Vector3d& d, const Eigen::Vector3d& x) {
  if (d.squaredNorm() == 0) return body_sd(t, tip0, axis, x);
  double fmin;
  golden([&](double l) { return body_sd(t, tip0 + l * d, axis, x); }, 0.0, 1.0, fmin, 1e-14);
  return fmin;
}

// Interval of the ray o + t u, t in [ta, tb], in the convex set {f <= 0}. Returns the minimum of f along the ray in
// fmin (a clear miss when > 0, a tangent contact when ~0).
inline bool ray_ref(const std::function<double(const Eigen::Vector3d&)>& f, const Eigen::Vector3d& o,
                    const Eigen::Vector3d& u, double ta, double tb, double& t0, double& t1, double& fmin) {
  auto g = [&](double t) { return f(o + t * u); };
  const double tm = golden(g, ta, tb, fmin, 1e-15);
  if (fmin > 0) return false;
  auto edge = [&](double inside, double outside) {
    if (g(outside) <= 0) return outside;
    for (int k = 0; k < 200 && std::abs(outside - inside) > 1e-14 * std::max(1.0, std::abs(inside)); ++k) {
      const double mid = 0.5 * (inside + outside);
      (g(mid) <= 0 ? inside : outside) = mid;
    }
    return 0.5 * (inside + outside);
  };
  t0 = edge(tm, ta);
  t1 = edge(tm, tb);
  return true;
}

}  // namespace vmsim::removal::testref
