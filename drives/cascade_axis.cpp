#include "drives/cascade_axis.hpp"

#include "core/error.hpp"

#include <Eigen/Core>
#include <fmt/format.h>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>

namespace vmsim::drives {

int whole_ratio(double longer, double shorter, const char* what) {
  const double q = longer / shorter;
  const double n = std::round(q);
  if (!(n >= 1.0 && n <= 1e6 && std::abs(q - n) <= 1e-6 * n))
    throw core::Error(fmt::format("{}: {:g} us is not a whole multiple of {:g} us", what, longer * 1e6, shorter * 1e6));
  return static_cast<int>(n);
}

namespace {

void require_positive(double v, const char* name) {
  if (!(v > 0.0 && std::isfinite(v)))
    throw core::Error(fmt::format("{} must be positive and finite, found {}", name, v));
}

void require_nonnegative(double v, const char* name) {
  if (!(v >= 0.0 && std::isfinite(v)))
    throw core::Error(fmt::format("{} must be non-negative and finite, found {}", name, v));
}

}  // namespace

CascadeAxis::CascadeAxis(const core::DriveParams& p, double te_s, core::AxisKind kind)
    : params_(p), kind_(kind), te_(te_s) {
  require_positive(te_s, "position-loop period Te");
  require_positive(p.kv_per_s, "kv");
  require_nonnegative(p.kf, "kf");
  require_nonnegative(p.ka, "ka");
  require_positive(p.velocity_period_s, "velocity_loop_period");
  require_positive(p.velocity_kp_A_s_per_rad, "velocity_kp_A_s_per_rad");
  require_positive(p.velocity_tn_s, "velocity_tn");
  require_positive(p.current_limit_A, "current_limit_A");
  require_positive(p.current_period_s, "current_loop_period");
  require_positive(p.current_kp_V_per_A, "current_kp_V_per_A");
  require_positive(p.current_tn_s, "current_tn");
  require_positive(p.resistance_ohm, "resistance_ohm");
  require_positive(p.inductance_H, "inductance");
  require_positive(p.torque_constant_Nm_per_A, "torque_constant_Nm_per_A");
  require_positive(p.voltage_limit_V, "voltage_limit_V");
  require_positive(p.inertia_kg_m2, "inertia_kg_m2");
  require_nonnegative(p.coulomb_Nm, "coulomb_friction_Nm");
  require_nonnegative(p.viscous_Nm_s_per_rad, "viscous_friction_Nm_s_per_rad");
  require_nonnegative(p.stribeck_static_Nm, "stribeck_static_Nm");
  if (p.stribeck_static_Nm > 0.0) require_positive(p.stribeck_velocity_rad_per_s, "stribeck_velocity_rad_per_s");
  if (!(p.axis_per_motor_rad > 0.0 && std::isfinite(p.axis_per_motor_rad)))
    throw core::Error(fmt::format("axis_per_motor_rad must be positive, found {}", p.axis_per_motor_rad));
  if (p.gravity != core::DriveParams::Gravity::None && !std::isfinite(p.gravity_Nm))
    throw core::Error("gravity_torque_Nm must be finite");
  if (p.gravity == core::DriveParams::Gravity::Tilting && kind_ != core::AxisKind::Rotary)
    throw core::Error("tilting gravity needs a rotary axis (its angle gives the torque)");
  if (p.position_delay_samples < 0 || p.feedforward_delay_samples < 0) throw core::Error("delays must be >= 0 samples");

  current_per_te_ = whole_ratio(te_s, p.current_period_s, "position-loop period Te against the current loop");
  current_per_velocity_ = whole_ratio(p.velocity_period_s, p.current_period_s, "velocity_loop_period");
  if (current_per_te_ % current_per_velocity_ != 0)
    throw core::Error(
        fmt::format("position-loop period Te {:g} us is not a whole multiple of the velocity loop's {:g} us",
                    te_s * 1e6, p.velocity_period_s * 1e6));

  r_ = p.axis_per_motor_rad;
  inv_r_ = 1.0 / r_;
  // PI in parallel form u = Kp e + I, I advanced by the backward-Euler (rectangle) rule I += Kp T/Tn e before the
  // output is formed: C(z) = Kp (1 + (T/Tn) z/(z-1)).
  kpv_ = p.velocity_kp_A_s_per_rad;
  kiv_ = kpv_ * p.velocity_period_s / p.velocity_tn_s;
  kpc_ = p.current_kp_V_per_A;
  kic_ = kpc_ * p.current_period_s / p.current_tn_s;
  ff_current_per_accel_ = p.ka * p.inertia_kg_m2 / (p.torque_constant_Nm_per_A * r_);

  // Plant (the feed-drive simulation paper eq. 1 with the winding): L di/dt = u - R i - Ke w;  J dw/dt = Kt i - B w +
  // tau;  dx/dt = r w, Ke = Kt (SI). ZOH discretisation over Tc: exp([[A, B], [0, 0]] Tc) = [[Phi, Gamma], [0, I]].
  const double L = p.inductance_H, R = p.resistance_ohm, Kt = p.torque_constant_Nm_per_A, J = p.inertia_kg_m2;
  Eigen::Matrix<double, 5, 5> m = Eigen::Matrix<double, 5, 5>::Zero();
  m(0, 0) = -R / L;
  m(0, 1) = -Kt / L;
  m(1, 0) = Kt / J;
  m(1, 1) = -p.viscous_Nm_s_per_rad / J;
  m(2, 1) = r_;
  m(0, 3) = 1.0 / L;  // voltage
  m(1, 4) = 1.0 / J;  // load torque
  const Eigen::Matrix<double, 5, 5> e = (m * p.current_period_s).exp();
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) phi_[a][b] = e(a, b);
    gam_u_[a] = e(a, 3);
    gam_t_[a] = e(a, 4);
  }
  // The winding with the shaft stuck (w = 0): first order, exact.
  stuck_a_ = std::exp(-R * p.current_period_s / L);
  stuck_b_ = -std::expm1(-R * p.current_period_s / L) / R;

  friction_ = p.coulomb_Nm > 0.0 || p.stribeck_static_Nm > 0.0;
  breakaway_Nm_ = std::max(p.coulomb_Nm, p.stribeck_static_Nm);
  // Karnopp's zero-speed window: 1 % of the speed the breakaway torque alone changes in one current period. Small
  // against any motion the loops command, large enough that a speed decaying towards zero without crossing it
  // (the loop creeping onto its target against friction) ends stuck instead of sliding forever at 1e-12 rad/s.
  stick_window_ = 0.01 * breakaway_Nm_ * p.current_period_s / J;

  pos_line_.assign(static_cast<std::size_t>(p.position_delay_samples) + 1, 0.0);
  vel_line_.assign(static_cast<std::size_t>(p.feedforward_delay_samples) + 1, 0.0);
  acc_line_.assign(vel_line_.size(), 0.0);
  rest_at(0.0);
}

