// Friction and inertia identification (the feed-drive simulation paper section 3.1): see identify.hpp for the model and
// the method.
#include "sysid/friction_inertia.hpp"

#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <Eigen/Dense>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace vmsim::sysid {

AxisTrace read_axis_trace_csv(const std::filesystem::path& path, std::vector<std::string>* ignored) {
  core::CsvReader in(path);
  const std::string& file = in.name();
  if (!in.has_header())
    throw core::Error(
        core::located(file, 0, "no header row (expected t_s, current_A and a position or velocity column)"));
  const std::vector<std::string>& names = in.columns();
  const int line_no = in.header_line();

  static constexpr const char* kMotion[] = {"position_mm", "position_deg", "velocity_mm_per_s", "velocity_deg_per_s"};
  int col_t = -1, col_i = -1, col_m = -1, motion = -1;
  for (int c = 0; c < static_cast<int>(names.size()); ++c) {
    const std::string& n = names[c];
    if (n == "t_s") {
      col_t = c;
    } else if (n == "current_A") {
      col_i = c;
    } else {
      bool is_motion = false;
      for (int m = 0; m < 4; ++m)
        if (n == kMotion[m]) {
          if (col_m >= 0)
            throw core::Error(core::located(
                file, line_no, fmt::format("columns '{}' and '{}' both give the motion; keep one", names[col_m], n)));
          col_m = c, motion = m, is_motion = true;
        }
      if (!is_motion && ignored) ignored->push_back(n);
    }
  }
  auto missing = [&](const char* what) {
    return core::Error(core::located(
        file, line_no, fmt::format("the header has no {} column (found: {})", what, fmt::join(names, ", "))));
  };
  if (col_t < 0) throw missing("t_s");
  if (col_i < 0) throw missing("current_A");
  if (col_m < 0) throw missing("position_mm, position_deg, velocity_mm_per_s or velocity_deg_per_s");

  AxisTrace tr;
  tr.source = file;
  tr.rotary = motion == 1 || motion == 3;
  const double unit = tr.rotary ? core::units::kDegToRad : 1.0;
  std::vector<double> t, m, cur;
  while (in.next()) {
    const double tv = in.number(static_cast<std::size_t>(col_t));
    if (!t.empty() && !(tv > t.back()))
      throw in.error(fmt::format("column {} 't_s': {} does not increase (previous row: {})", col_t + 1, tv, t.back()));
    t.push_back(tv);
    m.push_back(in.number(static_cast<std::size_t>(col_m)) * unit);
    cur.push_back(in.number(static_cast<std::size_t>(col_i)));
  }
  if (t.size() < 3)
    throw core::Error(core::located(file, 0, fmt::format("only {} data rows; a trace needs many more", t.size())));
  const auto n = static_cast<Eigen::Index>(t.size());
  tr.t_s = Eigen::Map<Eigen::ArrayXd>(t.data(), n);
  tr.current_A = Eigen::Map<Eigen::ArrayXd>(cur.data(), n);
  if (motion <= 1)
    tr.position = Eigen::Map<Eigen::ArrayXd>(m.data(), n);
  else
    tr.velocity = Eigen::Map<Eigen::ArrayXd>(m.data(), n);
  return tr;
}

