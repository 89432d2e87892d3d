#include "metrology/profile.hpp"
#include "core/units.hpp"

#include "core/error.hpp"
#include "metrology/register.hpp"

#include <Eigen/QR>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::metrology {

namespace {

using core::units::kNaN;
using core::units::kPi;

std::size_t valid_count(const Eigen::ArrayXd& z) {
  std::size_t n = 0;
  for (Eigen::Index i = 0; i < z.size(); ++i) n += std::isfinite(z[i]) ? 1 : 0;
  return n;
}

// Legendre polynomials P_0..P_d at u in [-1, 1] (a basis that stays well conditioned at any degree).
void legendre(double u, int d, double* out) {
  out[0] = 1;
  if (d >= 1) out[1] = u;
  for (int k = 2; k <= d; ++k) out[k] = ((2 * k - 1) * u * out[k - 1] - (k - 1) * out[k - 2]) / k;
}

}  // namespace

LineScan line_scan_of_row(const core::HeightGrid& g, Eigen::Index row) {
  if (row < 0 || row >= g.ny()) throw core::Error(fmt::format("line scan: row {} of a grid of {} rows", row, g.ny()));
  LineScan p;
  p.x0_mm = g.x0_mm;
  p.dx_mm = g.dx_mm;
  p.z_mm = g.z_mm.row(row).transpose();
  return p;
}

core::HeightGrid grid_of_line_scan(const LineScan& p) {
  core::HeightGrid g;
  g.x0_mm = p.x0_mm;
  g.dx_mm = g.dy_mm = p.dx_mm;
  g.z_mm = p.z_mm.transpose();
  return g;
}

LineScan crop(const LineScan& p, double a, double b) {
  const double tol = 1e-9 * p.dx_mm;
  Eigen::Index first = -1, last = -1;
  for (Eigen::Index i = 0; i < p.size(); ++i)
    if (p.x(i) >= a - tol && p.x(i) <= b + tol) {
      if (first < 0) first = i;
      last = i;
    }
  if (first < 0 || last - first < 1)
    throw core::Error(fmt::format(
        "profile range {:.6g} .. {:.6g} mm: fewer than 2 points of the profile (x {:.6g} .. {:.6g} mm) lie in it", a, b,
        p.x(0), p.x(p.size() - 1)));
  LineScan out;
  out.x0_mm = p.x(first);
  out.dx_mm = p.dx_mm;
  out.z_mm = p.z_mm.segment(first, last - first + 1);
  return out;
}

LineScan remove_profile_form(const LineScan& p, int degree) {
  if (degree < 0 || degree > 10) throw core::Error(fmt::format("profile form: degree {} (0 .. 10 expected)", degree));
  const std::size_t n = valid_count(p.z_mm);
  if (n < static_cast<std::size_t>(degree + 1))
    throw core::Error(
        fmt::format("profile form: {} valid points cannot determine a polynomial of degree {}", n, degree));
  const double xc = p.x0_mm + 0.5 * static_cast<double>(p.size() - 1) * p.dx_mm;
  const double half = std::max(0.5 * static_cast<double>(p.size() - 1) * p.dx_mm, p.dx_mm);
  Eigen::MatrixXd A(static_cast<Eigen::Index>(n), degree + 1);
  Eigen::VectorXd b(static_cast<Eigen::Index>(n));
  double basis[11];
  Eigen::Index r = 0;
  for (Eigen::Index i = 0; i < p.size(); ++i) {
    if (!std::isfinite(p.z_mm[i])) continue;
    legendre((p.x(i) - xc) / half, degree, basis);
    for (int k = 0; k <= degree; ++k) A(r, k) = basis[k];
    b[r++] = p.z_mm[i];
  }
  const Eigen::VectorXd c = A.colPivHouseholderQr().solve(b);
  LineScan out = p;
  for (Eigen::Index i = 0; i < p.size(); ++i) {
    if (!std::isfinite(p.z_mm[i])) continue;
    legendre((p.x(i) - xc) / half, degree, basis);
    double f = 0;
    for (int k = 0; k <= degree; ++k) f += c[k] * basis[k];
    out.z_mm[i] = p.z_mm[i] - f;
  }
  return out;
}