double CascadeAxis::gravity_torque() const {
  switch (params_.gravity) {
    case core::DriveParams::Gravity::None:
      return 0.0;
    case core::DriveParams::Gravity::Constant:
      return params_.gravity_Nm;
    case core::DriveParams::Gravity::Tilting:
      return params_.gravity_Nm * std::sin(x_ - params_.gravity_angle_offset_rad);
  }
  return 0.0;
}

// Friction magnitude while sliding at |w|: Coulomb, plus the Stribeck hump exp(-(w/ws)^2) towards the breakaway
// torque when one is given (the feed-drive simulation paper section 3.1 identifies the static Coulomb + viscous law;
// viscous is in Phi).
double CascadeAxis::friction_level(double abs_w) const {
  if (params_.stribeck_static_Nm <= 0.0) return params_.coulomb_Nm;
  const double q = abs_w / params_.stribeck_velocity_rad_per_s;
  return params_.coulomb_Nm + (params_.stribeck_static_Nm - params_.coulomb_Nm) * std::exp(-q * q);
}

void CascadeAxis::reset(double position) {
  x_ = position;
  const double hold = gravity_torque() / params_.torque_constant_Nm_per_A;
  if (!(std::abs(hold) <= params_.current_limit_A))
    throw core::Error(
        fmt::format("holding the gravity torque at position {:g} needs {:g} A, above the current limit "
                    "of {:g} A",
                    position, std::abs(hold), params_.current_limit_A));
  rest_at(position);
}

