// Contour error (Duong et al. section III.B eq. 1-2, the predictive-compensation paper section 4): for every actual
// position, the exact shortest distance to the commanded path near the place the tool is following, signed.
//
// The two-step search of the predictive-compensation paper:
//  1. nearest command sample, searched around the previous foot point (not the whole path: Duong et al.'s step 2
//     takes the minimum over all past samples, which on a raster of passes 0.25 mm apart lands on a neighbouring
//     pass as soon as the actual deviates by more than half the stepover);
//  2. exact distance to the two command segments beside that sample (eq. 1, clamped to the segments).
//
// How the search stays on the pass the tool is on (see contour.hpp for the options):
//  - Consecutive identical command samples (dwells, rests, the held last point) are merged first: the search
//    runs on distinct points, so a stationary stretch is one point, never a zero-length segment.
//  - Arc-length budget: a command point closer to the actual than the previous foot sample c_f lies within
//    2 d_f of c_f (triangle inequality, d_f = |a - c_f|). On a path that does not fold back on itself within that
//    ball the arc length between them is at most twice the chord, so candidates are scanned only while the
//    arc length from c_f stays within 4 d_f, both ways. This is what keeps the cost at a few samples per actual
//    sample, and it rules out passes reached only by a long way round (one-way rasters, spirals).
//  - Direction: a candidate that is not reached from c_f by a monotone descent of the distance (i.e. that lies
//    beyond a hump, a "jump") is taken only if the path there does not run against the tool's motion (both
//    adjacent segments more than 120 degrees away from the actual's displacement over the last sample). A zigzag
//    raster's neighbouring passes run the other way, so they are never jumped to while the tool travels along
//    its pass, however close they are; at a corner or a U-turn the tool's own direction turns, and the foot
//    follows. Candidates reached by descent (the tool overshooting the end of a move and coming back) are
//    always allowed.
//  - Same instant: the command point at the actual's own instant (the point the drives are following) is also a
//    candidate, under the same direction test. The arc-length budget cannot reach it where the path retraces
//    itself (a move out and back along the same line, as a program's first rapid from a job's start position):
//    the foot slides back down the outgoing leg, whose points are as near as the return leg's, and would be left
//    at its start, arc-length far from the move that follows.
//  - Index window: candidates are also limited to `window_samples` distinct points either side of the previous
//    foot (the predictive-compensation paper's buffer of length m). Default: twice the largest tracking error (command
//    at the same instant minus actual) over the smallest distinct command step, in [32, 65536]. Jerk-limited stops make
//    the smallest step tiny, so the default is usually the upper bound; the arc-length budget is the working limit, the
//    window only a hard cap on the cost of one sample.
//
// Sign (eq. 2): sign(n . E) with E = foot point - actual, i.e. command minus actual like Duong et al.'s E_X = X_d -
// X_a, taken at the foot point rather than at the same instant: Duong et al.'s E_i is the "minimum tracking error",
// the command sample nearest the actual, and the same-instant command on a curve lies inside the curve by
// lag^2 / 2R, which would give both sides of the path the same sign. n: plane_normal x tangent of the foot
// segment for planar profiles; otherwise the principal normal of the command path at the nearest sample.
#include "motion/contour.hpp"

