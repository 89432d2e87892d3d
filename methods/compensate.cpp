#include "methods/compensate.hpp"

#include "core/error.hpp"

#include <Eigen/Geometry>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace vmsim::methods {

using Index = Eigen::Index;

Eigen::MatrixXd tool_tips(const motion::Kinematics& kin, const Eigen::MatrixXd& axes, const Eigen::VectorXd& tlo_mm) {
  Eigen::MatrixXd tips(axes.rows(), 3);
  Eigen::VectorXd q(axes.cols());
  for (Index k = 0; k < axes.rows(); ++k) {
    q = axes.row(k).transpose();
    const double tlo = tlo_mm.size() > 0 ? tlo_mm[std::min(k, tlo_mm.size() - 1)] : 0.0;
    tips.row(k) = kin.forward(q, tlo).tip_mm.transpose();
  }
  return tips;
}

Eigen::MatrixXd tool_axes(const motion::Kinematics& kin, const Eigen::MatrixXd& axes, const Eigen::VectorXd& tlo_mm) {
  Eigen::MatrixXd u(axes.rows(), 3);
  Eigen::VectorXd q(axes.cols());
  for (Index k = 0; k < axes.rows(); ++k) {
    q = axes.row(k).transpose();
    const double tlo = tlo_mm.size() > 0 ? tlo_mm[std::min(k, tlo_mm.size() - 1)] : 0.0;
    u.row(k) = kin.forward(q, tlo).axis.transpose();
  }
  return u;
}

Eigen::MatrixXd axes_at(const Eigen::MatrixXd& cu, const Eigen::VectorXd& parameter) {
  const Index ns = cu.rows();
  Eigen::MatrixXd u(parameter.size(), 3);
  for (Index i = 0; i < parameter.size(); ++i) {
    const double s = std::clamp(parameter[i], 0.0, static_cast<double>(ns - 1));
    const Index j = std::min<Index>(static_cast<Index>(std::floor(s)), ns - 2 >= 0 ? ns - 2 : 0);
    const double t = ns > 1 ? s - static_cast<double>(j) : 0.0;
    const Eigen::RowVector3d v =
        ns > 1 ? Eigen::RowVector3d((1.0 - t) * cu.row(j) + t * cu.row(j + 1)) : Eigen::RowVector3d(cu.row(0));
    const double n = v.norm();
    u.row(i) = n > 0.0 ? Eigen::RowVector3d(v / n) : Eigen::RowVector3d(cu.row(j));
  }
  return u;
}

Eigen::VectorXd axis_angles(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  Eigen::VectorXd out(a.rows());
  for (Index i = 0; i < a.rows(); ++i) {
    // atan2 of |a x b| and a . b: accurate for the micro-radian angles acos loses.
    const Eigen::Vector3d x = a.row(i).transpose(), y = b.row(i).transpose();
    out[i] = std::atan2(x.cross(y).norm(), x.dot(y));
  }
  return out;
}

