#include "motion/nurbs.hpp"
#include "motion/quintic_hermite.hpp"

#include "core/csv.hpp"
#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace vmsim::motion {

namespace {

// 5-point Gauss-Legendre on [-1, 1].
constexpr std::array<double, 5> kGauss5X = {0.0, 0.5384693101056831, -0.5384693101056831, 0.9061798459386640,
                                        -0.9061798459386640};
constexpr std::array<double, 5> kGauss5W = {0.5688888888888889, 0.4786286704993665, 0.4786286704993665, 0.2369268850561891,
                                        0.2369268850561891};
constexpr int kTablePerSpan = 64;
constexpr int kMaxDegree = 9;

// Knot span index: knots[i] <= u < knots[i+1] with degree <= i <= n - 1 (the last span for u = u_max). NURBS Book A2.1.
int find_span(const NurbsCurve& c, double u) {
  const int n = static_cast<int>(c.points.size());
  const int p = c.degree;
  if (u >= c.knots[static_cast<std::size_t>(n)]) {
    int i = n - 1;
    while (i > p && c.knots[static_cast<std::size_t>(i)] >= c.knots[static_cast<std::size_t>(n)]) --i;
    return i;
  }
  if (u <= c.knots[static_cast<std::size_t>(p)]) {
    int i = p;
    while (i + 1 < n && c.knots[static_cast<std::size_t>(i + 1)] <= u) ++i;
    return i;
  }
  const auto it = std::upper_bound(c.knots.begin() + p, c.knots.begin() + n + 1, u);
  return static_cast<int>(it - c.knots.begin()) - 1;
}

// Basis functions and their derivatives up to order nd at u in span i: ders[k][j] = N^(k)_{i-p+j}. NURBS Book A2.3.
void basis_derivs(const NurbsCurve& c, int i, double u, int nd, double ders[4][kMaxDegree + 1]) {
  const int p = c.degree;
  const auto& U = c.knots;
  double ndu[kMaxDegree + 1][kMaxDegree + 1];
  double left[kMaxDegree + 1], right[kMaxDegree + 1];
  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[static_cast<std::size_t>(i + 1 - j)];
    right[j] = U[static_cast<std::size_t>(i + j)] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
  double a[2][kMaxDegree + 1];
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= nd; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k][r] = d;
      std::swap(s1, s2);
    }
  }
  double f = p;
  for (int k = 1; k <= nd; ++k) {
    for (int j = 0; j <= p; ++j) ders[k][j] *= f;
    f *= (p - k);
  }
}

core::Vec6 vec6(const Eigen::Vector3d& v) {
  core::Vec6 r = core::Vec6::Zero();
  r.head<3>() = v;
  return r;
}

// A curve file (core/csv): a header, then rows of numbers only (every cell, used or not), at least one.
struct CsvTable {
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;
  std::vector<int> lines;
  int column(const std::string& name) const {
    for (std::size_t i = 0; i < columns.size(); ++i)
      if (columns[i] == name) return static_cast<int>(i);
    return -1;
  }
};

CsvTable read_csv(const std::filesystem::path& file) {
  core::CsvReader in(file);
  if (!in.has_header()) throw core::Error(file.string() + ": no header line (expected column names)");
  CsvTable t;
  t.columns = in.columns();
  while (in.next()) {
    std::vector<double> row;
    for (std::size_t i = 0; i < in.cells(); ++i) row.push_back(in.number(i));
    t.rows.push_back(std::move(row));
    t.lines.push_back(in.line());
  }
  if (t.rows.empty()) throw core::Error(file.string() + ": no data rows");
  return t;
}

}  // namespace

