#include "motion/smooth_path.hpp"
#include "motion/quintic_hermite.hpp"

#include "core/arc.hpp"
#include "core/error.hpp"
#include "core/huge_pages.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace vmsim::motion {

namespace {

using core::units::kInf;
using core::units::kTwoPi;

// 4-point Gauss-Legendre on [-1, 1], exact for polynomials of degree 7. |p_u| of a quintic is smooth, and the
// rule is applied on at most 1/64 of the parameter range, where it integrates the speed to round-off.
constexpr std::array<double, 2> kGauss4X = {0.3399810435848563, 0.8611363115940526};
constexpr std::array<double, 2> kGauss4W = {0.6521451548625461, 0.3478548451374538};

// The speeds |p_u| of a quintic piece at N parameters side by side: per point the same Eigen operations as speed_u
// (Horner on the derivative's coefficients, then norm()), so bit for bit its values, with the N Horner chains and
// square roots overlapping instead of each call waiting on the last (issue 21: speed_u, ~11 calls per setpoint on
// blends, was the interpolator's largest cost).
template <int N>
inline void quintic_speeds(const PathPiece& pc, const double (&u)[N], double (&out)[N]) {
  core::Vec6 d[N];
  for (int i = 0; i < N; ++i) d[i] = pc.dcoef.col(4);
  for (int k = 4; k >= 1; --k)
    for (int i = 0; i < N; ++i) d[i] = d[i] * u[i] + pc.dcoef.col(k - 1);
  for (int i = 0; i < N; ++i) out[i] = d[i].norm();
}

// The arc length of [u0, u1] by the 4-point rule; with speed_at_u1, also the speed at u1 (Newton's derivative),
// computed beside the rule's four on quintics.
double integrate_speed(const PathPiece& piece, double u0, double u1, double* speed_at_u1 = nullptr) {
  const double half = 0.5 * (u1 - u0), mid = 0.5 * (u0 + u1);
  double sum = 0.0;
  if (piece.kind == PathPiece::Kind::Quintic) {
    const double a = mid - half * kGauss4X[0], b = mid + half * kGauss4X[0], c = mid - half * kGauss4X[1],
                 d = mid + half * kGauss4X[1];
    double v[5];
    if (speed_at_u1) {
      const double u[5] = {a, b, c, d, u1};
      quintic_speeds(piece, u, v);
      *speed_at_u1 = v[4];
    } else {  // the rule alone (the arc-length tables, s_at): four speeds, not five
      const double u[4] = {a, b, c, d};
      double w[4];
      quintic_speeds(piece, u, w);
      for (int i = 0; i < 4; ++i) v[i] = w[i];
    }
    sum += kGauss4W[0] * (v[0] + v[1]);
    sum += kGauss4W[1] * (v[2] + v[3]);
    return sum * half;
  }
  for (int i = 0; i < 2; ++i) {
    sum += kGauss4W[i] * (piece.speed_u(mid - half * kGauss4X[i]) + piece.speed_u(mid + half * kGauss4X[i]));
  }
  if (speed_at_u1) *speed_at_u1 = piece.speed_u(u1);
  return sum * half;
}

}  // namespace

core::Vec6 to_path_space(const core::Vec6& program) {
  core::Vec6 p = program;
  p.tail<3>() *= core::units::kRadToDeg;
  return p;
}

core::Vec6 from_path_space(const core::Vec6& path) {
  core::Vec6 p = path;
  p.tail<3>() *= core::units::kDegToRad;
  return p;
}

CurveJet PathPiece::jet_u(double u) const {
  CurveJet j;
  switch (kind) {
    case Kind::Line:
      j.p = a + u * b;
      j.pu = b;
      j.puu.setZero();
      j.puuu.setZero();
      break;
    case Kind::Arc: {
      j.p = a + u * b;
      j.pu = b;
      j.puu.setZero();
      j.puuu.setZero();
      const double th = theta0 + u * dtheta, r = r0 + u * dr;
      const double c = std::cos(th), s = std::sin(th), w = dtheta;
      j.p[arc_i1] = c1 + r * c;
      j.p[arc_i2] = c2 + r * s;
      j.pu[arc_i1] = dr * c - r * s * w;
      j.pu[arc_i2] = dr * s + r * c * w;
      j.puu[arc_i1] = -2 * dr * w * s - r * w * w * c;
      j.puu[arc_i2] = 2 * dr * w * c - r * w * w * s;
      j.puuu[arc_i1] = -3 * dr * w * w * c + r * w * w * w * s;
      j.puuu[arc_i2] = -3 * dr * w * w * s - r * w * w * w * c;
      break;
    }
    case Kind::Quintic: {
      // Horner for the value and the three derivatives.
      j.p = coef.col(5);
      j.pu = 5 * coef.col(5);
      j.puu = 20 * coef.col(5);
      j.puuu = 60 * coef.col(5);
      for (int k = 4; k >= 0; --k) j.p = j.p * u + coef.col(k);
      for (int k = 4; k >= 1; --k) j.pu = j.pu * u + k * coef.col(k);
      for (int k = 4; k >= 2; --k) j.puu = j.puu * u + k * (k - 1) * coef.col(k);
      for (int k = 4; k >= 3; --k) j.puuu = j.puuu * u + k * (k - 1) * (k - 2) * coef.col(k);
      break;
    }
  }
  return j;
}