namespace {

// Running trapezoidal integral of f over t: P[k] = integral from t_0 to t_k. The mean of f over [t_a, t_b] is
// (P[b] - P[a]) / (t_b - t_a).
Eigen::ArrayXd running_integral(const Eigen::ArrayXd& t, const Eigen::ArrayXd& f) {
  Eigen::ArrayXd p(t.size());
  p[0] = 0.0;
  for (Eigen::Index k = 1; k < t.size(); ++k) p[k] = p[k - 1] + 0.5 * (f[k] + f[k - 1]) * (t[k] - t[k - 1]);
  return p;
}

using NanArray = Eigen::ArrayXd;  // NaN where a smoothed signal is undefined (near the ends)

// Mean of f over [t_{k-h}, t_{k+h}] for k in [lo + h, hi - h], f being defined on [lo, hi]; NaN elsewhere.
NanArray box(const Eigen::ArrayXd& t, const Eigen::ArrayXd& f, Eigen::Index lo, Eigen::Index hi, Eigen::Index h) {
  NanArray g = NanArray::Constant(t.size(), std::numeric_limits<double>::quiet_NaN());
  if (hi - lo < 2 * h) return g;
  Eigen::ArrayXd p(hi - lo + 1);  // running trapezoidal integral from t_lo
  p[0] = 0.0;
  for (Eigen::Index k = lo + 1; k <= hi; ++k) p[k - lo] = p[k - lo - 1] + 0.5 * (f[k] + f[k - 1]) * (t[k] - t[k - 1]);
  for (Eigen::Index k = lo + h; k <= hi - h; ++k) g[k] = (p[k + h - lo] - p[k - h - lo]) / (t[k + h] - t[k - h]);
  return g;
}

// A constant-velocity stretch before fitting: its regressors and measured means.
struct Stretch {
  Eigen::Index a = 0, b = 0;
  double sign = 0.0, v = 0.0, acc = 0.0, i = 0.0, sin_x = 0.0, cos_x = 0.0;
};

}  // namespace

const char* gravity_model_name(GravityModel g) {
  switch (g) {
    case GravityModel::Auto:
      return "auto";
    case GravityModel::None:
      return "none";
    case GravityModel::Constant:
      return "constant";
    case GravityModel::Tilting:
      return "tilting";
  }
  return "?";
}