void check_nurbs(const NurbsCurve& c) {
  const std::string& src = c.source.empty() ? std::string("NURBS curve") : c.source;
  if (c.degree < 1 || c.degree > kMaxDegree)
    throw core::Error(fmt::format("{}: degree {} (expected 1..{})", src, c.degree, kMaxDegree));
  const std::size_t n = c.points.size(), p = static_cast<std::size_t>(c.degree);
  if (n < p + 1)
    throw core::Error(fmt::format("{}: {} control points, a degree-{} curve needs at least {}", src, n, p, p + 1));
  if (c.weights.size() != n)
    throw core::Error(fmt::format("{}: {} weights for {} control points", src, c.weights.size(), n));
  if (c.knots.size() != n + p + 1)
    throw core::Error(fmt::format("{}: {} knots; {} control points of degree {} need {} (points + degree + 1)", src,
                                  c.knots.size(), n, p, n + p + 1));
  for (std::size_t i = 0; i < n; ++i) {
    if (!(c.weights[i] > 0) || !std::isfinite(c.weights[i]))
      throw core::Error(fmt::format("{}: weight {} of control point {} (expected > 0)", src, c.weights[i], i));
    if (!c.points[i].allFinite()) throw core::Error(fmt::format("{}: control point {} is not finite", src, i));
  }
  for (std::size_t i = 0; i + 1 < c.knots.size(); ++i)
    if (!(c.knots[i + 1] >= c.knots[i]))
      throw core::Error(fmt::format("{}: knot {} ({}) is below knot {} ({}): knots must not decrease", src, i + 1,
                                    c.knots[i + 1], i, c.knots[i]));
  if (!(c.u_max() > c.u_min())) throw core::Error(fmt::format("{}: the knots leave an empty parameter range", src));
  // Inside the range, a knot of multiplicity > degree would cut the curve (and > degree - 2 only lowers its
  // continuity, which the G2 path checks where it matters).
  for (std::size_t i = p + 1; i + p + 1 < c.knots.size(); ++i) {
    std::size_t m = 1;
    while (i + m < n && c.knots[i + m] == c.knots[i]) ++m;
    if (m > p && c.knots[i] > c.u_min() && c.knots[i] < c.u_max())
      throw core::Error(
          fmt::format("{}: knot {} has multiplicity {} > degree {}: the curve is cut there", src, c.knots[i], m, p));
  }
}

NurbsCurve read_nurbs_csv(const std::filesystem::path& cp_file, const std::filesystem::path& knot_file, int degree) {
  NurbsCurve c;
  c.degree = degree;
  c.source = cp_file.string();
  const CsvTable cp = read_csv(cp_file);
  const int ix = cp.column("x"), iy = cp.column("y"), iz = cp.column("z"), iw = cp.column("weight");
  if (ix < 0 || iy < 0)
    throw core::Error(cp_file.string() + ": the header must name columns x and y (and optionally z, weight)");
  for (std::size_t r = 0; r < cp.rows.size(); ++r) {
    const auto& row = cp.rows[r];
    c.points.emplace_back(row[static_cast<std::size_t>(ix)], row[static_cast<std::size_t>(iy)],
                          iz >= 0 ? row[static_cast<std::size_t>(iz)] : 0.0);
    const double w = iw >= 0 ? row[static_cast<std::size_t>(iw)] : 1.0;
    if (!(w > 0))
      throw core::Error(core::located(cp_file.string(), cp.lines[r], fmt::format("weight {} (expected > 0)", w)));
    c.weights.push_back(w);
  }
  const CsvTable kt = read_csv(knot_file);
  const int ik = kt.column("knot");
  if (ik < 0) throw core::Error(knot_file.string() + ": the header must name a column knot");
  for (std::size_t r = 0; r < kt.rows.size(); ++r) {
    const double k = kt.rows[r][static_cast<std::size_t>(ik)];
    if (!c.knots.empty() && k < c.knots.back())
      throw core::Error(core::located(knot_file.string(), kt.lines[r],
                                      fmt::format("knot {} is below the one before ({})", k, c.knots.back())));
    c.knots.push_back(k);
  }
  c.source = cp_file.string() + " + " + knot_file.string();
  check_nurbs(c);
  return c;
}