void CascadeAxis::rest_at(double position) {
  x_ = position;
  w_ = 0.0;
  // Holding the load: Kt i = gravity, and both integrators at the values that keep it there (zero errors).
  const double hold = gravity_torque() / params_.torque_constant_Nm_per_A;
  i_ = hold;
  iv_ = hold;
  iset_ = hold;
  ic_ = params_.resistance_ohm * hold;
  u_ = ic_;
  std::fill(pos_line_.begin(), pos_line_.end(), position);
  std::fill(vel_line_.begin(), vel_line_.end(), 0.0);
  std::fill(acc_line_.begin(), acc_line_.end(), 0.0);
  pos_head_ = ff_head_ = 0;
}

// Velocity PI (the feed-drive simulation paper Fig. 2), output saturated at the current limit. Anti-windup by
// conditional integration: the integrator is frozen while the output is saturated and the error pushes it further out.
// It needs no tuning parameter (back-calculation would need a tracking time the seeds do not give) and it keeps the
// integrator where it was when the limit was hit, so the axis leaves saturation without the overshoot an unbounded
// integrator gives. It is the common "integrator stop at the limit" of industrial speed controllers.
inline void CascadeAxis::velocity_loop(double w_cmd, double i_ff) {
  const double err = w_cmd - w_;
  const double integ = iv_ + kiv_ * err;
  const double out = kpv_ * err + integ + i_ff;
  const double lim = params_.current_limit_A;
  if (out > lim) {
    iset_ = lim;
    if (err < 0.0) iv_ = integ;
  } else if (out < -lim) {
    iset_ = -lim;
    if (err > 0.0) iv_ = integ;
  } else {
    iset_ = out;
    iv_ = integ;
  }
}

// Current PI on the winding, output saturated at the voltage limit, same anti-windup rule.
inline void CascadeAxis::current_loop() {
  const double err = iset_ - i_;
  const double integ = ic_ + kic_ * err;
  const double out = kpc_ * err + integ;
  const double lim = params_.voltage_limit_V;
  if (out > lim) {
    u_ = lim;
    if (err < 0.0) ic_ = integ;
  } else if (out < -lim) {
    u_ = -lim;
    if (err > 0.0) ic_ = integ;
  } else {
    u_ = out;
    ic_ = integ;
  }
}

// One current period of the plant with the voltage held. Friction (Karnopp's stick-slip model): at rest (w == 0)
// the shaft stays stuck while the driving torque |Kt i - gravity| does not exceed the breakaway torque, and only
// the winding evolves; sliding, the friction torque opposes the motion; when the speed would change sign within the
// period, friction stops the shaft there (w = 0) and the next period decides between sticking and breaking away.
// Without friction the shaft is never treated as stuck: the step is the exact linear one.
inline void CascadeAxis::plant(double u) {
  double tau = -gravity_torque();
  double dir = 0.0;  // direction of the friction torque's opposition (the sliding direction), 0: none
  if (friction_) {
    if (w_ == 0.0) {
      const double drive = params_.torque_constant_Nm_per_A * i_ + tau;
      if (std::abs(drive) <= breakaway_Nm_) {
        i_ = stuck_a_ * i_ + stuck_b_ * u;
        return;
      }
      dir = drive > 0.0 ? 1.0 : -1.0;
      tau -= dir * breakaway_Nm_;
    } else {
      dir = w_ > 0.0 ? 1.0 : -1.0;
      tau -= dir * friction_level(std::abs(w_));
    }
  }
  const double i0 = i_, w0 = w_;
  i_ = phi_[0][0] * i0 + phi_[0][1] * w0 + gam_u_[0] * u + gam_t_[0] * tau;
  w_ = phi_[1][0] * i0 + phi_[1][1] * w0 + gam_u_[1] * u + gam_t_[1] * tau;
  x_ += phi_[2][0] * i0 + phi_[2][1] * w0 + gam_u_[2] * u + gam_t_[2] * tau;
  // Friction cannot reverse the motion: when the speed changes sign, or has decayed into Karnopp's small window
  // around zero while the driving torque cannot break the shaft loose, the shaft stops (sticks) here.
  if (dir * w_ < 0.0) {
    w_ = 0.0;
  } else if (std::abs(w_) < stick_window_ &&
             std::abs(params_.torque_constant_Nm_per_A * i_ - gravity_torque()) <= breakaway_Nm_) {
    w_ = 0.0;
  }
}