IdentifiedDrive identify_friction_inertia(const AxisTrace& tr, const IdentifyOptions& o) {
  const std::string& src = tr.source.empty() ? std::string("trace") : tr.source;
  auto fail = [&](const std::string& msg) { return core::Error(core::located(src, 0, msg)); };
  const double kt = o.torque_constant_Nm_per_A, r = o.axis_per_motor_rad;
  if (!(kt > 0.0 && std::isfinite(kt))) throw fail(fmt::format("the torque constant must be positive, found {}", kt));
  if (!(r > 0.0 && std::isfinite(r)))
    throw fail(fmt::format("the screw lead or gear ratio must be positive, found {} axis units per motor rad", r));
  if (!(o.smoothing_s > 0.0 && std::isfinite(o.smoothing_s)))
    throw fail(fmt::format("the smoothing window must be positive, found {} s", o.smoothing_s));
  if (!(o.steady_accel_fraction > 0.0 && o.steady_accel_fraction < o.accel_fraction && o.accel_fraction < 1.0))
    throw fail("expected 0 < steady_accel_fraction < accel_fraction < 1");
  if (!(o.min_speed_fraction >= 0.0 && o.min_speed_fraction < 1.0)) throw fail("expected 0 <= min_speed_fraction < 1");
  if (!(o.min_stretch_s > 0.0 && o.trim_s >= 0.0)) throw fail("expected min_stretch_s > 0 and trim_s >= 0");

  const Eigen::ArrayXd& t = tr.t_s;
  const Eigen::Index n = t.size();
  const bool has_pos = tr.position.size() == n && n > 0;
  if (tr.current_A.size() != n || (!has_pos && tr.velocity.size() != n))
    throw fail("the trace's columns have different lengths");
  if (n < 3) throw fail(fmt::format("{} samples: far too few", n));
  for (Eigen::Index k = 1; k < n; ++k)
    if (!(t[k] > t[k - 1])) throw fail(fmt::format("t_s does not increase at sample {}", k));
  // Half-width of the smoothing window in samples, from the median sample period.
  Eigen::Index h = 1;
  {
    std::vector<double> dt(static_cast<std::size_t>(n - 1));
    for (Eigen::Index k = 1; k < n; ++k) dt[k - 1] = t[k] - t[k - 1];
    std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
    h = std::max<Eigen::Index>(1, std::llround(o.smoothing_s / (2.0 * dt[dt.size() / 2])));
  }
  if (n < 4 * h + 3)
    throw fail(
        fmt::format("{} samples: too few for a smoothing window of {} samples ({} s)", n, 2 * h + 1, o.smoothing_s));

  // Smoothing (identify.hpp): V = the mean velocity over [t_{k-h}, t_{k+h}] (from positions exactly: their
  // difference over the window), A = (V_{k+h} - V_{k-h}) / (t_{k+h} - t_{k-h}), the acceleration averaged by the
  // window twice. Every other signal entering eq. 1 is averaged twice by the same window (box2), so the equation
  // holds for the smoothed signals as it does for the raw ones.
  const NanArray nan = NanArray::Constant(n, std::numeric_limits<double>::quiet_NaN());
  NanArray V = nan;
  if (has_pos) {
    const Eigen::ArrayXd& x = tr.position;
    for (Eigen::Index k = h; k + h < n; ++k) V[k] = (x[k + h] - x[k - h]) / (t[k + h] - t[k - h]);
  } else {
    V = box(t, tr.velocity, 0, n - 1, h);
  }
  NanArray A = nan;
  for (Eigen::Index k = 2 * h; k + 2 * h < n; ++k) A[k] = (V[k + h] - V[k - h]) / (t[k + h] - t[k - h]);
  auto box2 = [&](const Eigen::ArrayXd& f) { return box(t, box(t, f, 0, n - 1, h), h, n - 1 - h, h); };
  const NanArray I2 = box2(tr.current_A);
  const NanArray V2 = box(t, V, h, n - 1 - h, h);
  NanArray S2, C2;
  if (has_pos) S2 = box2(tr.position.sin()), C2 = box2(tr.position.cos());
  const Eigen::Index lo = 2 * h, hi = n - 1 - 2 * h;  // where A and the twice-smoothed signals exist

  IdentifiedDrive out;
  for (Eigen::Index k = lo; k <= hi; ++k) {
    out.peak_velocity = std::max(out.peak_velocity, std::abs(V[k]));
    out.peak_acceleration = std::max(out.peak_acceleration, std::abs(A[k]));
  }
  if (!(out.peak_velocity > 0.0)) throw fail("the axis never moves");
  const double v_min = o.min_speed_fraction * out.peak_velocity;
  const double a_steady = o.steady_accel_fraction * out.peak_acceleration;
  const double a_moving = o.accel_fraction * out.peak_acceleration;

  // Running integrals of the raw signals for the stretch means.
  const Eigen::ArrayXd P_i = running_integral(t, tr.current_A);
  const Eigen::ArrayXd P_v = has_pos ? Eigen::ArrayXd() : running_integral(t, tr.velocity);
  Eigen::ArrayXd P_s, P_c;
  if (has_pos) P_s = running_integral(t, tr.position.sin()), P_c = running_integral(t, tr.position.cos());
  auto mean = [&](const Eigen::ArrayXd& p, Eigen::Index a, Eigen::Index b) { return (p[b] - p[a]) / (t[b] - t[a]); };

  // (a) Constant-velocity stretches: runs of samples with small smoothed acceleration, one sign of velocity and a
  // speed above v_min, trimmed at both ends. Their means are taken over the raw samples.
  std::vector<Stretch> stretches;
  {
    auto steady = [&](Eigen::Index j) { return std::abs(A[j]) <= a_steady && std::abs(V[j]) >= v_min; };
    Eigen::Index k = lo;
    while (k <= hi) {
      if (!steady(k)) {
        ++k;
        continue;
      }
      const double sign = V[k] > 0.0 ? 1.0 : -1.0;
      Eigen::Index e = k;
      while (e + 1 <= hi && steady(e + 1) && V[e + 1] * sign > 0.0) ++e;
      Eigen::Index a = k, b = e;
      while (a < b && t[a] < t[k] + o.trim_s) ++a;
      while (b > a && t[b] > t[e] - o.trim_s) --b;
      if (t[b] - t[a] >= o.min_stretch_s) {
        Stretch s;
        s.a = a, s.b = b, s.sign = sign;
        s.v = has_pos ? (tr.position[b] - tr.position[a]) / (t[b] - t[a]) : mean(P_v, a, b);
        s.acc = (V[b] - V[a]) / (t[b] - t[a]);
        s.i = mean(P_i, a, b);
        if (has_pos) s.sin_x = mean(P_s, a, b), s.cos_x = mean(P_c, a, b);
        stretches.push_back(s);
      }
      k = e + 1;
    }
  }
  for (const Stretch& s : stretches) (s.sign > 0 ? out.stretches_positive : out.stretches_negative)++;
  out.stretches = static_cast<int>(stretches.size());
  const bool both_ways = out.stretches_positive > 0 && out.stretches_negative > 0;

  GravityModel g = o.gravity;
  if (g == GravityModel::Auto) g = both_ways ? GravityModel::Constant : GravityModel::None;
  if (g == GravityModel::Tilting && !has_pos)
    throw fail("a tilting axis' gravity depends on the angle: the trace needs a position_deg column");
  if (g != GravityModel::None && !both_ways)
    throw fail(fmt::format(
        "gravity ({}) cannot be told from Coulomb friction with constant-velocity moves in one direction only "
        "({} positive, {} negative stretches): move the axis both ways, or fit without gravity",
        gravity_model_name(g), out.stretches_positive, out.stretches_negative));
  out.gravity = g;
  const int n_par = g == GravityModel::None ? 2 : g == GravityModel::Constant ? 3 : 4;
  if (out.stretches < n_par + 1)
    throw fail(
        fmt::format("{} constant-velocity stretches found (at least {} s long, |a| <= {:.4g}/s^2, |v| >= {:.4g}/s); "
                    "the fit needs at least {}: add constant-velocity moves at several speeds",
                    out.stretches, o.min_stretch_s, a_steady, v_min, n_par + 1));

  // (b) Accelerating samples: smoothed acceleration above a_moving, the velocity one-signed and above v_min over
  // the whole support of the smoothing (V at k - h .. k + h covers the raw samples k - 2h .. k + 2h).
  std::vector<Eigen::Index> accel;
  for (Eigen::Index k = lo; k <= hi; ++k) {
    if (std::abs(A[k]) < a_moving) continue;
    const double sign = V[k] > 0.0 ? 1.0 : -1.0;
    bool ok = true;
    for (Eigen::Index j = k - h; j <= k + h && ok; ++j) ok = V[j] * sign >= v_min && V[j] != 0.0;
    if (ok) accel.push_back(k);
  }
  out.accel_samples = static_cast<int>(accel.size());
  if (out.accel_samples < 10)
    throw fail(
        fmt::format("{} accelerating samples (|a| >= {:.4g}/s^2 away from zero speed): the inertia needs "
                    "accelerated moves",
                    out.accel_samples, a_moving));

  // Regressor row of the friction law (+ gravity) for sign, mean velocity, mean sin/cos of the position.
  auto row = [&](double sign, double vel, double sx, double cx) {
    Eigen::RowVectorXd r(n_par);
    r[0] = sign;
    r[1] = vel;
    if (g == GravityModel::Constant) r[2] = 1.0;
    if (g == GravityModel::Tilting) r[2] = sx, r[3] = cx;
    return r;
  };
  // The current eq. 2 attributes to inertia at accelerating sample k: smoothed current minus smoothed friction.
  auto inertial_current = [&](Eigen::Index k, const Eigen::VectorXd& theta) {
    const double sign = V[k] > 0.0 ? 1.0 : -1.0;
    const double sx = has_pos ? S2[k] : 0.0, cx = has_pos ? C2[k] : 0.0;
    return I2[k] - (row(sign, V2[k], sx, cx) * theta)(0);
  };

  // Friction and inertia depend on each other only through the small mean acceleration left in the stretches
  // (the loops settling): fit friction with J = 0, then J, then friction again with the stretches' J term
  // removed, and J again. Later rounds change the results by a small fraction of a per cent.
  Eigen::VectorXd theta;
  Eigen::MatrixXd cov;
  double J = 0.0;
  for (int round = 0; round < 3; ++round) {
    const auto m = static_cast<Eigen::Index>(stretches.size());
    Eigen::MatrixXd X(m, n_par);
    Eigen::VectorXd y(m);
    for (Eigen::Index s = 0; s < m; ++s) {
      const Stretch& st = stretches[s];
      X.row(s) = row(st.sign, st.v, st.sin_x, st.cos_x);
      y[s] = st.i - J * st.acc / (kt * r);
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(X);
    if (qr.rank() < n_par)
      throw fail(
          "the constant-velocity stretches do not determine the friction law (all at one speed?): move the "
          "axis at several speeds");
    theta = qr.solve(y);
    const Eigen::VectorXd res = y - X * theta;
    const double rss = res.squaredNorm();
    out.friction_rms_residual_A = std::sqrt(rss / static_cast<double>(m));
    cov = (X.transpose() * X).inverse() * (rss / static_cast<double>(std::max<Eigen::Index>(1, m - n_par)));
    out.points.clear();
    for (Eigen::Index s = 0; s < m; ++s) {
      const Stretch& st = stretches[s];
      FrictionPoint p;
      p.t_start_s = t[st.a];
      p.t_end_s = t[st.b];
      p.samples = static_cast<int>(st.b - st.a + 1);
      p.velocity = st.v;
      p.acceleration = st.acc;
      p.mean_current_A = y[s];
      p.fitted_current_A = (X.row(s) * theta)(0);
      out.points.push_back(p);
    }

    // Eq. 2 by least squares: Kt (i - i_friction) = J dw/dt, on the smoothed signals.
    double num = 0.0, den = 0.0;
    for (Eigen::Index k : accel) {
      const double alpha = A[k] / r;  // motor rad/s^2
      num += alpha * inertial_current(k, theta);
      den += alpha * alpha;
    }
    J = kt * num / den;
  }
  double rss_j = 0.0;
  for (Eigen::Index k : accel) {
    const double e = inertial_current(k, theta) - J * A[k] / (r * kt);
    rss_j += e * e;
  }
  out.inertia_rms_residual_A = std::sqrt(rss_j / static_cast<double>(accel.size()));
  out.inertia_kg_m2 = J;

  out.coulomb_A = theta[0];
  out.coulomb_Nm = kt * theta[0];
  out.viscous_A_s_per_axis_unit = theta[1];
  out.viscous_Nm_s_per_rad = kt * r * theta[1];
  if (g == GravityModel::Constant) {
    out.gravity_A = theta[2];
    out.gravity_Nm = kt * theta[2];
    out.gravity_stderr_Nm = kt * std::sqrt(cov(2, 2));
  } else if (g == GravityModel::Tilting) {
    // p sin x + q cos x = (G/Kt) sin(x - x0): p = (G/Kt) cos x0, q = -(G/Kt) sin x0.
    const double p = theta[2], q = theta[3], amp = std::hypot(p, q);
    out.gravity_A = amp;
    out.gravity_Nm = kt * amp;
    out.gravity_angle_offset_rad = std::atan2(-q, p);
    if (amp > 0.0) {
      const double var = (p * p * cov(2, 2) + q * q * cov(3, 3) + 2 * p * q * cov(2, 3)) / (amp * amp);
      out.gravity_stderr_Nm = kt * std::sqrt(std::max(0.0, var));
    }
  }
  return out;
}

}  // namespace vmsim::sysid