NurbsDerivs nurbs_derivs(const NurbsCurve& c, double u) {
  u = std::clamp(u, c.u_min(), c.u_max());
  const int p = c.degree;
  const int span = find_span(c, u);
  const int nd = std::min(3, p);
  double ders[4][kMaxDegree + 1] = {};
  basis_derivs(c, span, u, nd, ders);
  // Homogeneous derivatives A^(k) = sum N^(k) w P and W^(k) = sum N^(k) w.
  Eigen::Vector3d A[4];
  double W[4];
  for (int k = 0; k < 4; ++k) A[k].setZero(), W[k] = 0.0;
  for (int k = 0; k <= nd; ++k)
    for (int j = 0; j <= p; ++j) {
      const std::size_t idx = static_cast<std::size_t>(span - p + j);
      const double nw = ders[k][j] * c.weights[idx];
      A[k] += nw * c.points[idx];
      W[k] += nw;
    }
  // NURBS Book A4.2: C^(k) = (A^(k) - sum_{i=1..k} binom(k, i) W^(i) C^(k-i)) / W.
  Eigen::Vector3d C[4];
  static const int binom[4][4] = {{1, 0, 0, 0}, {1, 1, 0, 0}, {1, 2, 1, 0}, {1, 3, 3, 1}};
  for (int k = 0; k < 4; ++k) {
    Eigen::Vector3d v = A[k];
    for (int i = 1; i <= k; ++i) v -= binom[k][i] * W[i] * C[k - i];
    C[k] = v / W[0];
  }
  return {C[0], C[1], C[2], C[3]};
}

ArcJet arc_jet(const NurbsDerivs& d) {
  const double sig = d.d1.norm();
  if (!(sig > 0)) throw core::Error("NURBS curve is not regular (dP/du = 0): it has no tangent there");
  const double sig_u = d.d1.dot(d.d2) / sig;
  const double sig_uu = (d.d2.squaredNorm() + d.d1.dot(d.d3)) / sig - sig_u * sig_u / sig;
  const double s2 = sig * sig, s3 = s2 * sig, s4 = s3 * sig;
  ArcJet j;
  j.p = d.p;
  j.t = d.d1 / sig;
  j.k = d.d2 / s2 - d.d1 * (sig_u / s3);
  j.dk = (d.d3 / s2 - 3 * d.d2 * (sig_u / s3) - d.d1 * (sig_uu / s3) + 3 * d.d1 * (sig_u * sig_u / s4)) / sig;
  return j;
}

NurbsArcLength::NurbsArcLength(const NurbsCurve& curve) : curve_(&curve) {
  check_nurbs(curve);
  const int p = curve.degree;
  const std::size_t n = curve.points.size();
  u_.push_back(curve.u_min());
  cum_.push_back(0.0);
  for (std::size_t i = static_cast<std::size_t>(p); i < n; ++i) {
    const double a = curve.knots[i], b = curve.knots[i + 1];
    if (!(b > a)) continue;
    for (int k = 1; k <= kTablePerSpan; ++k) {
      const double ub = k == kTablePerSpan ? b : a + (b - a) * k / kTablePerSpan;
      cum_.push_back(cum_.back() + integrate(u_.back(), ub));
      u_.push_back(ub);
    }
  }
}

double NurbsArcLength::integrate(double u0, double u1) const {
  const double half = 0.5 * (u1 - u0), mid = 0.5 * (u0 + u1);
  double sum = 0.0;
  for (std::size_t i = 0; i < kGauss5X.size(); ++i) sum += kGauss5W[i] * nurbs_derivs(*curve_, mid + half * kGauss5X[i]).d1.norm();
  return sum * half;
}

double NurbsArcLength::s_at(double u) const {
  if (u <= u_.front()) return 0.0;
  if (u >= u_.back()) return cum_.back();
  const std::size_t k = static_cast<std::size_t>(std::upper_bound(u_.begin(), u_.end(), u) - u_.begin()) - 1;
  return cum_[k] + integrate(u_[k], u);
}