LineScan gaussian_profile_mean_line(const LineScan& p, double cutoff_mm) {
  if (!(cutoff_mm > 0) || !std::isfinite(cutoff_mm))
    throw core::Error("profile filter: the cut-off must be a positive length");
  const double alpha = std::sqrt(std::log(2.0) / kPi);
  const Eigen::Index half = static_cast<Eigen::Index>(std::ceil(cutoff_mm / p.dx_mm));
  if (half > 50000000)
    throw core::Error(fmt::format("profile filter: cut-off {} mm is {} samples of {} mm", cutoff_mm, half, p.dx_mm));
  Eigen::ArrayXd w(half + 1);
  for (Eigen::Index k = 0; k <= half; ++k) {
    const double t = static_cast<double>(k) * p.dx_mm / (alpha * cutoff_mm);
    w[k] = std::exp(-kPi * t * t);
  }
  LineScan out = p;
  const Eigen::Index n = p.size();
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!std::isfinite(p.z_mm[i])) continue;
    double sw = 0, swz = 0;
    const Eigen::Index lo = std::max<Eigen::Index>(0, i - half), hi = std::min<Eigen::Index>(n - 1, i + half);
    for (Eigen::Index j = lo; j <= hi; ++j) {
      const double z = p.z_mm[j];
      if (!std::isfinite(z)) continue;
      const double wk = w[std::abs(j - i)];
      sw += wk, swz += wk * z;
    }
    out.z_mm[i] = swz / sw;  // sw >= w[0] = 1: the point itself is valid
  }
  return out;
}

LineScan profile_highpass(const LineScan& p, double cutoff_mm) {
  LineScan m = gaussian_profile_mean_line(p, cutoff_mm);
  m.z_mm = p.z_mm - m.z_mm;
  return m;
}

ProfileParameters profile_parameters(const LineScan& p, int sections, double section_length_mm) {
  ProfileParameters r;
  const Eigen::Index n = p.size();
  double sum = 0;
  for (Eigen::Index i = 0; i < n; ++i)
    if (std::isfinite(p.z_mm[i])) sum += p.z_mm[i], ++r.points;
  if (r.points == 0) throw core::Error("profile parameters: the profile has no valid point");
  const double np = static_cast<double>(r.points);
  r.mean_mm = sum / np;
  r.evaluation_length_mm = static_cast<double>(n) * p.dx_mm;
  double s1 = 0, s2 = 0, s3 = 0, s4 = 0, lo = HUGE_VAL, hi = -HUGE_VAL;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!std::isfinite(p.z_mm[i])) continue;
    const double z = p.z_mm[i] - r.mean_mm, z2 = z * z;
    s1 += std::abs(z), s2 += z2, s3 += z2 * z, s4 += z2 * z2;
    lo = std::min(lo, z), hi = std::max(hi, z);
  }
  r.Ra_mm = s1 / np;
  r.Rq_mm = std::sqrt(s2 / np);
  r.Rsk = r.Rq_mm > 0 ? (s3 / np) / (r.Rq_mm * r.Rq_mm * r.Rq_mm) : kNaN;
  r.Rku = r.Rq_mm > 0 ? (s4 / np) / (s2 / np * (s2 / np)) : kNaN;
  r.Rt_mm = hi - lo;
  // Sections: index ranges [b_k, b_{k+1}).
  std::vector<Eigen::Index> bounds;
  if (section_length_mm > 0) {
    const Eigen::Index per =
        std::max<Eigen::Index>(1, static_cast<Eigen::Index>(std::llround(section_length_mm / p.dx_mm)));
    const Eigen::Index count = std::max<Eigen::Index>(1, n / per);
    for (Eigen::Index k = 0; k <= count; ++k) bounds.push_back(std::min(n, k * per));
    r.section_length_mm = static_cast<double>(std::min(per, n)) * p.dx_mm;
  } else {
    const int s = std::max(1, sections);
    for (int k = 0; k <= s; ++k) bounds.push_back(static_cast<Eigen::Index>(static_cast<long long>(n) * k / s));
    r.section_length_mm = r.evaluation_length_mm / s;
  }
  double sp = 0, sv = 0;
  for (std::size_t k = 0; k + 1 < bounds.size(); ++k) {
    double peak = -HUGE_VAL, pit = HUGE_VAL;
    for (Eigen::Index i = bounds[k]; i < bounds[k + 1]; ++i)
      if (std::isfinite(p.z_mm[i]))
        peak = std::max(peak, p.z_mm[i] - r.mean_mm), pit = std::min(pit, p.z_mm[i] - r.mean_mm);
    if (!(peak >= pit)) continue;  // a section without a valid point
    ++r.sections;
    sp += peak, sv += -pit;
    r.Rzx_mm = std::max(r.Rzx_mm, peak - pit);
  }
  r.Rp_mm = sp / r.sections;
  r.Rv_mm = sv / r.sections;
  r.Rz_mm = r.Rp_mm + r.Rv_mm;
  return r;
}