#include "core/error.hpp"
#include "core/huge_pages.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace vmsim::motion {
namespace {

// Command samples closer than this to the previous kept sample are repeats (a femtometre: far below any
// resolution that matters, far above the rounding of coordinates in a machine's travel).
constexpr double kRepeatTolMm = 1e-12;
// Actual displacements below this (mm per sample) carry no direction: the direction test is off while the tool
// stands still.
constexpr double kStillMm = 1e-9;
// Jumps to a point whose path runs more than 120 degrees against the tool's motion are refused.
constexpr double kCosReverse = -0.5;
// Arc length scanned either way from the previous foot sample, in units of its distance to the actual.
constexpr double kArcBudget = 4.0;
constexpr int kMinWindow = 32, kMaxWindow = 65536;

// The command path with consecutive repeats merged. Per point 40 B (issue 21: a run's 3.7 M samples held 84 B each
// here at its memory peak): the principal normal is kept as the point whose turn defines it, recomputed when used.
struct DistinctPath {
  std::vector<double> p;    // x y z per point
  std::vector<double> s;    // arc length at each point
  std::vector<int> last;    // last command row of each point's run of repeats (ContourError's rows are int too)
  std::vector<int> n_from;  // the point whose turn is each point's principal normal (-1: none), without a plane normal
  double noise = 0.0;       // rounding of the coordinates: turns below noise / step are not measurable
  Eigen::Index size() const { return static_cast<Eigen::Index>(s.size()); }
};

void check_input(const Eigen::MatrixXd& m, const char* what) {
  if (m.cols() != 3)
    throw core::Error(std::string("contour_error: the ") + what + " has " + std::to_string(m.cols()) +
                      " columns; expected 3 (x y z in mm)");
  if (m.allFinite()) return;  // one contiguous pass; the search below names the first bad value
  for (Eigen::Index k = 0; k < m.rows(); ++k)
    for (int j = 0; j < 3; ++j)
      if (!std::isfinite(m(k, j)))
        throw core::Error(std::string("contour_error: the ") + what + " row " + std::to_string(k) + " column " +
                          std::to_string(j) + " is not finite");
}

DistinctPath merge_repeats(const Eigen::MatrixXd& c) {
  DistinctPath path;
  const Eigen::Index n = c.rows();
  core::reserve_huge(path.p, static_cast<std::size_t>(3 * n));
  core::reserve_huge(path.s, static_cast<std::size_t>(n));
  core::reserve_huge(path.last, static_cast<std::size_t>(n));
  double s = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double x = c(k, 0), y = c(k, 1), z = c(k, 2);
    if (!path.s.empty()) {
      const double* q = &path.p[path.p.size() - 3];
      const double d = std::sqrt((x - q[0]) * (x - q[0]) + (y - q[1]) * (y - q[1]) + (z - q[2]) * (z - q[2]));
      if (d <= kRepeatTolMm) {
        path.last.back() = static_cast<int>(k);
        continue;
      }
      s += d;
    }
    path.p.insert(path.p.end(), {x, y, z});
    path.s.push_back(s);
    path.last.push_back(static_cast<int>(k));
  }
  return path;
}

// Whether the tangent turns measurably at a point between segments of lengths l1 and l2 (turn: |dt|, the change of
// the unit tangent): above what rounding of the coordinates gives. One test for principal_normals and turn_at.
inline bool turns_measurably(double turn, double l1, double l2, double noise) {
  return turn > std::max(1e-12, noise / std::min(l1, l2));
}

// The unit turn of the tangent at interior point q, when it is measurable (false: straight there).
bool turn_at(const DistinctPath& path, Eigen::Index q, Eigen::Vector3d& n) {
  const double* a = &path.p[3 * (q - 1)];
  const double* b = &path.p[3 * q];
  const double* c = &path.p[3 * (q + 1)];
  const double l1 = path.s[q] - path.s[q - 1], l2 = path.s[q + 1] - path.s[q];
  Eigen::Vector3d dt((c[0] - b[0]) / l2 - (b[0] - a[0]) / l1, (c[1] - b[1]) / l2 - (b[1] - a[1]) / l1,
                     (c[2] - b[2]) / l2 - (b[2] - a[2]) / l1);
  const double turn = dt.norm();
  if (!turns_measurably(turn, l1, l2, path.noise)) return false;
  n = dt / turn;
  return true;
}

