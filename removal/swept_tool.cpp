#include "removal/swept_tool.hpp"
#include "core/units.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::removal {

namespace {

using core::units::kInf;

// Running [min, max] of the candidate ray parameters found on the volume's boundary.
struct Hull {
  double lo = kInf, hi = -kInf;
  void add(double t) {
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  bool empty() const { return !(lo <= hi); }
};

// Real roots of a t^2 + b t + c = 0 (a may be 0).
int quadratic_roots(double a, double b, double c, double& r0, double& r1) {
  const double scale = std::max({std::abs(a), std::abs(b), std::abs(c)});
  if (scale == 0) return 0;
  if (std::abs(a) <= 1e-14 * scale) {
    if (std::abs(b) <= 1e-14 * scale) return 0;
    r0 = r1 = -c / b;
    return 1;
  }
  double disc = b * b - 4 * a * c;
  if (disc < 0) {
    if (disc > -1e-12 * b * b)
      disc = 0;  // tangent ray: keep the touching point
    else
      return 0;
  }
  // Numerically stable form.
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  if (q == 0) {
    r0 = r1 = 0;
    return 1;
  }
  r0 = q / a;
  r1 = c / q;
  if (r0 > r1) std::swap(r0, r1);
  return 2;
}

// Tolerance of the feasibility checks of the boundary candidates (the candidates lie exactly on one constraint;
// the others are checked with this slack so that tangent cases are not lost to round-off).
constexpr double kSlack = 1e-9;
// Grazing contacts (mm): see ray_interval_axial.
constexpr double kGraze = 1e-9;

// ---- Ball end: dist(p, parallelogram c + s a + l d, s in [0, h], l in [0, 1]) <= R ----

// Ray vs the cylinder of radius R about the segment e0 + x f, x in [0, len] (f unit): crossing points whose foot
// lies on the segment.
void ray_edge_cylinder(const Eigen::Vector3d& o, const Eigen::Vector3d& u, const Eigen::Vector3d& e0,
                       const Eigen::Vector3d& f, double len, double R, Hull& h) {
  const Eigen::Vector3d w = o - e0;
  const Eigen::Vector3d wp = w - w.dot(f) * f, up = u - u.dot(f) * f;
  double r0, r1;
  const int n = quadratic_roots(up.squaredNorm(), 2 * wp.dot(up), wp.squaredNorm() - R * R, r0, r1);
  for (int i = 0; i < n; ++i) {
    const double t = i == 0 ? r0 : r1;
    const double x = (w + t * u).dot(f);
    if (x >= -kSlack && x <= len + kSlack) h.add(t);
  }
}

void ray_sphere(const Eigen::Vector3d& o, const Eigen::Vector3d& u, const Eigen::Vector3d& c, double R, Hull& h) {
  const Eigen::Vector3d w = o - c;
  double r0, r1;
  const int n = quadratic_roots(1.0, 2 * w.dot(u), w.squaredNorm() - R * R, r0, r1);
  if (n >= 1) h.add(r0);
  if (n == 2) h.add(r1);
}

// A point within R of a segment or parallelogram spanned from c by f1 (length l1) and f2 (length l2), unit f1, f2.
void ray_rounded_parallelogram(const Eigen::Vector3d& o, const Eigen::Vector3d& u, const Eigen::Vector3d& c,
                               const Eigen::Vector3d& f1, double l1, const Eigen::Vector3d& f2, double l2, double R,
                               Hull& h) {
  // Corners, edges, face: the closest point of the parallelogram is a corner, on an edge, or inside the face.
  const Eigen::Vector3d c1 = c + l1 * f1, c2 = c + l2 * f2, c3 = c1 + l2 * f2;
  ray_sphere(o, u, c, R, h);
  if (l1 > 0) {
    ray_sphere(o, u, c1, R, h);
    ray_edge_cylinder(o, u, c, f1, l1, R, h);
  }
  if (l2 > 0) {
    ray_sphere(o, u, c2, R, h);
    ray_edge_cylinder(o, u, c, f2, l2, R, h);
  }
  if (l1 > 0 && l2 > 0) {
    ray_sphere(o, u, c3, R, h);
    ray_edge_cylinder(o, u, c2, f1, l1, R, h);
    ray_edge_cylinder(o, u, c1, f2, l2, R, h);
    const Eigen::Vector3d nrm = f1.cross(f2).normalized();
    const double un = u.dot(nrm);
    if (std::abs(un) > 1e-14) {
      // In-plane coordinates by the dual basis of (f1, f2).
      const double g11 = 1.0, g12 = f1.dot(f2), g22 = 1.0, det = g11 * g22 - g12 * g12;
      for (double side : {-R, R}) {
        const double t = (side - (o - c).dot(nrm)) / un;
        const Eigen::Vector3d p = o + t * u - c;
        const double b1 = p.dot(f1), b2 = p.dot(f2);
        const double x1 = (g22 * b1 - g12 * b2) / det, x2 = (g11 * b2 - g12 * b1) / det;
        if (x1 >= -kSlack && x1 <= l1 + kSlack && x2 >= -kSlack && x2 <= l2 + kSlack) h.add(t);
      }
    }
  }
}

// ---- Flat end: p in c + disk(rho, normal a) + s a + l d, s in [0, h], l in [0, 1] ----
// In the (t, l) plane the set is {0 <= A + B t - delta l <= h, |m + t n - l e|^2 <= rho^2, 0 <= l <= 1}: a convex
// region bounded by one quadric and four lines. The extreme t lie on its boundary: at the quadric's t-extremes,
// where the quadric meets a line, or at the lines' crossings inside the quadric.
void ray_swept_disk(const Eigen::Vector3d& o, const Eigen::Vector3d& u, const Eigen::Vector3d& c,
                    const Eigen::Vector3d& a, double rho, double hgt, const Eigen::Vector3d& d, Hull& hull) {
  const Eigen::Vector3d w0 = o - c;
  const double A = a.dot(w0), B = a.dot(u), delta = a.dot(d);
  const Eigen::Vector3d m = w0 - A * a, n = u - B * a, e = d - delta * a;
  const double tol = kSlack * std::max(1.0, rho);
  auto axial_ok = [&](double t, double l) {
    const double z = A + B * t - delta * l;
    return z >= -tol && z <= hgt + tol;
  };
  auto radial_ok = [&](double t, double l) {
    return (m + t * n - l * e).squaredNorm() <= rho * rho * (1 + 1e-9) + tol * tol;
  };
  auto lambda_ok = [&](double l) { return l >= -kSlack && l <= 1 + kSlack; };
  double r0, r1;
  // (a) t-extremes of the quadric alone: the closest l for each t, then |P_e(m + t n)| = rho.
  const double ee = e.squaredNorm();
  if (ee > 1e-24) {
    const Eigen::Vector3d mp = m - (m.dot(e) / ee) * e, np = n - (n.dot(e) / ee) * e;
    const int k = quadratic_roots(np.squaredNorm(), 2 * mp.dot(np), mp.squaredNorm() - rho * rho, r0, r1);
    for (int i = 0; i < k; ++i) {
      const double t = i == 0 ? r0 : r1;
      const double l = (m + t * n).dot(e) / ee;
      if (lambda_ok(l) && axial_ok(t, l)) hull.add(t);
    }
  } else {
    // The move is along the axis: the quadric does not depend on l; l is free within the axial strip.
    const int k = quadratic_roots(n.squaredNorm(), 2 * m.dot(n), m.squaredNorm() - rho * rho, r0, r1);
    for (int i = 0; i < k; ++i) {
      const double t = i == 0 ? r0 : r1;
      // Some l in [0, 1] with 0 <= A + B t - delta l <= hgt?
      double lo = 0, hi = 1;
      const double z = A + B * t;
      if (std::abs(delta) > 1e-300) {
        const double l1 = (z - hgt) / delta, l2 = z / delta;
        lo = std::max(lo, std::min(l1, l2));
        hi = std::min(hi, std::max(l1, l2));
      } else if (z < -tol || z > hgt + tol) {
        continue;
      }
      if (lo <= hi + kSlack) hull.add(t);
    }
  }
  // (b) the lines l = 0 and l = 1 against the quadric.
  for (double l : {0.0, 1.0}) {
    const Eigen::Vector3d ml = m - l * e;
    const int k = quadratic_roots(n.squaredNorm(), 2 * ml.dot(n), ml.squaredNorm() - rho * rho, r0, r1);
    for (int i = 0; i < k; ++i) {
      const double t = i == 0 ? r0 : r1;
      if (axial_ok(t, l)) hull.add(t);
    }
  }
  // (c) the axial lines A + B t - delta l = kappa against the quadric, and (d) their crossings with l = 0, 1.
  //     Each line is written as t(l) or l(t), whichever has a slope of at most 1 in the units t (mm) and x = l |d|
  //     (mm), so that its quadratic is well conditioned. Solving for t = (kappa - A + delta l) / B when B is tiny (a
  //     ray almost perpendicular to the axis of a tool moving along it) would amplify the round-off of l by
  //     delta / B and put the candidate far off the quadric (tens of mm on a ray 1e-9 rad off the disk's plane).
  const double dl = std::sqrt(d.squaredNorm());
  for (double kappa : {0.0, hgt}) {
    if (std::abs(B) > 1e-14 && std::abs(B) * dl >= std::abs(delta)) {
      // t = (kappa - A + delta l) / B: the quadric in l.
      const Eigen::Vector3d p0 = m + ((kappa - A) / B) * n, p1 = (delta / B) * n - e;
      const int k = quadratic_roots(p1.squaredNorm(), 2 * p0.dot(p1), p0.squaredNorm() - rho * rho, r0, r1);
      for (int i = 0; i < k; ++i) {
        const double l = i == 0 ? r0 : r1;
        if (lambda_ok(l)) hull.add((kappa - A + delta * l) / B);
      }
      for (double l : {0.0, 1.0}) {
        const double t = (kappa - A + delta * l) / B;
        if (radial_ok(t, l)) hull.add(t);
      }
    } else if (std::abs(delta) > 1e-14) {
      // l = l0 + (B / delta) t: the quadric in t (B = 0: the ray lies in a plane of the disk, l is fixed).
      const double l0 = (A - kappa) / delta, bd = B / delta;
      const Eigen::Vector3d p0 = m - l0 * e, p1 = n - bd * e;
      const int k = quadratic_roots(p1.squaredNorm(), 2 * p0.dot(p1), p0.squaredNorm() - rho * rho, r0, r1);
      for (int i = 0; i < k; ++i) {
        const double t = i == 0 ? r0 : r1;
        if (lambda_ok(l0 + bd * t)) hull.add(t);
      }
      if (bd != 0) {
        for (double l : {0.0, 1.0}) {
          const double t = (l - l0) / bd;
          if (radial_ok(t, l)) hull.add(t);
        }
      }
    }
  }
}

// ---- Bull-nose on any ray: numerically, on the convex distance to the swept core ----

double dist_to_interval(double x, double lo, double hi) { return x < lo ? lo - x : (x > hi ? x - hi : 0.0); }

// Distance from p to the swept core c + disk(rho, a) + [0, h] a + [0, 1] d: a convex function of l, minimised by
// golden section (the sum of two convex terms).
double core_distance(const SweptTool& s, const Eigen::Vector3d& c, double rho, double hgt, const Eigen::Vector3d& p) {
  const Eigen::Vector3d w = p - c;
  const double A = s.axis.dot(w), delta = s.axis.dot(s.d);
  const Eigen::Vector3d m = w - A * s.axis, e = s.d - delta * s.axis;
  auto f = [&](double l) {
    const double ax = dist_to_interval(A - delta * l, 0.0, hgt);
    const double rad = std::max(0.0, (m - l * e).norm() - rho);
    return ax * ax + rad * rad;
  };
  double lo = 0, hi = 1;
  const double g = 0.5 * (std::sqrt(5.0) - 1);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = f(x1), f2 = f(x2);
  for (int it = 0; it < 60 && hi - lo > 1e-13; ++it) {
    if (f1 < f2) {
      hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = f(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = f(x2);
    }
  }
  return std::sqrt(std::min({f1, f2, f(0.0), f(1.0)}));
}

// ---- Bull-nose on any ray: bracketed by exact flat-end sweeps, refined on the distance to the swept core ----
// The body is the core C = disk(rho, a) x [rc, L - rc] (+) ball(rc). It holds the flat bodies disk(rho) x [0, L] and
// disk(R) x [rc, L - rc] and lies in disk(R) x [0, L]; so do their sweeps (a translation of a subset is a subset).
// ray_swept_disk gives those three intervals exactly: the swept body's interval [t0, t1] (a convex set's) has t0 in
// [outer t0, inner t0] and t1 in [inner t1, outer t1], and only these gaps, a fraction of rc wide, need the numerical
// solver. The solver is g(t) = dist(o + t u, K) - rc (K the swept core), convex in t, whose roots are found by the
// Illinois false position; the distance is a 1-D convex minimisation over the move's parameter l, solved on its
// continuous, nondecreasing derivative by the same method. The nested golden sections they replace (kept in
// ray_interval_reference) took ~15 000 evaluations of the core's distance per ray; this takes tens.

// dist(p, K)^2 for K = c + disk(rho, a) + [0, hgt] a + [0, 1] d: min over l in [0, 1] of F(l) = ex(l)^2 + rad(l)^2,
// ex the axial excess of A - delta l over [0, hgt], rad the radial excess of |m - l e| over rho (both convex in l).
struct CoreDistance {
  Eigen::Vector3d c, a, e;
  double rho, hgt, delta, ee;
  CoreDistance(const SweptTool& s, const Eigen::Vector3d& c0, double rho_mm, double hgt_mm)
      : c(c0), a(s.axis), rho(rho_mm), hgt(hgt_mm) {
    delta = a.dot(s.d);
    e = s.d - delta * a;
    ee = e.squaredNorm();
  }
  double squared(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d w = p - c;
    const double A = a.dot(w);
    const Eigen::Vector3d m = w - A * a;
    const double mm = m.squaredNorm(), me = m.dot(e);
    // F and its derivative at l.
    auto eval = [&](double l, double& dF) {
      const double z = A - delta * l;
      double ex = 0, dex = 0;
      if (z < 0) {
        ex = -z, dex = delta;
      } else if (z > hgt) {
        ex = z - hgt, dex = -delta;
      }
      const double n2 = std::max(0.0, mm - 2 * l * me + l * l * ee), n = std::sqrt(n2);
      double rad = 0, drad = 0;
      if (n > rho) {
        rad = n - rho;
        drad = (l * ee - me) / n;
      }
      dF = 2 * (ex * dex + rad * drad);
      return ex * ex + rad * rad;
    };
    double d0, d1;
    const double f0 = eval(0.0, d0);
    if (d0 >= 0) return f0;
    const double f1 = eval(1.0, d1);
    if (d1 <= 0) return f1;
    // F' changes sign in (0, 1): its root by false position (Illinois), the bracket kept.
    double lo = 0, hi = 1, glo = d0, ghi = d1, best = std::min(f0, f1);
    int side = 0;
    for (int it = 0; it < 100 && hi - lo > 1e-13; ++it) {
      double l = (lo * ghi - hi * glo) / (ghi - glo);
      if (!(l > lo && l < hi)) l = 0.5 * (lo + hi);
      double dl;
      const double fl = eval(l, dl);
      best = std::min(best, fl);
      if (dl == 0) break;
      if (dl < 0) {
        lo = l, glo = dl;
        if (side == -1) ghi *= 0.5;
        side = -1;
      } else {
        hi = l, ghi = dl;
        if (side == 1) glo *= 0.5;
        side = 1;
      }
    }
    return best;
  }
  double operator()(const Eigen::Vector3d& p) const { return std::sqrt(squared(p)); }
};

// A root of the convex g between x_out (g > 0) and x_in (g <= 0) by the Illinois false position, to 1e-10 mm.
template <class G>
double convex_root(const G& g, double x_out, double g_out, double x_in, double g_in) {
  int side = 0;
  for (int it = 0; it < 200 && std::abs(x_in - x_out) > 1e-10; ++it) {
    double x = (x_out * g_in - x_in * g_out) / (g_in - g_out);
    const double lo = std::min(x_in, x_out), hi = std::max(x_in, x_out);
    if (!(x > lo && x < hi)) x = 0.5 * (lo + hi);
    const double gx = g(x);
    if (gx <= 0) {
      x_in = x, g_in = gx;
      if (side == -1) g_out *= 0.5;
      side = -1;
      if (gx == 0) return x;
    } else {
      x_out = x, g_out = gx;
      if (side == 1) g_in *= 0.5;
      side = 1;
    }
  }
  return 0.5 * (x_in + x_out);
}

bool ray_interval_bull(const SweptTool& s, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double w0, double w1,
                       double& t0, double& t1) {
  const Tool& tl = s.tool;
  const double R = tl.radius_mm, rc = tl.corner_radius_mm, rho = tl.disk_radius(), L = tl.length_mm;
  const double hgt = std::max(0.0, L - 2 * rc);
  Hull outer, in1, in2;
  ray_swept_disk(o, u, s.tip0, s.axis, R, L, s.d, outer);
  if (outer.empty()) return false;
  const CoreDistance core(s, s.tip0 + rc * s.axis, rho, hgt);
  auto g = [&](double t) { return core(o + t * u) - rc; };
  double a = outer.lo, b = outer.hi;  // outer ends
  double ga = g(a), gb = g(b);
  // Both outer ends on the body (a ray through the cylindrical side, most rays across a tilted tool): they are its.
  if (ga <= 0 && gb <= 0) {
    t0 = a, t1 = b;
    return true;
  }
  ray_swept_disk(o, u, s.tip0, s.axis, rho, L, s.d, in1);
  ray_swept_disk(o, u, s.tip0 + rc * s.axis, s.axis, R, hgt, s.d, in2);
  Hull inner = in1;
  if (!in2.empty()) inner.add(in2.lo), inner.add(in2.hi);
  double tin, gin;  // a point of the ray inside the swept body
  if (!inner.empty() && inner.hi - inner.lo > 1e-9) {
    tin = 0.5 * (inner.lo + inner.hi);
    gin = g(tin);
  } else if (ga <= 0) {
    tin = a, gin = ga;
  } else if (gb <= 0) {
    tin = b, gin = gb;
  } else {
    // The ray passes the rounded corner only, or misses: golden section on the convex g until a point inside, or a
    // lower bound above 0 (the secant lines through the best point and its neighbours bound a convex function).
    const double gr = 0.5 * (std::sqrt(5.0) - 1);
    double lo = a, hi = b, glo = ga, ghi = gb;
    double x1 = hi - gr * (hi - lo), x2 = lo + gr * (hi - lo), g1 = g(x1), g2 = g(x2);
    bool found = false;
    for (int it = 0; it < 100; ++it) {
      if (g1 <= 0 || g2 <= 0) {
        found = true;
        tin = g1 <= g2 ? x1 : x2, gin = std::min(g1, g2);
        break;
      }
      // best point and its neighbours
      double p, gp, q, gq, m, gm;
      if (g1 < g2)
        p = lo, gp = glo, m = x1, gm = g1, q = x2, gq = g2;
      else
        p = x1, gp = g1, m = x2, gm = g2, q = hi, gq = ghi;
      const double sl = m > p ? (gm - gp) / (m - p) : 0.0, sr = q > m ? (gq - gm) / (q - m) : 0.0;
      if (std::min(gm + sl * (q - m), gm - sr * (m - p)) > 0 || hi - lo <= 1e-9) break;
      if (g1 < g2) {
        hi = x2, ghi = g2, x2 = x1, g2 = g1, x1 = hi - gr * (hi - lo), g1 = g(x1);
      } else {
        lo = x1, glo = g1, x1 = x2, g1 = g2, x2 = lo + gr * (hi - lo), g2 = g(x2);
      }
    }
    if (!found) return false;
  }
  // The ends: an outer end inside the body is the body's; an end beyond the ray's material [w0, w1] on the far side
  // of the inner interval needs no refinement.
  if (ga <= 0)
    t0 = a;
  else if (!inner.empty() && inner.hi - inner.lo > 1e-9 && inner.lo <= w0)
    t0 = a;
  else
    t0 = convex_root(g, a, ga, tin, gin);
  if (gb <= 0)
    t1 = b;
  else if (!inner.empty() && inner.hi - inner.lo > 1e-9 && inner.hi >= w1)
    t1 = b;
  else
    t1 = convex_root(g, b, gb, tin, gin);
  return t0 <= t1;
}

// ---- Rays parallel to the tool axis (z-maps of 3-axis work): closed forms ----
// Along such a ray the tool's cross-section at horizontal distance r from its axis spans
// [f_low(r), f_high(r)] above the tip, f_low(r) = rc - sqrt(rc^2 - (r - rho)+^2), f_high = L - f_low. Over the move
// the axis passes at distance r(l) = sqrt(dperp^2 + |e|^2 (l - l*)^2), so the ray's interval is
// [min_l (delta l + f_low(r(l))), max_l (delta l + f_high(r(l)))] over the l where r(l) <= R: each a 1-D convex
// problem, solved in closed form for ball and flat ends.
bool ray_interval_axial(const SweptTool& s, const Eigen::Vector3d& o, double sign, double& t0, double& t1) {
  const Tool& tl = s.tool;
  const double R = tl.radius_mm, rc = tl.corner_radius_mm, rho = tl.disk_radius(), L = tl.length_mm;
  const Eigen::Vector3d& a = s.axis;
  const Eigen::Vector3d w = o - s.tip0;
  const double A = a.dot(w), delta = a.dot(s.d);
  const Eigen::Vector3d q = w - A * a, e = s.d - delta * a;  // horizontal offset of the ray, horizontal move
  const double ee = e.squaredNorm();
  double lstar = 0, dperp2 = q.squaredNorm();
  if (ee > 1e-24) {
    lstar = q.dot(e) / ee;
    dperp2 = std::max(0.0, (q - lstar * e).squaredNorm());
  }
  // A ray that only grazes the tool's side (within 1 nm) is not cut: that contact has no width, and whether round-off
  // puts it in or out must not decide whether a whole ray of material goes.
  const double Rg = R - kGraze;
  if (dperp2 >= Rg * Rg) return false;
  const double el = std::sqrt(ee);
  // l-range where the axis passes within R of the ray.
  double la = 0, lb = 1;
  if (ee > 1e-24) {
    const double half = std::sqrt(R * R - dperp2) / el;
    la = std::max(0.0, lstar - half);
    lb = std::min(1.0, lstar + half);
    if (la > lb) return false;
  } else if (dperp2 > R * R) {
    return false;
  }
  auto r_of = [&](double l) { return std::sqrt(dperp2 + ee * (l - lstar) * (l - lstar)); };
  auto flow = [&](double r) {
    const double x = std::max(0.0, r - rho);
    return rc - std::sqrt(std::max(0.0, rc * rc - x * x));
  };
  double zlo, zhi;  // along +a, relative to the tip at l = 0 (the ray coordinate of a point is its a-component)
  if (rho == 0 && ee > 1e-24) {
    // Ball end: g(l) = delta l - sqrt(R^2 - r(l)^2) + R. Stationary where s = el (l - l*) solves
    // s / sqrt(R^2 - dperp^2 - s^2) = -delta / el, i.e. s = -m sqrt(R^2 - dperp^2) / sqrt(1 + m^2), m = delta / el.
    const double rr = std::sqrt(std::max(0.0, R * R - dperp2)), mslope = delta / el;
    const double sl = -mslope * rr / std::sqrt(1 + mslope * mslope);
    const double l_lo = std::clamp(lstar + sl / el, la, lb), l_hi = std::clamp(lstar - sl / el, la, lb);
    zlo = delta * l_lo + flow(r_of(l_lo));
    zhi = delta * l_hi + (L - flow(r_of(l_hi)));
  } else if (rc == 0 || ee <= 1e-24) {
    // Flat end (f_low = 0 inside the disk), or a plunge (r constant): the ends of the l-range decide.
    const double fl_a = flow(r_of(la)), fl_b = flow(r_of(lb));
    zlo = std::min(delta * la + fl_a, delta * lb + fl_b);
    zhi = std::max(delta * la + L - fl_a, delta * lb + L - fl_b);
    if (rc > 0 && ee <= 1e-24) {  // plunge: r is constant
      zlo = std::min(0.0, delta) + fl_a;
      zhi = std::max(0.0, delta) + L - fl_a;
    }
  } else {
    // Bull-nose moving sideways: golden section on the convex g(l) = delta l + f_low(r(l)) (and its mirror).
    auto golden = [&](auto&& g) {
      double lo = la, hi = lb;
      const double gr = 0.5 * (std::sqrt(5.0) - 1);
      double x1 = hi - gr * (hi - lo), x2 = lo + gr * (hi - lo), g1 = g(x1), g2 = g(x2);
      for (int it = 0; it < 80 && hi - lo > 1e-14; ++it) {
        if (g1 < g2)
          hi = x2, x2 = x1, g2 = g1, x1 = hi - gr * (hi - lo), g1 = g(x1);
        else
          lo = x1, x1 = x2, g1 = g2, x2 = lo + gr * (hi - lo), g2 = g(x2);
      }
      return std::min({g1, g2, g(la), g(lb)});
    };
    zlo = golden([&](double l) { return delta * l + flow(r_of(l)); });
    zhi = -golden([&](double l) { return -(delta * l + L - flow(r_of(l))); });
  }
  // Ray coordinate t of a point at height z (along a) above the tip: z = A + sign t.
  if (sign > 0) {
    t0 = zlo - A;
    t1 = zhi - A;
  } else {
    t0 = A - zhi;
    t1 = A - zlo;
  }
  return t0 <= t1;
}

}  // namespace

Tool make_tool(const core::ToolSpec& spec) {
  Tool t;
  t.radius_mm = spec.diameter_mm / 2;
  t.corner_radius_mm = spec.shape == core::ToolShape::Ball   ? t.radius_mm
                       : spec.shape == core::ToolShape::Flat ? 0.0
                                                             : spec.corner_radius_mm;
  t.length_mm = std::max(spec.length_mm, 2 * t.corner_radius_mm);
  return t;
}

double Tool::reach() const {
  const double rc = corner_radius_mm;
  return std::hypot(length_mm - rc, radius_mm - rc) + rc;
}

void SweptTool::bounds(Eigen::Vector3d& lo, Eigen::Vector3d& hi) const {
  // Extent of the body about its axis: radius R across, [0, L] along; then the move.
  const Eigen::Vector3d top = tip0 + tool.length_mm * axis;
  Eigen::Vector3d ext;
  for (int i = 0; i < 3; ++i) ext[i] = tool.radius_mm * std::sqrt(std::max(0.0, 1 - axis[i] * axis[i]));
  lo = tip0.cwiseMin(top) - ext;
  hi = tip0.cwiseMax(top) + ext;
  lo = lo.cwiseMin(lo + d);
  hi = hi.cwiseMax(hi + d);
}

namespace {

bool ray_interval_impl(const SweptTool& s, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double w0, double w1,
                       bool reference, double& t0, double& t1) {
  const double ua = u.dot(s.axis);
  // The axial closed form treats the ray as parallel to the axis: only when it is, to within 1e-12 rad (a lateral
  // drift of 1e-10 mm over a 100 mm ray). A test on the cosine, |ua| within 1e-12 of 1, would let rays 1.4e-6 rad off
  // the axis through (0.14 um over 100 mm); the general solvers below handle such nearly parallel rays.
  if ((u - ua * s.axis).squaredNorm() < 1e-24) return ray_interval_axial(s, o, ua > 0 ? 1.0 : -1.0, t0, t1);
  const Tool& tl = s.tool;
  const double rc = tl.corner_radius_mm, rho = tl.disk_radius();
  const double hgt = std::max(0.0, tl.length_mm - 2 * rc);
  const Eigen::Vector3d c = s.tip0 + rc * s.axis;
  Hull h;
  if (rho == 0) {
    // Ball end: within R of the parallelogram swept by the sphere's centre segment.
    const double dl = s.d.norm();
    const Eigen::Vector3d f2 = dl > 0 ? Eigen::Vector3d(s.d / dl) : Eigen::Vector3d::UnitX();
    if (dl > 0 && s.axis.cross(f2).norm() < 1e-12) {
      // Moving along the axis: one segment covering both extents.
      const double lo = std::min(0.0, s.d.dot(s.axis)), hi = std::max(hgt, hgt + s.d.dot(s.axis));
      ray_rounded_parallelogram(o, u, c + lo * s.axis, s.axis, hi - lo, f2, 0.0, tl.radius_mm, h);
    } else {
      ray_rounded_parallelogram(o, u, c, s.axis, hgt, f2, dl, tl.radius_mm, h);
    }
  } else if (rc == 0) {
    ray_swept_disk(o, u, c, s.axis, rho, hgt, s.d, h);
  } else if (!reference) {
    return ray_interval_bull(s, o, u, w0, w1, t0, t1);
  } else {
    // Bull-nose: {t : dist(o + t u, core) <= rc}, a convex function of t, on the stretch where the ray crosses
    // the swept volume's bounding box.
    Eigen::Vector3d lo, hi;
    s.bounds(lo, hi);
    double ta = -kInf, tb = kInf;
    for (int i = 0; i < 3; ++i) {
      if (std::abs(u[i]) < 1e-300) {
        if (o[i] < lo[i] || o[i] > hi[i]) return false;
        continue;
      }
      double a1 = (lo[i] - o[i]) / u[i], a2 = (hi[i] - o[i]) / u[i];
      if (a1 > a2) std::swap(a1, a2);
      ta = std::max(ta, a1);
      tb = std::min(tb, a2);
    }
    if (ta > tb) return false;
    auto f = [&](double t) { return core_distance(s, c, rho, hgt, o + t * u) - rc; };
    double lo_t = ta, hi_t = tb;
    const double gr = 0.5 * (std::sqrt(5.0) - 1);
    double x1 = hi_t - gr * (hi_t - lo_t), x2 = lo_t + gr * (hi_t - lo_t), f1 = f(x1), f2 = f(x2);
    for (int it = 0; it < 100 && hi_t - lo_t > 1e-9; ++it) {
      if (f1 < f2)
        hi_t = x2, x2 = x1, f2 = f1, x1 = hi_t - gr * (hi_t - lo_t), f1 = f(x1);
      else
        lo_t = x1, x1 = x2, f1 = f2, x2 = lo_t + gr * (hi_t - lo_t), f2 = f(x2);
    }
    const double tm = f1 < f2 ? x1 : x2;
    if (std::min(f1, f2) > 0) return false;
    auto root = [&](double inside, double outside) {
      for (int it = 0; it < 80 && std::abs(outside - inside) > 1e-9; ++it) {
        const double mid = 0.5 * (inside + outside);
        (f(mid) <= 0 ? inside : outside) = mid;
      }
      return 0.5 * (inside + outside);
    };
    t0 = f(ta) <= 0 ? ta : root(tm, ta);
    t1 = f(tb) <= 0 ? tb : root(tm, tb);
    return true;
  }
  if (h.empty()) return false;
  t0 = h.lo;
  t1 = h.hi;
  return true;
}

}  // namespace

bool ray_interval(const SweptTool& s, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double& t0, double& t1) {
  return ray_interval_impl(s, o, u, -kInf, kInf, false, t0, t1);
}

bool ray_interval_within(const SweptTool& s, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double w0, double w1,
                         double& t0, double& t1) {
  return ray_interval_impl(s, o, u, w0, w1, false, t0, t1);
}

bool ray_interval_reference(const SweptTool& s, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double& t0,
                            double& t1) {
  return ray_interval_impl(s, o, u, -kInf, kInf, true, t0, t1);
}

double distance(const SweptTool& s, const Eigen::Vector3d& p) {
  const Tool& tl = s.tool;
  const double rc = tl.corner_radius_mm;
  return core_distance(s, s.tip0 + rc * s.axis, tl.disk_radius(), std::max(0.0, tl.length_mm - 2 * rc), p) - rc;
}

}  // namespace vmsim::removal