FootPoints find_foot_points(const Eigen::MatrixXd& pc, const Eigen::MatrixXd& pe, int buffer_samples) {
  const Index ns = pc.rows(), rows = pe.rows();
  if (ns < 2 || pc.cols() != 3 || pe.cols() != 3 || rows < 1)
    throw core::Error("contour prediction: the command path needs 2 or more 3-D points, the prediction 1 or more");
  // The buffer's half length n (the predictive-compensation paper Fig. 8: m = 2n + 1 command points centred on the
  // actual point's own instant). Automatic: the largest lag of a predicted point behind its command point, in command
  // steps, x3 + 10.
  int n = (buffer_samples - 1) / 2;
  if (buffer_samples <= 0) {
    std::vector<double> steps;
    for (Index j = 1; j < ns; ++j) {
      const double d = (pc.row(j) - pc.row(j - 1)).norm();
      if (d > 0.0) steps.push_back(d);
    }
    double h = 1.0;
    if (!steps.empty()) {
      std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
      h = steps[steps.size() / 2];
    }
    double dmax = 0.0;
    for (Index i = 0; i < rows; ++i) dmax = std::max(dmax, (pc.row(std::min(i, ns - 1)) - pe.row(i)).norm());
    n = static_cast<int>(std::min<double>(static_cast<double>(ns), std::ceil(3.0 * dmax / h) + 10.0));
  }
  n = std::max(n, 1);
  FootPoints fp;
  fp.buffer_samples = 2 * n + 1;
  fp.error.resize(rows, 3);
  fp.norm_mm.resize(rows);
  fp.parameter.resize(rows);
  for (Index i = 0; i < rows; ++i) {
    const Eigen::Vector3d p = pe.row(i).transpose();
    const Index c = std::min(i, ns - 1);
    const Index lo = std::max<Index>(0, c - n), hi = std::min<Index>(ns - 1, c + n);
    // First search: the nearest command point in the buffer.
    Index r = lo;
    double best = (pc.row(lo).transpose() - p).squaredNorm();
    for (Index j = lo + 1; j <= hi; ++j) {
      const double d = (pc.row(j).transpose() - p).squaredNorm();
      if (d < best) {
        best = d;
        r = j;
      }
    }
    // Second search (eq. 18-22): the foot on the adjacent segment Pc_r Pc_r+1 or Pc_r Pc_r-1 nearer to the point
    // (the angle-bisector rule of Fig. 9 picks the same side); coincident points leave Pc_r itself.
    Eigen::Vector3d foot = pc.row(r).transpose();
    double param = static_cast<double>(r), dist2 = best;
    for (const Index s : {r, r - 1}) {
      if (s < 0 || s + 1 >= ns) continue;
      const Eigen::Vector3d a = pc.row(s).transpose(), b = pc.row(s + 1).transpose();
      const Eigen::Vector3d ab = b - a;
      const double l2 = ab.squaredNorm();
      if (!(l2 > 0.0)) continue;
      const double t = std::clamp((p - a).dot(ab) / l2, 0.0, 1.0);
      const Eigen::Vector3d f = a + t * ab;
      const double d2 = (p - f).squaredNorm();
      if (d2 < dist2) {
        dist2 = d2;
        foot = f;
        param = static_cast<double>(s) + t;
      }
    }
    fp.error.row(i) = (foot - p).transpose();
    fp.norm_mm[i] = std::sqrt(dist2);
    fp.parameter[i] = param;
  }
  return fp;
}