void PathPiece::set_quintic(const Eigen::Matrix<double, 6, 6>& c) {
  kind = Kind::Quintic;
  coef = c;
  for (int k = 1; k <= 5; ++k) dcoef.col(k - 1) = k * coef.col(k);
}

double PathPiece::speed_u(double u) const {
  switch (kind) {
    case Kind::Line:
      return b.norm();
    case Kind::Arc: {
      core::Vec6 d = b;
      const double th = theta0 + u * dtheta, r = r0 + u * dr;
      const double c = std::cos(th), s = std::sin(th);
      d[arc_i1] = dr * c - r * s * dtheta;
      d[arc_i2] = dr * s + r * c * dtheta;
      return d.norm();
    }
    case Kind::Quintic: {
      core::Vec6 d = dcoef.col(4);
      for (int k = 4; k >= 1; --k) d = d * u + dcoef.col(k - 1);
      return d.norm();
    }
  }
  return 0.0;
}

core::Vec6 PathPiece::point_u(double u) const {
  if (kind == Kind::Line) return a + u * b;
  if (kind == Kind::Arc) {
    core::Vec6 p = a + u * b;
    const double th = theta0 + u * dtheta, r = r0 + u * dr;
    p[arc_i1] = c1 + r * std::cos(th);
    p[arc_i2] = c2 + r * std::sin(th);
    return p;
  }
  core::Vec6 p = coef.col(5);
  for (int k = 4; k >= 0; --k) p = p * u + coef.col(k);
  return p;
}

void PathPiece::finalize() {
  const double span = u_end - u_begin;
  if (uniform) {
    length = speed_u(u_begin) * span;
    cum.clear();
    return;
  }
  cum.assign(kTable + 1, 0.0);
  for (int k = 0; k < kTable; ++k) {
    const double ua = u_begin + span * k / kTable, ub = u_begin + span * (k + 1) / kTable;
    cum[k + 1] = cum[k] + integrate_speed(*this, ua, ub);
  }
  length = cum[kTable];
}

double PathPiece::s_at(double u) const {
  const double span = u_end - u_begin;
  if (span <= 0) return 0.0;
  if (uniform) return length * (u - u_begin) / span;
  const double x = std::clamp((u - u_begin) / span, 0.0, 1.0) * kTable;
  const int k = std::min(static_cast<int>(x), kTable - 1);
  const double uk = u_begin + span * k / kTable;
  return cum[k] + integrate_speed(*this, uk, u);
}

double PathPiece::u_at(double s_local) const {
  const double span = u_end - u_begin;
  if (length <= 0 || span <= 0) return u_begin;
  if (s_local <= 0) return u_begin;
  if (s_local >= length) return u_end;
  if (uniform) return u_begin + span * (s_local / length);
  const int k = static_cast<int>(std::upper_bound(cum.begin(), cum.end(), s_local) - cum.begin()) - 1;
  const int kk = std::clamp(k, 0, kTable - 1);
  const double ua = u_begin + span * kk / kTable, ub = u_begin + span * (kk + 1) / kTable;
  // Newton on the arc length from the table node; the speed is bounded away from zero (blends are checked
  // for regularity), so it converges in a few steps to round-off.
  double u = ua + (ub - ua) * (s_local - cum[kk]) / std::max(cum[kk + 1] - cum[kk], 1e-300);
  for (int it = 0; it < 8; ++it) {
    double speed = 0.0;
    const double f = cum[kk] + integrate_speed(*this, ua, u, &speed) - s_local;
    const double step = f / speed;
    u = std::clamp(u - step, ua, ub);
    if (std::abs(step) < 1e-14 * (ub - ua)) break;
  }
  return u;
}