double NurbsArcLength::u_at(double s) const {
  if (s <= 0) return u_.front();
  if (s >= cum_.back()) return u_.back();
  std::size_t k = static_cast<std::size_t>(std::upper_bound(cum_.begin(), cum_.end(), s) - cum_.begin()) - 1;
  k = std::min(k, u_.size() - 2);
  const double ua = u_[k], ub = u_[k + 1];
  double lo = ua, hi = ub;
  double u = ua + (ub - ua) * (s - cum_[k]) / std::max(cum_[k + 1] - cum_[k], 1e-300);
  for (int it = 0; it < 30; ++it) {
    const double f = cum_[k] + integrate(ua, u) - s;
    if (f > 0)
      hi = u;
    else
      lo = u;
    const double sp = nurbs_derivs(*curve_, u).d1.norm();
    double un = sp > 0 ? u - f / sp : 0.5 * (lo + hi);
    if (!(un > lo && un < hi)) un = 0.5 * (lo + hi);  // Newton left the bracket: bisect
    if (std::abs(un - u) <= 1e-15 * std::max(1.0, std::abs(u))) return un;
    u = un;
  }
  return u;
}

double NurbsPath::path_s(double curve_s) const {
  if (path.pieces.empty()) return 0.0;
  if (curve_s <= joint_s.front()) return 0.0;
  if (curve_s >= joint_s.back()) return path.length;
  const std::size_t j =
      static_cast<std::size_t>(std::upper_bound(joint_s.begin(), joint_s.end(), curve_s) - joint_s.begin()) - 1;
  const PathPiece& pc = path.pieces[std::min(j, path.pieces.size() - 1)];
  const double w = (curve_s - joint_s[j]) / std::max(joint_s[j + 1] - joint_s[j], 1e-300);
  return pc.s_begin + w * pc.length;
}

double NurbsPath::curve_s(double s) const {
  if (path.pieces.empty() || s <= 0) return 0.0;
  if (s >= path.length) return joint_s.back();
  const std::size_t j = path.piece_at(s);
  const PathPiece& pc = path.pieces[j];
  const double w = pc.length > 0 ? (s - pc.s_begin) / pc.length : 0.0;
  return joint_s[j] + std::clamp(w, 0.0, 1.0) * (joint_s[j + 1] - joint_s[j]);
}