namespace {

// Eq. 23's "interpolation point at the corresponding position": the error vectors, known at the feet's places on the
// path, carried to each command sample by linear interpolation along the path parameter; samples no foot passes
// (stops) take the nearest assigned value.
Eigen::MatrixXd correction_at_commands(const Eigen::MatrixXd& error, const Eigen::VectorXd& parameter, Index ns) {
  Eigen::MatrixXd delta = Eigen::MatrixXd::Zero(ns, error.cols());
  std::vector<char> set(static_cast<std::size_t>(ns), 0);
  const Index rows = parameter.size();
  for (Index i = 0; i + 1 < rows; ++i) {
    const double s0 = parameter[i], s1 = parameter[i + 1];
    if (!(s1 > s0)) continue;
    const Index j0 = static_cast<Index>(std::ceil(s0)),
                j1 = std::min<Index>(static_cast<Index>(std::floor(s1)), ns - 1);
    for (Index j = std::max<Index>(j0, 0); j <= j1; ++j) {
      const double w = (static_cast<double>(j) - s0) / (s1 - s0);
      delta.row(j) = (1.0 - w) * error.row(i) + w * error.row(i + 1);
      set[static_cast<std::size_t>(j)] = 1;
    }
  }
  Index first = -1, last = -1;
  for (Index j = 0; j < ns; ++j) {
    if (set[static_cast<std::size_t>(j)]) {
      if (first < 0) first = j;
      last = j;
    } else if (last >= 0) {
      delta.row(j) = delta.row(last);
    }
  }
  for (Index j = 0; j < first; ++j) delta.row(j) = delta.row(first);
  return delta;
}

// Zero-phase Gaussian smoothing along the rows (weights renormalised at the ends, where the kernel is cut).
Eigen::MatrixXd smooth_rows(const Eigen::MatrixXd& x, double sigma) {
  if (!(sigma > 0.0) || x.rows() < 3) return x;
  const Index half = static_cast<Index>(std::ceil(4.0 * sigma)), n = x.rows();
  std::vector<double> w(static_cast<std::size_t>(2 * half + 1));
  for (Index i = -half; i <= half; ++i)
    w[static_cast<std::size_t>(i + half)] = std::exp(-0.5 * (i / sigma) * (i / sigma));
  Eigen::MatrixXd y(n, x.cols());
  for (Index k = 0; k < n; ++k) {
    double ws = 0.0;
    Eigen::RowVectorXd acc = Eigen::RowVectorXd::Zero(x.cols());
    for (Index i = std::max<Index>(-half, -k); i <= std::min<Index>(half, n - 1 - k); ++i) {
      const double wi = w[static_cast<std::size_t>(i + half)];
      acc += wi * x.row(k + i);
      ws += wi;
    }
    y.row(k) = acc / ws;
  }
  return y;
}

// Per setpoint: does some axis break its velocity, acceleration or jerk limit there (backward differences ending at
// the sample, at rest before the first and after the last, as core::finite_difference_peaks; relative margin 1e-6)?
// Rows n .. n + 2 (the axes coming to rest after the last setpoint) are reported on the last row.
std::vector<char> limit_breaks(const Eigen::MatrixXd& sp, double te, const core::Machine& machine) {
  const Index n = sp.rows();
  std::vector<char> out(static_cast<std::size_t>(n), 0);
  for (Index a = 0; a < sp.cols() && a < static_cast<Index>(machine.axes.size()); ++a) {
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(a)];
    auto x = [&](Index k) { return sp(std::clamp<Index>(k, 0, n - 1), a); };
    const double m = 1.0 + 1e-6;
    for (Index k = 1; k < n + 3; ++k) {
      const double v = std::abs(x(k) - x(k - 1)) / te;
      const double acc = std::abs(x(k) - 2 * x(k - 1) + x(k - 2)) / (te * te);
      const double j = std::abs(x(k) - 3 * x(k - 1) + 3 * x(k - 2) - x(k - 3)) / (te * te * te);
      if (v > ax.max_velocity * m || acc > ax.max_acceleration * m || j > ax.max_jerk * m)
        out[static_cast<std::size_t>(std::min(k, n - 1))] = 1;
    }
  }
  return out;
}

Eigen::MatrixXd checked_prediction(const CompensationProblem& p, const Eigen::MatrixXd& c) {
  Eigen::MatrixXd pred = p.predict(c);
  if (pred.rows() < c.rows() || pred.cols() != c.cols() || !pred.allFinite())
    throw core::Error(
        fmt::format("compensation: the prediction gave {} x {} positions for {} x {} setpoints (or a "
                    "non-finite one)",
                    pred.rows(), pred.cols(), c.rows(), c.cols()));
  return pred;
}

}  // namespace