// Principal normal: the direction in which the unit tangent turns from one segment to the next. Where it does
// not turn measurably (straight stretches, or steps so short that rounding of the coordinates dominates the
// turn) the last defined normal is carried forward; before the first defined one, that first one is used; a path
// that never turns gets n = 0, and its contour error is then unsigned (always >= 0).
void principal_normals(DistinctPath& path) {
  const Eigen::Index q_n = path.size();
  core::reserve_huge(path.n_from, static_cast<std::size_t>(q_n));
  path.n_from.assign(static_cast<std::size_t>(q_n), -1);
  if (q_n < 3) return;
  double scale = 1.0;
  for (double v : path.p) scale = std::max(scale, std::abs(v));
  // Rounding of coordinates of magnitude `scale` perturbs a unit tangent over a step h by ~eps * scale / h.
  path.noise = 64.0 * std::numeric_limits<double>::epsilon() * scale;
  int first_defined = -1, carry = -1;
  // turn_at's test, each segment's unit tangent computed once: point q's outgoing tangent (c - b) / l2 is point
  // q + 1's incoming one (b - a) / l1, the same operands, so the same bits (three divisions per point, not six).
  const double* P = path.p.data();
  const double* S = path.s.data();
  double t_in[3];
  {
    const double l = S[1] - S[0];
    for (int i = 0; i < 3; ++i) t_in[i] = (P[3 + i] - P[i]) / l;
  }
  for (Eigen::Index q = 1; q + 1 < q_n; ++q) {
    const double* b = P + 3 * q;
    const double* c = b + 3;
    const double l1 = S[q] - S[q - 1], l2 = S[q + 1] - S[q];
    double t_out[3];
    for (int i = 0; i < 3; ++i) t_out[i] = (c[i] - b[i]) / l2;
    const Eigen::Vector3d dt(t_out[0] - t_in[0], t_out[1] - t_in[1], t_out[2] - t_in[2]);
    for (int i = 0; i < 3; ++i) t_in[i] = t_out[i];
    if (turns_measurably(dt.norm(), l1, l2, path.noise)) {
      carry = static_cast<int>(q);
      if (first_defined < 0) first_defined = carry;
    }
    path.n_from[static_cast<std::size_t>(q)] = carry;
  }
  if (first_defined < 0) return;  // straight: n stays 0
  for (Eigen::Index q = 0; q < first_defined; ++q) path.n_from[static_cast<std::size_t>(q)] = first_defined;
  path.n_from[static_cast<std::size_t>(q_n - 1)] = path.n_from[static_cast<std::size_t>(q_n - 2)];
}

// The principal normal at point q (zero where the path never turns).
Eigen::Vector3d normal_at(const DistinctPath& path, Eigen::Index q) {
  const int from = path.n_from[static_cast<std::size_t>(q)];
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  if (from >= 0) turn_at(path, from, n);
  return n;
}

inline double dist2(const double* c, double ax, double ay, double az) {
  const double dx = c[0] - ax, dy = c[1] - ay, dz = c[2] - az;
  return dx * dx + dy * dy + dz * dz;
}

int default_window(const Eigen::MatrixXd& command, const Eigen::MatrixXd& actual, const DistinctPath& path) {
  double max_e2 = 0.0;
  const Eigen::Index n = command.rows();
  for (Eigen::Index k = 0; k < actual.rows(); ++k) {
    const Eigen::Index i = std::min(k, n - 1);
    max_e2 = std::max(max_e2, (command.row(i) - actual.row(k)).squaredNorm());
  }
  double h_min = std::numeric_limits<double>::infinity();
  for (Eigen::Index q = 1; q < path.size(); ++q) h_min = std::min(h_min, path.s[q] - path.s[q - 1]);
  if (!std::isfinite(h_min)) return kMinWindow;
  const double w = std::ceil(2.0 * std::sqrt(max_e2) / h_min);
  return static_cast<int>(std::clamp(w, double(kMinWindow), double(kMaxWindow)));
}

}  // namespace