EvaluatedProfile evaluate_profile(const LineScan& p, const ProfileEvaluation& how) {
  EvaluatedProfile e;
  e.profile = remove_profile_form(p, how.level);
  double lc = 0;
  for (const ProfileFilter& f : how.filters) {
    if (f.kind == 'S') {
      e.profile = profile_lowpass(e.profile, f.cutoff_mm);
    } else {
      e.profile = profile_highpass(e.profile, f.cutoff_mm);
      lc = f.cutoff_mm;
    }
  }
  if (lc > 0) {
    const double a = e.profile.x0_mm + lc / 2, b = e.profile.x(e.profile.size() - 1) - lc / 2;
    if (!(b - a >= lc))
      throw core::Error(
          fmt::format("profile: {:.4g} mm long, too short for the L-filter's cut-off {:.4g} mm (it needs at least "
                      "2 cut-offs: one evaluated, half a cut-off run-in and run-out)",
                      e.profile.length_mm(), lc));
    e.profile = crop(e.profile, a, b);
  }
  e.parameters = profile_parameters(e.profile, how.sections, lc);
  return e;
}

LineScan line_across(const core::HeightGrid& g, double x0, double y0, double x1, double y1, double step) {
  const double len = std::hypot(x1 - x0, y1 - y0);
  if (!(len > 0) || !std::isfinite(len)) throw core::Error("profile line: its two ends must be distinct points");
  if (!(step > 0)) throw core::Error("profile line: the sampling step must be positive");
  const double nn = std::floor(len / step + 1e-9) + 1;
  if (nn > 1e8) throw core::Error(fmt::format("profile line: {:.6g} mm at {:.3g} mm is too many samples", len, step));
  const Eigen::Index n = static_cast<Eigen::Index>(nn);
  LineScan p;
  p.x0_mm = 0;
  p.dx_mm = step;
  p.z_mm.resize(n);
  const double ux = (x1 - x0) / len, uy = (y1 - y0) / len;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double s = static_cast<double>(k) * step;
    double z = 0;
    p.z_mm[k] = sample_bilinear(g, x0 + s * ux, y0 + s * uy, z) ? z : kNaN;
  }
  return p;
}

namespace {

// The predicted heights along the line at arbitrary s: linear between the fine samples of `line`.
double at_s(const LineScan& line, double s) {
  const double f = (s - line.x0_mm) / line.dx_mm;
  if (!(f >= 0) || f > static_cast<double>(line.size() - 1)) return kNaN;
  const Eigen::Index i = std::min<Eigen::Index>(static_cast<Eigen::Index>(f), line.size() - 2);
  const double t = f - static_cast<double>(i);
  return (1 - t) * line.z_mm[i] + t * line.z_mm[i + 1];  // NaN when either end is
}

struct Fit {
  std::size_t n = 0;
  double ms = HUGE_VAL, a = 0, b = 0, c = 0;
};

// Least-squares offset and tilt of (measured - predicted) at the shift, and the mean square residual.
Fit fit_at(const LineScan& m, const LineScan& line, double shift, bool align, Eigen::Index stride) {
  double S = 0, Sd = 0, Ss = 0, Sss = 0, Ssd = 0;
  std::size_t n = 0;
  for (Eigen::Index i = 0; i < m.size(); i += stride) {
    if (!std::isfinite(m.z_mm[i])) continue;
    const double s = static_cast<double>(i) * m.dx_mm + shift;
    const double zp = at_s(line, s);
    if (!std::isfinite(zp)) continue;
    const double d = m.z_mm[i] - zp;
    ++n, S += 1, Sd += d, Ss += s, Sss += s * s, Ssd += s * d;
  }
  Fit f;
  f.n = n;
  if (n < 3) return f;
  f.c = Ss / S;
  const double var = Sss / S - f.c * f.c;
  if (align) {
    f.a = Sd / S;
    f.b = var > 0 ? (Ssd / S - f.c * f.a) / var : 0.0;
  }
  double e2 = 0;
  for (Eigen::Index i = 0; i < m.size(); i += stride) {
    if (!std::isfinite(m.z_mm[i])) continue;
    const double s = static_cast<double>(i) * m.dx_mm + shift;
    const double zp = at_s(line, s);
    if (!std::isfinite(zp)) continue;
    const double r = m.z_mm[i] - zp - f.a - f.b * (s - f.c);
    e2 += r * r;
  }
  f.ms = e2 / static_cast<double>(n);
  return f;
}

}  // namespace