template <bool kTrace>
AxisSample CascadeAxis::advance(const AxisCommand& c, InnerSample* trace) {
  const double kv = std::isnan(c.kv_per_s) ? params_.kv_per_s : c.kv_per_s;
  const double kf = std::isnan(c.kf) ? params_.kf : c.kf;
  // Delay lines: write the new command, read the one received `delay` samples ago (the feed-drive simulation paper
  // section 2.2).
  const int pos_n = static_cast<int>(pos_line_.size()), ff_n = static_cast<int>(vel_line_.size());
  pos_line_[pos_head_] = c.position;
  pos_head_ = pos_head_ + 1 == pos_n ? 0 : pos_head_ + 1;
  const double xd = pos_line_[pos_head_];
  vel_line_[ff_head_] = c.velocity;
  acc_line_[ff_head_] = c.acceleration;
  ff_head_ = ff_head_ + 1 == ff_n ? 0 : ff_head_ + 1;
  const double vd = vel_line_[ff_head_], ad = acc_line_[ff_head_];

  // Position loop (Duong et al. Fig. 6, the feed-drive simulation paper Fig. 2): v_cmd = Kv (x_d - x) + KF v_d in axis
  // units/s, to motor rad/s through the screw lead or gear; torque feedforward KA J a_d as a current (Kt i = J dw/dt).
  const double w_cmd = (kv * (xd - x_) + kf * vd) * inv_r_;
  const double i_ff = ff_current_per_accel_ * ad;
  const double w_start = w_;
  int n = 0;
  double i_sum = 0.0, i_peak = 0.0;
  for (int v = 0; v < current_per_te_; v += current_per_velocity_) {
    velocity_loop(w_cmd, i_ff);
    for (int k = 0; k < current_per_velocity_; ++k, ++n) {
      current_loop();
      if constexpr (kTrace) trace[n] = InnerSample{x_, r_ * w_, i_, iset_, u_};
      plant(u_);
      i_sum += i_;
      i_peak = std::max(i_peak, std::abs(i_));
    }
  }
  AxisSample s = sample();
  s.current_mean_A = i_sum / n;
  s.current_peak_A = i_peak;
  // Mean acceleration over the period just ended (the backward difference of the exact speeds), so that jerk by
  // differencing follows the same convention as the setpoints' finite differences.
  s.acceleration = r_ * (w_ - w_start) / te_;
  return s;
}

AxisSample CascadeAxis::step(const AxisCommand& command) { return advance<false>(command, nullptr); }

AxisSample CascadeAxis::step(const AxisCommand& command, InnerSample* trace) {
  return trace ? advance<true>(command, trace) : advance<false>(command, nullptr);
}

AxisSample CascadeAxis::sample() const {
  AxisSample s;
  s.position = x_;
  s.velocity = r_ * w_;
  s.acceleration = 0.0;
  s.current_A = i_;
  s.current_mean_A = i_;
  s.current_peak_A = std::abs(i_);
  s.current_setpoint_A = iset_;
  return s;
}

InnerSample CascadeAxis::inner_sample() const { return InnerSample{x_, r_ * w_, i_, iset_, u_}; }

std::unique_ptr<AxisModel> CascadeAxis::clone() const { return std::make_unique<CascadeAxis>(*this); }

std::unique_ptr<AxisModel> make_cascade_axis(const core::DriveParams& params, double te_s, core::AxisKind kind) {
  return std::make_unique<CascadeAxis>(params, te_s, kind);
}

}  // namespace vmsim::drives