namespace {

// contour_error; `release`, when given, is the command, released once the search no longer needs it.
ContourError contour_error_impl(const Eigen::MatrixXd& command, const Eigen::MatrixXd& actual,
                                const ContourOptions& options, Eigen::MatrixXd* release) {
  check_input(command, "command");
  check_input(actual, "actual");
  if (command.rows() == 0) throw core::Error("contour_error: the command path has no samples");
  Eigen::Vector3d plane_n = Eigen::Vector3d::Zero();
  const bool planar = options.plane_normal.has_value();
  if (planar) {
    plane_n = *options.plane_normal;
    if (!plane_n.allFinite() || plane_n.norm() == 0.0)
      throw core::Error("contour_error: plane_normal must be a finite, non-zero vector");
  }

  DistinctPath path = merge_repeats(command);
  const Eigen::Index q_n = path.size();
  const Eigen::Index m = actual.rows();
  const Eigen::Index command_rows = command.rows();
  const int window = options.window_samples > 0 ? options.window_samples : default_window(command, actual, path);
  if (release) release->resize(0, 3);  // `command` is not used beyond this line
  if (!planar) principal_normals(path);

  ContourError out;
  out.window_samples = window;
  out.signed_mm.resize(m);
  out.foot_segment.resize(m);
  core::advise_huge_pages(out.signed_mm);
  core::advise_huge_pages(out.foot_segment);
  if (m == 0) return out;

  // The distinct point of the command row at the current instant (the rows only increase).
  Eigen::Index q_now = 0;

  const double* P = path.p.data();
  const double* S = path.s.data();
  auto pt = [&](Eigen::Index q) { return P + 3 * q; };

  // The first foot: the nearest distinct point within the window from the start of the path.
  Eigen::Index f = 0;
  {
    const double ax = actual(0, 0), ay = actual(0, 1), az = actual(0, 2);
    double best = dist2(pt(0), ax, ay, az);
    for (Eigen::Index q = 1; q < std::min<Eigen::Index>(q_n, window + 1); ++q) {
      const double d = dist2(pt(q), ax, ay, az);
      if (d < best) best = d, f = q;
    }
  }

  double sum2 = 0.0, max_abs = 0.0;
  int normal_from = -2;  // the point normal was last computed from (-2: none yet)
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double px = actual(0, 0), py = actual(0, 1), pz = actual(0, 2);
  for (Eigen::Index k = 0; k < m; ++k) {
    const double ax = actual(k, 0), ay = actual(k, 1), az = actual(k, 2);
    const double ux = ax - px, uy = ay - py, uz = az - pz;
    px = ax, py = ay, pz = az;
    const double u_len = std::sqrt(ux * ux + uy * uy + uz * uz);
    const bool moving = u_len > kStillMm;

    // Does the path at q run with the tool's motion (at least one adjacent segment within 120 degrees)?
    auto runs_with_motion = [&](Eigen::Index q) {
      const double* c = pt(q);
      if (q > 0) {
        const double* b = pt(q - 1);
        const double dot = (c[0] - b[0]) * ux + (c[1] - b[1]) * uy + (c[2] - b[2]) * uz;
        if (dot >= kCosReverse * (S[q] - S[q - 1]) * u_len) return true;
      }
      if (q + 1 < q_n) {
        const double* d = pt(q + 1);
        const double dot = (d[0] - c[0]) * ux + (d[1] - c[1]) * uy + (d[2] - c[2]) * uz;
        if (dot >= kCosReverse * (S[q + 1] - S[q]) * u_len) return true;
      }
      return false;
    };

    // Step 1: nearest distinct command point around the previous foot.
    const double d_f2 = dist2(pt(f), ax, ay, az);
    const double budget = kArcBudget * std::sqrt(d_f2);
    Eigen::Index best = f;
    double best2 = d_f2;
    const Eigen::Index hi = std::min<Eigen::Index>(q_n - 1, f + window);
    const Eigen::Index lo = std::max<Eigen::Index>(0, f - window);
    {
      bool descent = true;
      double prev = d_f2;
      for (Eigen::Index q = f + 1; q <= hi && S[q] - S[f] <= budget; ++q) {
        const double d = dist2(pt(q), ax, ay, az);
        if (d > prev) descent = false;
        prev = d;
        if (d < best2 && (descent || !moving || runs_with_motion(q))) best2 = d, best = q;
      }
    }
    {
      bool descent = true;
      double prev = d_f2;
      for (Eigen::Index q = f - 1; q >= lo && S[f] - S[q] <= budget; --q) {
        const double d = dist2(pt(q), ax, ay, az);
        if (d > prev) descent = false;
        prev = d;
        if (d < best2 && (descent || !moving || runs_with_motion(q))) best2 = d, best = q;
      }
    }
    // The command point at this instant (the held last point for settling rows).
    {
      const Eigen::Index row = std::min<Eigen::Index>(k, command_rows - 1);
      while (path.last[static_cast<std::size_t>(q_now)] < row) ++q_now;
      const Eigen::Index q = q_now;
      const double d = dist2(pt(q), ax, ay, az);
      if (d < best2 && (!moving || runs_with_motion(q))) best2 = d, best = q;
    }
    f = best;

    // Step 2: exact distance to the segments [f-1, f] and [f, f+1] (eq. 1, the projection clamped to each).
    double foot[3] = {pt(f)[0], pt(f)[1], pt(f)[2]};
    double foot2 = q_n > 1 ? std::numeric_limits<double>::infinity() : best2;
    Eigen::Index seg = 0;
    for (Eigen::Index s0 = std::max<Eigen::Index>(0, f - 1); s0 <= f && s0 + 1 < q_n; ++s0) {
      const double* b = pt(s0);
      const double* c = pt(s0 + 1);
      const double ex = c[0] - b[0], ey = c[1] - b[1], ez = c[2] - b[2];
      const double l2 = ex * ex + ey * ey + ez * ez;  // > 0: repeats are merged
      const double t = std::clamp(((ax - b[0]) * ex + (ay - b[1]) * ey + (az - b[2]) * ez) / l2, 0.0, 1.0);
      const double fx = b[0] + t * ex, fy = b[1] + t * ey, fz = b[2] + t * ez;
      const double d = (fx - ax) * (fx - ax) + (fy - ay) * (fy - ay) + (fz - az) * (fz - az);
      if (d < foot2) {  // a tie (foot on the shared vertex) keeps the earlier segment
        foot2 = d, seg = s0;
        foot[0] = fx, foot[1] = fy, foot[2] = fz;
      }
    }

    // Sign (eq. 2): n . E, E = foot - actual.
    double nx = 0.0, ny = 0.0, nz = 0.0;
    if (planar) {
      if (q_n > 1) {
        const double* b = pt(seg);
        const double* c = pt(seg + 1);
        const double tx = c[0] - b[0], ty = c[1] - b[1], tz = c[2] - b[2];
        nx = plane_n.y() * tz - plane_n.z() * ty;
        ny = plane_n.z() * tx - plane_n.x() * tz;
        nz = plane_n.x() * ty - plane_n.y() * tx;
      }
    } else {
      // Consecutive feet mostly share the point whose turn defines the normal: computed again only when it changes.
      const int from = path.n_from[static_cast<std::size_t>(f)];
      if (from != normal_from) {
        normal_from = from;
        normal = normal_at(path, f);
      }
      nx = normal[0], ny = normal[1], nz = normal[2];
    }
    const double ne = nx * (foot[0] - ax) + ny * (foot[1] - ay) + nz * (foot[2] - az);
    const double eps = std::sqrt(foot2);
    const double signed_eps = ne < 0.0 ? -eps : eps;
    out.signed_mm[k] = signed_eps;
    out.foot_segment[k] = static_cast<int>(q_n > 1 ? path.last[seg] : 0);
    sum2 += eps * eps;
    max_abs = std::max(max_abs, eps);
  }
  out.max_abs_mm = max_abs;
  out.rms_mm = std::sqrt(sum2 / static_cast<double>(m));
  out.mse_um2 = sum2 / static_cast<double>(m) * 1e6;
  return out;
}

}  // namespace

ContourError contour_error(const Eigen::MatrixXd& command, const Eigen::MatrixXd& actual,
                           const ContourOptions& options) {
  return contour_error_impl(command, actual, options, nullptr);
}

ContourError contour_error(Eigen::MatrixXd&& command, const Eigen::MatrixXd& actual, const ContourOptions& options) {
  return contour_error_impl(command, actual, options, &command);
}

}  // namespace vmsim::motion
