#include "metrology/areal.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace vmsim::metrology {

ArealParameters areal_parameters(const core::HeightGrid& g) {
  const Eigen::Index nx = g.nx(), ny = g.ny();
  // Row partial sums, then a sum in row order: the result does not depend on the thread count.
  std::vector<double> s0(static_cast<std::size_t>(ny), 0.0), s1(static_cast<std::size_t>(ny), 0.0);
  std::vector<std::size_t> cnt(static_cast<std::size_t>(ny), 0);
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < ny; ++j) {
    double s = 0;
    std::size_t c = 0;
    for (Eigen::Index i = 0; i < nx; ++i)
      if (g.valid(j, i)) s += g.z_mm(j, i), ++c;
    s0[static_cast<std::size_t>(j)] = s;
    cnt[static_cast<std::size_t>(j)] = c;
  }
  ArealParameters p;
  double sum = 0;
  for (Eigen::Index j = 0; j < ny; ++j)
    sum += s0[static_cast<std::size_t>(j)], p.points += cnt[static_cast<std::size_t>(j)];
  if (p.points == 0) throw core::Error("areal parameters: the surface has no valid point");
  p.mean_mm = sum / static_cast<double>(p.points);
  const double m = p.mean_mm;

  struct Row {
    double a = 0, q2 = 0, q3 = 0, q4 = 0, lo = HUGE_VAL, hi = -HUGE_VAL, g2 = 0, dr = 0;
    std::size_t gn = 0;
  };
  std::vector<Row> rows(static_cast<std::size_t>(ny));
  const auto slope = [&](double zm, double z0, double zp, bool vm, bool vp, double h, bool& ok) {
    ok = true;
    if (vm && vp) return (zp - zm) / (2 * h);
    if (vp) return (zp - z0) / h;
    if (vm) return (z0 - zm) / h;
    ok = false;
    return 0.0;
  };
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < ny; ++j) {
    Row r;
    for (Eigen::Index i = 0; i < nx; ++i) {
      if (!g.valid(j, i)) continue;
      const double z0 = g.z_mm(j, i), z = z0 - m, z2 = z * z;
      r.a += std::abs(z), r.q2 += z2, r.q3 += z2 * z, r.q4 += z2 * z2;
      r.lo = std::min(r.lo, z), r.hi = std::max(r.hi, z);
      const bool xm = i > 0 && g.valid(j, i - 1), xp = i + 1 < nx && g.valid(j, i + 1);
      const bool ym = j > 0 && g.valid(j - 1, i), yp = j + 1 < ny && g.valid(j + 1, i);
      bool okx, oky;
      const double zx = slope(xm ? g.z_mm(j, i - 1) : 0, z0, xp ? g.z_mm(j, i + 1) : 0, xm, xp, g.dx_mm, okx);
      const double zy = slope(ym ? g.z_mm(j - 1, i) : 0, z0, yp ? g.z_mm(j + 1, i) : 0, ym, yp, g.dy_mm, oky);
      if (!okx || !oky) continue;
      const double s2 = zx * zx + zy * zy;
      r.g2 += s2;
      // sqrt(1 + s2) - 1 written so that small slopes lose no digits.
      r.dr += s2 / (std::sqrt(1.0 + s2) + 1.0);
      ++r.gn;
    }
    rows[static_cast<std::size_t>(j)] = r;
  }
  Row t;
  for (const Row& r : rows) {
    t.a += r.a, t.q2 += r.q2, t.q3 += r.q3, t.q4 += r.q4, t.g2 += r.g2, t.dr += r.dr, t.gn += r.gn;
    t.lo = std::min(t.lo, r.lo), t.hi = std::max(t.hi, r.hi);
  }
  const double n = static_cast<double>(p.points);
  p.Sa_mm = t.a / n;
  p.Sq_mm = std::sqrt(t.q2 / n);
  p.Sp_mm = t.hi;
  p.Sv_mm = -t.lo;
  p.Sz_mm = p.Sp_mm + p.Sv_mm;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  p.Ssk = p.Sq_mm > 0 ? (t.q3 / n) / (p.Sq_mm * p.Sq_mm * p.Sq_mm) : nan;
  p.Sku = p.Sq_mm > 0 ? (t.q4 / n) / (p.Sq_mm * p.Sq_mm * p.Sq_mm * p.Sq_mm) : nan;
  p.gradient_points = t.gn;
  p.Sdq = t.gn ? std::sqrt(t.g2 / static_cast<double>(t.gn)) : nan;
  p.Sdr_percent = t.gn ? 100.0 * t.dr / static_cast<double>(t.gn) : nan;
  return p;
}

}  // namespace vmsim::metrology