CompensationResult compensate_contour(const CompensationProblem& p, const CompensateOptions& options) {
  if (!p.setpoints || !p.kinematics || !p.predict) throw core::Error("compensation: incomplete problem");
  const Eigen::MatrixXd& c0 = p.setpoints->position;
  const Index ns = c0.rows();
  if (ns < 2) throw core::Error("compensation: fewer than 2 setpoints");
  const Eigen::VectorXd tlo = p.tool_length_offset_mm.size() > 0 ? p.tool_length_offset_mm : Eigen::VectorXd::Zero(1);
  const motion::Kinematics& kin = *p.kinematics;
  const bool orient = options.orientation && kin.family() != motion::KinematicFamily::Cartesian;

  CompensationResult out;
  out.orientation = orient;
  out.command_tip = tool_tips(kin, c0, tlo);
  out.command_axis = tool_axes(kin, c0, tlo);
  Eigen::MatrixXd c = c0;
  Eigen::MatrixXd pred = checked_prediction(p, c);

  // One prediction's errors: the tip's contour error (the predictive-compensation paper's two-step search) and, on
  // five-axis chains, the tool axis' error against the commanded axis at the same foot point (commanded minus actual:
  // the correction's sign).
  struct Errors {
    FootPoints fp;
    Eigen::MatrixXd axis_error;  // rows x 3 (empty without orientation)
    Eigen::VectorXd angle_rad;   // rows
    CompensationIteration rec;
  };
  auto errors_of = [&](const Eigen::MatrixXd& predicted, int buffer) {
    Errors e;
    e.fp = find_foot_points(out.command_tip, tool_tips(kin, predicted, tlo), buffer);
    e.rec.max_mm = e.fp.norm_mm.maxCoeff();
    e.rec.mean_mm = e.fp.norm_mm.mean();
    if (orient) {
      const Eigen::MatrixXd ua = tool_axes(kin, predicted, tlo);
      const Eigen::MatrixXd uc = axes_at(out.command_axis, e.fp.parameter);
      e.axis_error = uc - ua;
      e.angle_rad = axis_angles(uc, ua);
      e.rec.orientation_max_rad = e.angle_rad.maxCoeff();
      e.rec.orientation_mean_rad = e.angle_rad.mean();
    }
    return e;
  };
  Errors err = errors_of(pred, options.buffer_samples);
  out.buffer_samples = err.fp.buffer_samples;
  out.predicted_before = pred;
  err.rec.accepted = true;
  out.iterations.push_back(err.rec);
  out.setpoints = c;
  out.predicted_after = pred;

  // Setpoints c moved by w(j) delta(j): the tool tip by delta's first three columns, and on five-axis chains the tool
  // axis by the last three (renormalised), through the chain's inverse of the corrected pose near the original joints.
  const Index dc = orient ? 6 : 3;
  auto corrected = [&](const Eigen::MatrixXd& c_now, const Eigen::MatrixXd& delta, const Eigen::VectorXd& w) {
    Eigen::MatrixXd next(ns, c_now.cols());
    Eigen::VectorXd q(c_now.cols());
    for (Index j = 0; j < ns; ++j) {
      q = c_now.row(j).transpose();
      const double l = tlo[std::min(j, tlo.size() - 1)];
      motion::ToolPose pose = kin.forward(q, l);
      pose.tip_mm += w[j] * delta.row(j).head<3>().transpose();
      if (orient) pose.axis = (pose.axis + w[j] * delta.row(j).tail<3>().transpose()).normalized();
      next.row(j) = kin.inverse(pose, l, q).transpose();
    }
    return next;
  };
  auto wanted_now = [&](const Errors& e) {
    Eigen::MatrixXd err_rows(e.fp.error.rows(), dc);
    err_rows.leftCols(3) = e.fp.error;
    if (orient) err_rows.rightCols(3) = e.axis_error;
    return smooth_rows(correction_at_commands(err_rows, e.fp.parameter, ns), options.smoothing_samples);
  };
  // Limits the original setpoints already break are not the compensation's to keep.
  const std::vector<char> broken_before =
      options.limits ? limit_breaks(c0, p.setpoints->period_s, *options.limits) : std::vector<char>();
  // The correction is kept whole, as the pose offset of the original setpoints (eq. 23's Pc -> Pn): each iteration
  // adds the error its prediction still shows, and the limits fade the whole offset back towards the original
  // setpoints, which keep them.
  Eigen::MatrixXd total = Eigen::MatrixXd::Zero(ns, dc);
  for (int it = 0; it < options.max_iterations; ++it) {
    const Eigen::MatrixXd wanted = total + wanted_now(err);
    Eigen::VectorXd w = Eigen::VectorXd::Ones(ns);
    Eigen::MatrixXd next = corrected(c0, wanted, w);
    int faded = 0;
    if (options.limits) {
      // Fade the correction where it breaks a limit: halve the weight over a window around each such sample, smooth
      // the weights (a gradual fade adds little jerk of its own), retry, widening the window every fourth pass.
      Index win = std::max(1, options.limit_window_samples);
      Eigen::VectorXd r = Eigen::VectorXd::Ones(ns);
      for (int pass = 0; pass < options.limit_passes; ++pass) {
        const std::vector<char> br = limit_breaks(next, p.setpoints->period_s, *options.limits);
        bool any = false;
        std::vector<char> mark(static_cast<std::size_t>(ns), 0);
        for (Index k = 0; k < ns; ++k) {
          if (!br[static_cast<std::size_t>(k)] || broken_before[static_cast<std::size_t>(k)]) continue;
          any = true;
          for (Index j = std::max<Index>(0, k - win); j <= std::min(ns - 1, k + win); ++j)
            mark[static_cast<std::size_t>(j)] = 1;
        }
        if (!any) break;
        for (Index j = 0; j < ns; ++j)
          if (mark[static_cast<std::size_t>(j)]) r[j] *= 0.5;
        w = smooth_rows(r, 0.5 * static_cast<double>(win));
        next = corrected(c0, wanted, w);
        if (pass % 4 == 3) win *= 2;
      }
      for (Index j = 0; j < ns; ++j) faded += w[j] < 1.0 - 1e-12 ? 1 : 0;
    }
    const Eigen::MatrixXd next_pred = checked_prediction(p, next);
    Errors next_err = errors_of(next_pred, out.buffer_samples);
    CompensationIteration rec = next_err.rec;
    rec.faded_samples = faded;
    const CompensationIteration& best = out.iterations[static_cast<std::size_t>(it)].accepted
                                            ? out.iterations[static_cast<std::size_t>(it)]
                                            : out.iterations.front();
    // Accepted when the mean falls and the maximum does not grow (the predictive-compensation paper reports both), and
    // on five-axis chains when the mean orientation error does not grow either.
    rec.accepted = rec.mean_mm < best.mean_mm && rec.max_mm <= best.max_mm &&
                   (!orient || rec.orientation_mean_rad <= best.orientation_mean_rad);
    out.iterations.push_back(rec);
    if (!rec.accepted) break;
    const double gain = (best.mean_mm - rec.mean_mm) / std::max(best.mean_mm, 1e-300);
    total = w.asDiagonal() * wanted;
    c = next;
    err = std::move(next_err);
    out.setpoints = c;
    out.predicted_after = next_pred;
    if (gain < options.min_improvement) break;
  }
  return out;
}