PathJet PathPiece::jet_at_u(double u) const {
  const CurveJet c = jet_u(u);
  // Chain rule from u to arc length s, with sigma = |p_u| = ds/du.
  const double sig = c.pu.norm();
  const double sig_u = c.pu.dot(c.puu) / sig;
  const double sig_uu = (c.puu.squaredNorm() + c.pu.dot(c.puuu)) / sig - sig_u * sig_u / sig;
  PathJet j;
  j.p = c.p;
  j.t = c.pu / sig;
  j.k = c.puu / (sig * sig) - c.pu * (sig_u / (sig * sig * sig));
  j.dk = (c.puuu / (sig * sig) - 3 * c.puu * (sig_u / (sig * sig * sig)) - c.pu * (sig_uu / (sig * sig * sig)) +
          3 * c.pu * (sig_u * sig_u / (sig * sig * sig * sig))) /
         sig;
  return j;
}

std::size_t SmoothPath::piece_at(double s, std::size_t hint) const {
  const std::size_t n = pieces.size();
  if (n == 0) return 0;
  if (hint >= n) hint = n - 1;
  // Monotone queries move the hint forward by a few pieces; otherwise binary search.
  for (int step = 0; step < 4; ++step) {
    const PathPiece& p = pieces[hint];
    if (s < p.s_begin) break;
    if (s <= p.s_begin + p.length || hint + 1 == n) return hint;
    ++hint;
  }
  auto it =
      std::upper_bound(pieces.begin(), pieces.end(), s, [](double v, const PathPiece& p) { return v < p.s_begin; });
  return it == pieces.begin() ? 0 : static_cast<std::size_t>(it - pieces.begin()) - 1;
}

core::Vec6 SmoothPath::point(double s) const {
  if (pieces.empty() || s <= 0) return start;
  if (s >= length) return end;
  const PathPiece& p = pieces[piece_at(s)];
  return p.point_u(p.u_at(s - p.s_begin));
}

core::Vec6 SmoothPath::point(double s, Cursor& c) const {
  if (pieces.empty() || s <= 0) return start;
  if (s >= length) return end;
  const std::size_t i = piece_at(s, c.piece);
  const PathPiece& p = pieces[i];
  const double sl = s - p.s_begin;
  if (p.uniform) {
    c.piece = i;
    return p.point_u(p.u_at(sl));
  }
  if (i != c.piece || c.u < 0 || sl < c.s_local) {  // new piece or a step back: full inversion
    c.piece = i;
    c.u = p.u_at(sl);
    c.s_local = sl;
    return p.point_u(c.u);
  }
  // Newton from the previous parameter; the interval is short, so the 4-point rule is exact to round-off.
  const double u0 = c.u, s0 = c.s_local;
  double u = u0 + (sl - s0) / p.speed_u(u0);
  if (!(std::abs(u - u0) <= (p.u_end - p.u_begin) / PathPiece::kTable)) {  // a long step: full inversion
    c.u = p.u_at(sl);
    c.s_local = sl;
    return p.point_u(c.u);
  }
  for (int it = 0; it < 4; ++it) {
    double speed = 0.0;
    const double f = s0 + integrate_speed(p, u0, u, &speed) - sl;
    const double step = f / speed;
    u = std::clamp(u - step, p.u_begin, p.u_end);
    if (std::abs(step) < 1e-14 * (p.u_end - p.u_begin)) break;
  }
  c.u = u;
  c.s_local = sl;
  return p.point_u(u);
}