NurbsPath nurbs_to_path(const NurbsCurve& curve, const NurbsPathOptions& options) {
  check_nurbs(curve);
  if (!(options.tolerance_mm > 0) || !(options.max_piece_mm > 0) || !(options.feed_mm_per_min > 0))
    throw core::Error("NURBS path: the tolerance, the longest piece and the feed must be > 0");
  const NurbsArcLength arc(curve);
  NurbsPath out;

  struct Candidate {
    double u0, u1;
    Eigen::Matrix<double, 6, 6> coef;
    double deviation;
  };
  auto build = [&](double u0, double u1) {
    const double h = u1 - u0;
    const NurbsDerivs a = nurbs_derivs(curve, u0), b = nurbs_derivs(curve, u1);
    Candidate c{
        u0, u1,
        quintic_hermite(vec6(a.p), vec6(h * a.d1), vec6(h * h * a.d2), vec6(b.p), vec6(h * b.d1), vec6(h * h * b.d2)),
        0.0};
    // Parametric distance at 32 interior points: an upper bound on the geometric one.
    for (int i = 0; i < 32; ++i) {
      const double t = (i + 0.5) / 32;
      core::Vec6 q = c.coef.col(5);
      for (int k = 4; k >= 0; --k) q = q * t + c.coef.col(k);
      c.deviation = std::max(c.deviation, (q.head<3>() - nurbs_derivs(curve, u0 + t * h).p).norm());
    }
    return c;
  };

  // Distinct knots inside the range: each span is split into equal parameter steps no longer than max_piece_mm, then
  // halved until within the tolerance.
  std::vector<double> breaks;
  for (double k : curve.knots)
    if (k >= curve.u_min() && k <= curve.u_max() && (breaks.empty() || k > breaks.back())) breaks.push_back(k);
  std::vector<Candidate> pieces;
  for (std::size_t b = 0; b + 1 < breaks.size(); ++b) {
    const double ua = breaks[b], ub = breaks[b + 1];
    const double len = arc.s_at(ub) - arc.s_at(ua);
    const int m = std::max(1, static_cast<int>(std::ceil(len / options.max_piece_mm)));
    for (int i = 0; i < m; ++i) {
      // Depth-first halving keeps the pieces in order.
      std::vector<std::pair<double, double>> stack{
          {ua + (ub - ua) * i / m, i + 1 == m ? ub : ua + (ub - ua) * (i + 1) / m}};
      while (!stack.empty()) {
        const auto [u0, u1] = stack.back();
        stack.pop_back();
        Candidate c = build(u0, u1);
        if (c.deviation > options.tolerance_mm) {
          if (u1 - u0 < 1e-12 * std::max(1.0, std::abs(u1)))
            throw core::Error(
                fmt::format("{}: the curve cannot be followed within {} mm near u = {} (is it regular there?)",
                            curve.source, options.tolerance_mm, u0));
          const double um = 0.5 * (u0 + u1);
          stack.push_back({um, u1});
          stack.push_back({u0, um});
          continue;
        }
        pieces.push_back(std::move(c));
      }
    }
  }

  SmoothPath& sp = out.path;
  core::ToolPath& tp = out.program;
  tp.source_path = curve.source;
  const Eigen::Vector3d p0 = nurbs_derivs(curve, curve.u_min()).p;
  tp.initial_position = vec6(p0);
  sp.start = to_path_space(tp.initial_position);
  double s = 0.0;
  out.joint_u.push_back(curve.u_min());
  out.joint_s.push_back(0.0);
  core::Vec6 at = tp.initial_position;
  for (std::size_t i = 0; i < pieces.size(); ++i) {
    const Candidate& c = pieces[i];
    PathPiece pc;
    pc.set_quintic(c.coef);
    pc.u_begin = 0.0;
    pc.u_end = 1.0;
    pc.uniform = false;
    pc.move_index = pc.move_index_next = static_cast<int>(i);
    pc.feed_metric = PathPiece::FeedMetric::Xyz;
    pc.feed_limit = options.feed_mm_per_min / 60.0;
    constexpr int kRegular = 64;
    double min_speed = 1e300, max_speed = 0.0;
    for (int k = 0; k <= kRegular; ++k) {
      const double v = pc.speed_u(double(k) / kRegular);
      min_speed = std::min(min_speed, v);
      max_speed = std::max(max_speed, v);
    }
    if (!(min_speed > 1e-6 * max_speed))
      throw core::Error(fmt::format("{}: the curve is not regular near u = {} (no tangent): it cannot be followed",
                                    curve.source, c.u0));
    pc.finalize();
    pc.s_begin = s;
    s += pc.length;
    sp.pieces.push_back(std::move(pc));
    out.max_deviation_mm = std::max(out.max_deviation_mm, c.deviation);

    core::Move m;
    m.kind = core::MotionKind::Line;
    m.start = at;
    // The piece's own end point (the next piece starts at the curve's point there, within round-off).
    m.end = core::Vec6::Zero();
    m.end.head<3>() = c.coef.col(0).head<3>() + c.coef.col(1).head<3>() + c.coef.col(2).head<3>() +
                      c.coef.col(3).head<3>() + c.coef.col(4).head<3>() + c.coef.col(5).head<3>();
    m.feed_mm_per_min = options.feed_mm_per_min;
    tp.moves.push_back(m);
    at = m.end;
    out.joint_u.push_back(c.u1);
    out.joint_s.push_back(arc.s_at(c.u1));
  }
  sp.length = s;
  sp.end = to_path_space(at);
  return out;
}

}  // namespace vmsim::motion