ProfileComparison compare_profile(const LineScan& measured, const core::HeightGrid& predicted, double x0, double y0,
                                  double x1, double y1, const ProfileAlignmentOptions& o) {
  if (measured.size() < 3 || valid_count(measured.z_mm) < 3)
    throw core::Error("profile comparison: the measured profile has fewer than 3 valid points");
  const double step = std::min(predicted.dx_mm, predicted.dy_mm) / 2;
  const LineScan line = line_across(predicted, x0, y0, x1, y1, step);
  ProfileComparison c;
  c.line_length_mm = std::hypot(x1 - x0, y1 - y0);
  if (valid_count(line.z_mm) < 2)
    throw core::Error(
        fmt::format("profile comparison: the line ({:.6g}, {:.6g}) - ({:.6g}, {:.6g}) mm does not cross the predicted "
                    "surface (x {:.6g} .. {:.6g}, y {:.6g} .. {:.6g} mm)",
                    x0, y0, x1, y1, predicted.x(0), predicted.x(predicted.nx() - 1), predicted.y(0),
                    predicted.y(predicted.ny() - 1)));
  const double lm = static_cast<double>(measured.size() - 1) * measured.dx_mm;
  Fit best;
  double shift = o.shift_mm;
  if (o.align) {
    // Shifts where at least half of the measured profile lies on the line, every predicted sample; the measured
    // points thinned so that the coarse search stays near 5e7 evaluations.
    const double lo = -0.5 * lm, hi = c.line_length_mm - 0.5 * lm;
    const Eigen::Index shifts = static_cast<Eigen::Index>(std::floor((hi - lo) / step)) + 1;
    const Eigen::Index stride = std::max<Eigen::Index>(
        1, static_cast<Eigen::Index>(static_cast<double>(shifts) * static_cast<double>(measured.size()) / 5e7));
    const std::size_t need = valid_count(measured.z_mm) / static_cast<std::size_t>(2 * stride);
    std::vector<Fit> fits(static_cast<std::size_t>(shifts));
#pragma omp parallel for schedule(dynamic, 16)
    for (Eigen::Index k = 0; k < shifts; ++k)
      fits[static_cast<std::size_t>(k)] = fit_at(measured, line, lo + static_cast<double>(k) * step, true, stride);
    Eigen::Index kb = -1;
    for (Eigen::Index k = 0; k < shifts; ++k) {
      const Fit& f = fits[static_cast<std::size_t>(k)];
      if (f.n >= need && f.n >= 3 && (kb < 0 || f.ms < fits[static_cast<std::size_t>(kb)].ms)) kb = k;
    }
    if (kb < 0)
      throw core::Error(
          "profile comparison: the measured profile overlaps the valid part of the line nowhere by half its length");
    // Golden-section refinement within one step either side, on all points.
    double a = lo + static_cast<double>(kb - 1) * step, b = lo + static_cast<double>(kb + 1) * step;
    const double g = (std::sqrt(5.0) - 1) / 2;
    double u = b - g * (b - a), v = a + g * (b - a);
    Fit fu = fit_at(measured, line, u, true, 1), fv = fit_at(measured, line, v, true, 1);
    while (b - a > step / 100) {
      if (fu.ms < fv.ms)
        b = v, v = u, fv = fu, u = b - g * (b - a), fu = fit_at(measured, line, u, true, 1);
      else
        a = u, u = v, fu = fv, v = a + g * (b - a), fv = fit_at(measured, line, v, true, 1);
    }
    shift = fu.ms < fv.ms ? u : v;
  }
  best = fit_at(measured, line, shift, o.align, 1);
  if (best.n < 3)
    throw core::Error("profile comparison: fewer than 3 measured points lie on the valid part of the line");
  c.shift_mm = shift, c.offset_mm = best.a, c.tilt = best.b, c.s_centre_mm = best.c;
  c.measured.x0_mm = c.predicted.x0_mm = c.deviation.x0_mm = shift;
  c.measured.dx_mm = c.predicted.dx_mm = c.deviation.dx_mm = measured.dx_mm;
  const Eigen::Index n = measured.size();
  c.measured.z_mm.resize(n), c.predicted.z_mm.resize(n), c.deviation.z_mm.resize(n);
  double sum = 0, s2 = 0, mn = HUGE_VAL, mx = -HUGE_VAL;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double s = shift + static_cast<double>(i) * measured.dx_mm;
    const double zm = measured.z_mm[i] - best.a - best.b * (s - best.c);
    const double zp = at_s(line, s);
    c.measured.z_mm[i] = zm;
    c.predicted.z_mm[i] = zp;
    const double d = zm - zp;
    c.deviation.z_mm[i] = std::isfinite(d) ? d : kNaN;
    if (!std::isfinite(d)) continue;
    ++c.points, sum += d, s2 += d * d, mn = std::min(mn, d), mx = std::max(mx, d);
  }
  c.mean_mm = sum / static_cast<double>(c.points);
  c.rms_mm = std::sqrt(s2 / static_cast<double>(c.points));
  c.min_mm = mn, c.max_mm = mx;
  return c;
}

}  // namespace vmsim::metrology