std::vector<AxisLimitCheck> check_axis_limits(const Eigen::MatrixXd& sp, double te, const core::Machine& machine) {
  std::vector<AxisLimitCheck> out;
  const Index n = sp.rows();
  for (Index a = 0; a < sp.cols() && a < static_cast<Index>(machine.axes.size()); ++a) {
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(a)];
    AxisLimitCheck r;
    r.axis = ax.name;
    r.limit_velocity = ax.max_velocity;
    r.limit_acceleration = ax.max_acceleration;
    r.limit_jerk = ax.max_jerk;
    // At rest before the first sample and after the last (3 held samples each way).
    auto x = [&](Index k) { return sp(std::clamp<Index>(k, 0, n - 1), a); };
    for (Index k = 0; k < n + 3; ++k) {
      const double v = (x(k) - x(k - 1)) / te;
      const double v1 = (x(k - 1) - x(k - 2)) / te, v2 = (x(k - 2) - x(k - 3)) / te;
      const double acc = (v - v1) / te, acc1 = (v1 - v2) / te;
      const double j = (acc - acc1) / te;
      r.peak_velocity = std::max(r.peak_velocity, std::abs(v));
      r.peak_acceleration = std::max(r.peak_acceleration, std::abs(acc));
      r.peak_jerk = std::max(r.peak_jerk, std::abs(j));
      const double m = 1.0 + 1e-6;
      if (std::abs(v) > ax.max_velocity * m || std::abs(acc) > ax.max_acceleration * m ||
          std::abs(j) > ax.max_jerk * m) {
        if (r.samples_over == 0) r.first_over_s = static_cast<double>(std::min(k, n - 1)) * te;
        ++r.samples_over;
      }
    }
    out.push_back(r);
  }
  return out;
}

}  // namespace vmsim::methods