namespace {

// The removed part of the programmed path beside a blend, for the deviation check.
struct Portion {
  const PathPiece* piece;
  double u_lo, u_hi;
};

double distance_to_portion(const Portion& por, const core::Vec6& q) {
  const PathPiece& pc = *por.piece;
  if (pc.kind == PathPiece::Kind::Line) {
    const core::Vec6 p0 = pc.point_u(por.u_lo), d = pc.point_u(por.u_hi) - p0;
    const double dd = d.squaredNorm();
    const double t = dd > 0 ? std::clamp((q - p0).dot(d) / dd, 0.0, 1.0) : 0.0;
    return (p0 + t * d - q).norm();
  }
  // Curved: start from the candidates (the portion's ends, and for arcs the parameters where the in-plane angle
  // of q falls inside the portion), then Newton on (p(u) - q) . p_u = 0 kept inside the portion.
  double cand[8];
  int nc = 0;
  cand[nc++] = por.u_lo;
  cand[nc++] = por.u_hi;
  cand[nc++] = 0.5 * (por.u_lo + por.u_hi);
  if (pc.kind == PathPiece::Kind::Arc && pc.dtheta != 0) {
    const double tq = std::atan2(q[pc.arc_i2] - pc.c2, q[pc.arc_i1] - pc.c1);
    const double per = kTwoPi / std::abs(pc.dtheta);  // parameter span of one turn
    double u0 = (tq - pc.theta0) / pc.dtheta;
    u0 -= std::floor((u0 - por.u_lo) / per) * per;  // first candidate at or after u_lo
    for (double u = u0; u <= por.u_hi && nc < 8; u += per) cand[nc++] = u;
  }
  double best = kInf;
  for (int c = 0; c < nc; ++c) {
    double u = cand[c];
    for (int it = 0; it < 10; ++it) {
      const CurveJet j = pc.jet_u(u);
      const core::Vec6 r = j.p - q;
      const double g = r.dot(j.pu), h = j.pu.squaredNorm() + r.dot(j.puu);
      if (!(h > 0)) break;
      const double un = std::clamp(u - g / h, por.u_lo, por.u_hi);
      if (std::abs(un - u) < 1e-14) break;
      u = un;
    }
    best = std::min(best, (pc.point_u(u) - q).squaredNorm());
  }
  return std::sqrt(best);
}

struct BlendTrial {
  PathPiece blend;
  double ua = 0, ub = 0;    // new end parameter of A, new start parameter of B
  double deviation = kInf;  // largest distance from the blend to the programmed corner
  bool regular = false;
};

// The blend leaving A at arc length la before its end and entering B at lb after its start, G2 on both sides:
// position, unit tangent and curvature vector match. Its tangent length lambda is the chord, which keeps the
// quintic close to the corner for every angle up to the blend limit.
BlendTrial make_blend(const PathPiece& A, const PathPiece& B, double la, double lb) {
  BlendTrial t;
  const double sa = A.length - la;
  const PathJet ja = A.jet_s(sa), jb = B.jet_s(lb);
  t.ua = A.u_at(sa);
  t.ub = B.u_at(lb);
  const double lambda = (jb.p - ja.p).norm();
  if (!(lambda > 0)) return t;
  PathPiece& q = t.blend;
  q.set_quintic(
      quintic_hermite(ja.p, lambda * ja.t, lambda * lambda * ja.k, jb.p, lambda * jb.t, lambda * lambda * jb.k));
  q.u_begin = 0;
  q.u_end = 1;
  q.uniform = false;
  // Regular: |p_u| stays well away from zero (no cusp, so arc length is a valid parameter).
  double min_speed = kInf;
  constexpr int kSamples = 32;
  {
    // The speeds side by side (quintic_speeds: speed_u's values, bit for bit), then their minimum in the same order.
    double u[kSamples + 1], v[kSamples + 1];
    for (int i = 0; i <= kSamples; ++i) u[i] = double(i) / kSamples;
    quintic_speeds(q, u, v);
    for (int i = 0; i <= kSamples; ++i) min_speed = std::min(min_speed, v[i]);
  }
  t.regular = min_speed > 0.05 * lambda;
  if (!t.regular) return t;

  const Portion pa{&A, t.ua, A.u_end}, pb{&B, B.u_begin, t.ub};
  auto dev = [&](double u) {
    const core::Vec6 x = q.point_u(u);
    return std::min(distance_to_portion(pa, x), distance_to_portion(pb, x));
  };
  // The deviation is the smaller of the distances to the two sides: besides a smooth maximum it has kinks where
  // the blend crosses the corner's bisector, which a grid can miss. Every local maximum of the grid is refined
  // by a golden-section search (the deviation is unimodal within two grid steps of it).
  std::array<double, kSamples + 1> d;
  for (int i = 0; i <= kSamples; ++i) d[i] = dev(double(i) / kSamples);
  double worst = 0.0;
  const double g = 0.5 * (std::sqrt(5.0) - 1);
  for (int i = 1; i < kSamples; ++i) {
    worst = std::max(worst, d[i]);
    if (d[i] < d[i - 1] || d[i] < d[i + 1]) continue;
    double lo = double(i - 1) / kSamples, hi = double(i + 1) / kSamples;
    double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = dev(x1), f2 = dev(x2);
    for (int it = 0; it < 25; ++it) {
      if (f1 > f2) {
        hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = dev(x1);
      } else {
        lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = dev(x2);
      }
    }
    worst = std::max({worst, f1, f2});
  }
  t.deviation = worst;
  q.finalize();
  return t;
}

PathPiece piece_from_move(const core::ToolPath& path, std::size_t index, double feed_scale) {
  const core::Move& m = path.moves[index];
  PathPiece p;
  p.move_index = p.move_index_next = static_cast<int>(index);
  p.rapid = m.rapid;
  const core::Vec6 s = to_path_space(m.start), e = to_path_space(m.end);
  if (m.kind == core::MotionKind::Line) {
    p.kind = PathPiece::Kind::Line;
    p.a = s;
    p.b = e - s;
  } else {
    p.kind = PathPiece::Kind::Arc;
    const core::ArcFrame f = core::arc_frame(m, path.source_path);
    const int i1 = f.axis1, i2 = f.axis2;
    p.arc_i1 = i1;
    p.arc_i2 = i2;
    p.c1 = f.centre_mm[0];
    p.c2 = f.centre_mm[1];
    p.theta0 = f.start_angle_rad;
    p.dtheta = f.sweep_rad;
    p.r0 = f.start_radius_mm;
    p.dr = f.end_radius_mm - f.start_radius_mm;
    p.a = s;
    p.b = e - s;
    p.a[i1] = p.a[i2] = p.b[i1] = p.b[i2] = 0;
    // A circle or helix: |dp/du| is constant (the radii's last-digit difference dropped).
    p.uniform = f.constant_radius();
    if (p.uniform) p.dr = 0;
  }
  p.finalize();

  const bool xyz_moves = (e.head<3>() - s.head<3>()).norm() > 1e-12 || m.kind == core::MotionKind::Arc;
  if (m.rapid) {
    p.feed_limit = kInf;
  } else if (m.feed_mode == core::FeedMode::InverseTime) {
    if (!(m.inverse_time_per_min > 0))
      throw core::Error(
          core::located(path.source_path, m.source_line, "inverse-time feed move without a positive F word"));
    p.feed_metric = PathPiece::FeedMetric::Path;
    p.feed_limit = p.length * m.inverse_time_per_min * feed_scale / 60.0;
  } else {
    if (!(m.feed_mm_per_min > 0))
      throw core::Error(
          core::located(path.source_path, m.source_line, "feed move with no feed rate (F is 0 or missing)"));
    p.feed_metric = xyz_moves ? PathPiece::FeedMetric::Xyz : PathPiece::FeedMetric::Abc;
    p.feed_limit = m.feed_mm_per_min * feed_scale / 60.0;
  }
  return p;
}

// The pieces of a move: one, or for an axis-space move of a chain machine with via points (core/kinematics) the
// lines start -> via... -> end. A via line covers the programmed-path parameters [s_a, s_b] of the move, so under an
// inverse-time feed it takes (s_b - s_a) of the move's programmed duration (the tip keeps its programmed speed along
// the move); a line at one s (the free rotary axis turning at a singular pose, the tool pose held) has no feed limit
// of its own: the axes' limits give its time.
void pieces_from_move(const core::ToolPath& path, std::size_t index, double feed_scale, std::vector<PathPiece>& out) {
  const core::Move& m = path.moves[index];
  if (m.via.empty()) {
    PathPiece p = piece_from_move(path, index, feed_scale);
    if (p.length > 1e-9) out.push_back(std::move(p));
    return;
  }
  if (m.kind != core::MotionKind::Line || m.via_s.size() != m.via.size())
    throw core::Error(
        core::located(path.source_path, m.source_line, "via points on an arc, or without their path parameters"));
  core::ToolPath one;
  one.source_path = path.source_path;
  core::Move part = m;
  part.via.clear();
  part.via_s.clear();
  one.moves.push_back(part);
  core::Vec6 from = m.start;
  double s_from = 0.0;
  for (std::size_t k = 0; k <= m.via.size(); ++k) {
    const core::Vec6& to = k < m.via.size() ? m.via[k] : m.end;
    const double s_to = k < m.via.size() ? m.via_s[k] : 1.0;
    if (!(s_to >= s_from) || s_to > 1.0)
      throw core::Error(core::located(path.source_path, m.source_line, "via points whose path parameters decrease"));
    core::Move& q = one.moves.front();
    q.start = from;
    q.end = to;
    if (m.feed_mode == core::FeedMode::InverseTime && !m.rapid) {
      // The fraction (s_to - s_from) of the move's duration 1 / inverse_time_per_min.
      q.inverse_time_per_min = s_to > s_from ? m.inverse_time_per_min / (s_to - s_from) : kInf;
    }
    PathPiece p = piece_from_move(one, 0, feed_scale);
    p.move_index = p.move_index_next = static_cast<int>(index);
    if (m.feed_mode == core::FeedMode::InverseTime && !m.rapid && !(s_to > s_from)) p.feed_limit = kInf;
    if (p.length > 1e-9) out.push_back(std::move(p));
    from = to;
    s_from = s_to;
  }
}

// How far the tool pose moves in the workpiece frame per unit of path-space deviation at the junction of two pieces
// (Move::tip_per_mm, tip_per_deg; Cauchy-Schwarz on |J_lin d_lin + sum J_r d_r|): the linear axes' gain, and each
// rotary axis' where either piece turns it (a blend between pieces that hold a rotary axis holds it too).
double corner_gain(const core::ToolPath& path, const PathPiece& a, const PathPiece& b) {
  const core::Move& ma = path.moves[static_cast<std::size_t>(a.move_index_next)];
  const core::Move& mb = path.moves[static_cast<std::size_t>(b.move_index)];
  const double lin = std::max(ma.tip_per_mm, mb.tip_per_mm);
  double g2 = lin * lin;
  for (int r = 0; r < 3; ++r) {
    bool turns = false;
    for (const PathPiece* pc : {&a, &b})
      if (pc->point_u(pc->u_begin)[3 + r] != pc->point_u(pc->u_end)[3 + r]) turns = true;
    if (!turns) continue;
    const double g = std::max(ma.tip_per_deg[r], mb.tip_per_deg[r]);
    g2 += g * g;
  }
  return g2 == 1.0 ? 1.0 : std::sqrt(g2);
}

// How far the tool tip moves per unit of path-space length along a line piece (Move::tip_per_mm, tip_per_deg, the
// latter only for the rotary axes the piece turns; Cauchy-Schwarz as corner_gain).
double line_gain(const core::ToolPath& path, const PathPiece& p) {
  const core::Move& m = path.moves[static_cast<std::size_t>(p.move_index)];
  double g2 = m.tip_per_mm * m.tip_per_mm;
  for (int r = 0; r < 3; ++r)
    if (p.b[3 + r] != 0) g2 += m.tip_per_deg[r] * m.tip_per_deg[r];
  return std::sqrt(g2);
}

// A line a tiny one can be merged into: a whole straight move (no via points) under the same tool and offset.
bool mergeable(const core::ToolPath& path, const PathPiece& p, const PathPiece& q) {
  if (p.kind != PathPiece::Kind::Line || q.kind != PathPiece::Kind::Line) return false;
  const core::Move& a = path.moves[static_cast<std::size_t>(p.move_index)];
  const core::Move& b = path.moves[static_cast<std::size_t>(q.move_index)];
  return a.via.empty() && b.via.empty() && a.tool_number == b.tool_number &&
         a.tool_length_offset_mm == b.tool_length_offset_mm && a.tcp == b.tcp;
}

// Moves line q so that it starts at `from` (or ends at `to`), keeping an inverse-time feed's duration.
void reshape_line(PathPiece& q, const core::Vec6& from, const core::Vec6& to) {
  const double old_length = q.length;
  q.a = from;
  q.b = to - from;
  q.finalize();
  if (q.feed_metric == PathPiece::FeedMetric::Path && old_length > 0) q.feed_limit *= q.length / old_length;
}

// Lines shorter than the tiny length merged into the next line (or, for the last, the previous one). shift[i] bounds
// how far piece i now lies from the programmed path (path space): the merged line's length, summed over merges.
void merge_tiny_lines(const core::ToolPath& path, double tiny_tip_mm, std::vector<PathPiece>& base,
                      std::vector<double>& shift) {
  std::vector<PathPiece> out;
  std::vector<double> out_shift;
  core::reserve_huge(out, base.size());
  core::reserve_huge(out_shift, base.size());
  for (std::size_t i = 0; i < base.size(); ++i) {
    PathPiece& p = base[i];
    const bool tiny = p.kind == PathPiece::Kind::Line && p.length * line_gain(path, p) < tiny_tip_mm;
    if (tiny && i + 1 < base.size() && mergeable(path, p, base[i + 1])) {
      PathPiece& n = base[i + 1];
      reshape_line(n, p.a, n.a + n.b);
      shift[i + 1] += shift[i] + p.length;
      continue;
    }
    if (tiny && !out.empty() && mergeable(path, out.back(), p)) {
      PathPiece& q = out.back();
      reshape_line(q, q.a, p.a + p.b);
      out_shift.back() += shift[i] + p.length;
      continue;
    }
    out.push_back(std::move(p));
    out_shift.push_back(shift[i]);
  }
  base.swap(out);
  shift.swap(out_shift);
}

// Whether the kink between A (ending with jet ja) and B (starting with jb) is taken without a blend
// (SmoothPathOptions::period_s): per axis, the velocity step at the fastest speed allowed there against what the
// plan leaves of the axis' jerk and acceleration over one period.
bool kink_within_limits(const PathPiece& A, const PathPiece& B, const PathJet& ja, const PathJet& jb,
                        const SmoothPathOptions& o) {
  const double te = o.period_s;
  if (!(te > 0)) return false;
  const core::Vec6 m = ja.t.cwiseAbs().cwiseMax(jb.t.cwiseAbs());  // the larger tangent component per axis
  // Only where the rotary axes hold still: where they turn, a kink moves the tool tip through the chain's gains, and
  // on the five-axis dome passing such kinks made the cycle 0.2 s longer (not understood yet): they keep their blends.
  if (m.tail<3>().maxCoeff() > 0) return false;
  // The fastest path speed at the junction: the programmed feeds (X Y Z speed, the path speed when the rotary axes
  // hold still), and every axis' velocity limit.
  double v = kInf;
  for (const PathPiece* p : {&A, &B})
    if (p->feed_metric == PathPiece::FeedMetric::Xyz && m.tail<3>().maxCoeff() == 0) v = std::min(v, p->feed_limit);
  // Largest path acceleration and jerk the plan can give here: each axis i carries m_i of them.
  double a_path = kInf, j_path = kInf;
  for (int i = 0; i < 6; ++i) {
    if (m[i] <= 0) continue;
    v = std::min(v, o.axis_velocity[i] / m[i]);
    a_path = std::min(a_path, o.plan_accel_share * o.axis_accel[i] / m[i]);
    j_path = std::min(j_path, o.plan_jerk_share * o.axis_jerk[i] / m[i]);
  }
  if (!std::isfinite(v)) return false;
  // A velocity step dv between two setpoints gives one period an acceleration of at most dv / T and a jerk of at
  // most dv / T^2 on top of the plan's.
  for (int i = 0; i < 6; ++i) {
    const double dv = v * std::abs(ja.t[i] - jb.t[i]);
    if (dv == 0) continue;
    if (!(dv <= (o.axis_jerk[i] - m[i] * j_path) * te * te)) return false;
    if (!(dv <= (o.axis_accel[i] - m[i] * a_path) * te)) return false;
  }
  return true;
}

}  // namespace

SmoothPath build_smooth_path(const core::ToolPath& path, const SmoothPathOptions& options) {
  SmoothPath out;
  out.start = to_path_space(path.initial_position);
  out.end = out.start;
  std::vector<PathPiece> base;
  core::reserve_huge(base, path.moves.size());
  for (std::size_t i = 0; i < path.moves.size(); ++i) pieces_from_move(path, i, options.feed_scale, base);
  std::vector<double> shift(base.size(), 0.0);
  merge_tiny_lines(path, options.tiny_move_share * options.tolerance_mm, base, shift);
  if (base.empty()) return out;
  out.start = base.front().point_u(base.front().u_begin);
  out.end = base.back().point_u(base.back().u_end);

  const double corner_target = 0.9 * options.tolerance_mm;  // margin for the deviation between checked samples
  std::vector<double> length0(base.size());
  for (std::size_t i = 0; i < base.size(); ++i) length0[i] = base[i].length;

  std::vector<PathPiece> pieces;
  core::reserve_huge(pieces, 2 * base.size());
  for (std::size_t i = 0; i < base.size(); ++i) {
    PathPiece& A = base[i];
    if (i + 1 == base.size()) {
      A.finalize();
      pieces.push_back(A);
      break;
    }
    PathPiece& B = base[i + 1];
    const PathJet ja = A.jet_s(A.length), jb = B.jet_s(0.0);
    const double cosang = std::clamp(ja.t.dot(jb.t), -1.0, 1.0);
    const double angle = std::acos(cosang);
    // Between lines only: at an arc the kink comes with a curvature jump, which the tangent rounding below handles.
    const bool kink = angle >= 1e-9 && A.kind == PathPiece::Kind::Line && B.kind == PathPiece::Kind::Line &&
                      kink_within_limits(A, B, ja, jb, options);
    const bool g1 = angle < 1e-9 || kink;
    // The tolerance holds on the tool tip in the workpiece frame: on chain machines a path-space deviation moves it by
    // up to corner_gain times as much (1 on "xyz" machines and wherever the rotary axes hold still); a merged tiny
    // line already moved A or B by up to its shift.
    const double gain = corner_gain(path, A, B);
    const double shifted = std::max(shift[i], shift[i + 1]);
    double target = corner_target / gain - shifted;
    if (angle < 1e-6 || kink) {
      // Tangent junction: a transition of length L bridging the curvature jump dK has a rate |dK| / L, so the axis
      // jerk v^3 |dK_i| / L stays within J_i for L >= v^3 |dK_i| / J_i; it then leaves the path by about
      // L^2 |dK| / 24 (a clothoid's shift). Twice that, within the tolerance, is all the rounding it gets: at low
      // feed next to none.
      const core::Vec6 dk = ja.k - jb.k;
      double v = std::min({A.feed_limit, B.feed_limit, options.rapid_speed});
      for (const PathJet* j : {&ja, &jb})
        for (int i = 0; i < 6; ++i) {
          if (std::abs(j->k[i]) > 0) v = std::min(v, std::sqrt(options.axis_accel[i] / std::abs(j->k[i])));
          if (std::abs(j->dk[i]) > 0) v = std::min(v, std::cbrt(options.axis_jerk[i] / std::abs(j->dk[i])));
        }
      double L = 0;
      for (int i = 0; i < 6; ++i)
        if (std::abs(dk[i]) > 0) L = std::max(L, v * v * v * std::abs(dk[i]) / options.axis_jerk[i]);
      target = std::min(corner_target / gain - shifted, 2 * L * L * dk.norm() / 24);
    }
    const bool g2 = g1 && (ja.k - jb.k).norm() < 1e-9;
    if (g2) {  // already curvature-continuous
      A.finalize();
      pieces.push_back(A);
      continue;
    }
    bool blended = false;
    if (angle <= options.max_blend_angle_rad) {
      // Each piece gives at most half its programmed length to each of its two corners.
      const double ca = std::min(0.5 * length0[i], A.length), cb = 0.5 * length0[i + 1];
      const bool lines = A.kind == PathPiece::Kind::Line && B.kind == PathPiece::Kind::Line;
      BlendTrial best;
      BlendTrial t = make_blend(A, B, ca, cb);
      if (t.regular && t.deviation <= target) {
        best = std::move(t);
      } else if (lines && t.regular && std::isfinite(t.deviation)) {
        // Two lines: the blend is self-similar about the corner, so its deviation is proportional to the trim.
        const double f = target / t.deviation * (1 - 1e-9);
        BlendTrial s = make_blend(A, B, f * ca, f * cb);
        if (s.regular && s.deviation <= target) best = std::move(s);
      }
      if (!best.regular || best.deviation > target) {
        // Arcs involved: bisect the trim factor for the largest blend within the tolerance.
        double lo = 0.0, hi = 1.0;
        for (int it = 0; it < 40 && hi - lo > 1e-2 * hi; ++it) {
          const double f = 0.5 * (lo + hi);
          BlendTrial s = make_blend(A, B, f * ca, f * cb);
          if (s.regular && s.deviation <= target) {
            lo = f;
            best = std::move(s);
          } else {
            hi = f;
          }
        }
      }
      if (best.regular && best.deviation <= target && best.blend.length > 0) {
        A.u_end = best.ua;
        A.finalize();
        B.u_begin = best.ub;
        B.finalize();
        pieces.push_back(A);
        PathPiece& q = best.blend;
        q.move_index = A.move_index;
        q.move_index_next = B.move_index;
        q.rapid = A.rapid && B.rapid;
        // The blend carries the stricter of the two programmed feeds.
        if (A.feed_limit <= B.feed_limit) {
          q.feed_metric = A.feed_metric, q.feed_limit = A.feed_limit;
        } else {
          q.feed_metric = B.feed_metric, q.feed_limit = B.feed_limit;
        }
        pieces.push_back(std::move(q));
        ++out.blends;
        blended = true;
      }
    }
    if (!blended) {
      A.stop_after = true;
      A.finalize();
      pieces.push_back(A);
      ++out.exact_stops;
    }
  }

  // Drop what the blends consumed entirely; a stop on a dropped piece moves to its predecessor.
  core::reserve_huge(out.pieces, pieces.size());
  double s = 0.0;
  for (PathPiece& p : pieces) {
    if (p.length <= 1e-12) {
      if (p.stop_after && !out.pieces.empty()) out.pieces.back().stop_after = true;
      continue;
    }
    p.s_begin = s;
    s += p.length;
    out.pieces.push_back(std::move(p));
  }
  out.length = s;
  return out;
}

}  // namespace vmsim::motion
