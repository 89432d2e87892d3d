#include "drives/linear_model.hpp"

#include "core/error.hpp"
#include "drives/cascade_axis.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <fmt/format.h>
#include <unsupported/Eigen/MatrixFunctions>

#include <cmath>

namespace vmsim::drives {

namespace {

using cd = std::complex<double>;

// Zero-order hold followed by sampling, aliasing neglected: (1 - e^{-sT}) / (sT), 1 at DC.
cd zoh(cd s, double T) {
  const cd sT = s * T;
  if (std::abs(sT) < 1e-12) return 1.0;
  return (1.0 - std::exp(-sT)) / sT;
}

// Integer power of 1/z (the delays).
cd zpow_inv(cd z, int n) {
  cd r = 1.0;
  const cd zi = 1.0 / z;
  for (int k = 0; k < n; ++k) r *= zi;
  return r;
}

enum : int { kI = 0, kW = 1, kX = 2, kIc = 3, kIv = 4, kIset = 5 };

}  // namespace

LinearAxisModel::LinearAxisModel(const core::DriveParams& p, double te_s) : params_(p), te_(te_s) {
  if (!(te_s > 0.0 && std::isfinite(te_s))) throw core::Error(fmt::format("Te must be positive, found {}", te_s));
  const int nc = whole_ratio(te_s, p.current_period_s, "position-loop period Te against the current loop");
  const int nvc = whole_ratio(p.velocity_period_s, p.current_period_s, "velocity_loop_period");
  if (nc % nvc != 0) throw core::Error("position-loop period Te is not a whole multiple of the velocity loop's");

  const double L = p.inductance_H, R = p.resistance_ohm, Kt = p.torque_constant_Nm_per_A, J = p.inertia_kg_m2;
  const double B = p.viscous_Nm_s_per_rad, r = p.axis_per_motor_rad;
  // Winding and shaft (the feed-drive simulation paper eq. 1), state (i, w, x), input the voltage, held over Tc: exact
  // ZOH discretisation.
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  a(kI, kI) = -R / L;
  a(kI, kW) = -Kt / L;  // back-EMF, Ke = Kt in SI
  a(kW, kI) = Kt / J;
  a(kW, kW) = -B / J;
  a(kX, kW) = r;
  a(kI, 3) = 1.0 / L;
  const Eigen::Matrix4d e = (a * p.current_period_s).exp();

  // Discrete PIs C(z) = Kp (1 + (T/Tn) z/(z-1)): the integrator takes this sample's error before the output.
  const double kpv = p.velocity_kp_A_s_per_rad, kiv = kpv * p.velocity_period_s / p.velocity_tn_s;
  const double kpc = p.current_kp_V_per_A, kic = kpc * p.current_period_s / p.current_tn_s;

  using M6 = Eigen::Matrix<double, 6, 6>;
  using B6 = Eigen::Matrix<double, 6, 2>;
  // Velocity-loop update (inputs: speed command w_cmd in rad/s, current feedforward in A).
  M6 v = M6::Identity();
  B6 vu = B6::Zero();
  v(kIv, kW) = -kiv;
  vu(kIv, 0) = kiv;
  v(kIset, kIset) = 0.0;
  v(kIset, kW) = -(kpv + kiv);
  v(kIset, kIv) = 1.0;
  vu(kIset, 0) = kpv + kiv;
  vu(kIset, 1) = 1.0;
  // Current-loop update and one Tc of the plant under the voltage it holds.
  M6 c = M6::Identity();
  c(kIc, kIset) = kic;
  c(kIc, kI) = -kic;
  Eigen::Matrix<double, 1, 6> volt = Eigen::Matrix<double, 1, 6>::Zero();  // volt = (kpc + kic)(iset - i) + ic
  volt(kIset) = kpc + kic;
  volt(kI) = -(kpc + kic);
  volt(kIc) = 1.0;
  for (int row = 0; row < 3; ++row) {
    c.row(row).setZero();
    for (int col = 0; col < 3; ++col) c(row, col) = e(row, col);
    c.row(row) += e(row, 3) * volt;
  }
  // Compose one Te: the velocity loop at the start of each Tv, the current loop at each Tc.
  phi_.setIdentity();
  gamma_.setZero();
  for (int n = 0; n < nc; ++n) {
    if (n % nvc == 0) {
      gamma_ = v * gamma_ + vu;
      phi_ = v * phi_;
    }
    gamma_ = c * gamma_;
    phi_ = c * phi_;
  }
}

cd LinearAxisModel::lifted(double omega, int input) const {
  const cd z = std::exp(cd(0.0, omega * te_));
  const Eigen::Matrix<cd, 6, 6> m = z * Eigen::Matrix<cd, 6, 6>::Identity() - phi_.cast<cd>();
  const Eigen::Matrix<cd, 6, 1> y = m.partialPivLu().solve(gamma_.col(input).cast<cd>());
  return y(kX);
}

cd LinearAxisModel::velocity_to_position(double omega) const {
  return lifted(omega, 0) / params_.axis_per_motor_rad;  // v_cmd (axis units/s) = r w_cmd
}

cd LinearAxisModel::current_to_position(double omega) const { return lifted(omega, 1); }

// The position loop around the inner cascade (Duong et al. Fig. 6): v_cmd = Kv (z^-dp x_d - x) + KF z^-df v_d, with
// v_d = (1 - z^-1)/Te x_d, and the torque feedforward KA J a_d / (Kt r) on a_d = (1 - z^-1)^2/Te^2 x_d.
cd LinearAxisModel::close(cd z, cd pv, cd pi, double kv, double kf) const {
  const cd zi = 1.0 / z;
  const cd dp = zpow_inv(z, params_.position_delay_samples), df = zpow_inv(z, params_.feedforward_delay_samples);
  const cd diff = (1.0 - zi) / te_;
  const double ka_gain =
      params_.ka * params_.inertia_kg_m2 / (params_.torque_constant_Nm_per_A * params_.axis_per_motor_rad);
  const cd num = (kv * dp + kf * df * diff) * pv + ka_gain * df * diff * diff * pi;
  return num / (1.0 + kv * pv);
}

cd LinearAxisModel::closed_loop(double omega) const { return closed_loop(omega, params_.kv_per_s, params_.kf); }

cd LinearAxisModel::closed_loop(double omega, double kv, double kf) const {
  if (omega == 0.0) return 1.0;
  const cd z = std::exp(cd(0.0, omega * te_));
  return close(z, velocity_to_position(omega), current_to_position(omega), kv, kf);
}

cd LinearAxisModel::closed_loop_elements(double omega) const {
  return closed_loop_elements(omega, params_.kv_per_s, params_.kf);
}

cd LinearAxisModel::closed_loop_elements(double omega, double kv, double kf) const {
  if (omega == 0.0) return 1.0;
  const core::DriveParams& p = params_;
  const cd s(0.0, omega);
  const double tc = p.current_period_s, tv = p.velocity_period_s;
  const cd zc = std::exp(s * tc), zv = std::exp(s * tv), ze = std::exp(s * te_);
  const double kpv = p.velocity_kp_A_s_per_rad, kiv = kpv * tv / p.velocity_tn_s;
  const double kpc = p.current_kp_V_per_A, kic = kpc * tc / p.current_tn_s;
  const double Kt = p.torque_constant_Nm_per_A;
  // Rate changes: a sequence held over T and read by a loop running at T' < T (T' divides T) is the hold
  // upsampler 1 + z'^-1 + ... (T/T' terms), at baseband (T'/T) (1 - e^{-sT}) / (1 - e^{-sT'}) = zoh(T) / zoh(T'):
  // a delay (T - T')/2, not T/2, since the faster loop takes the new value at the instant it appears. Only the
  // loop that drives the continuous plant (the current loop's voltage) holds with a full ZOH(Tc).
  const cd hc = zoh(s, tc), hv = zoh(s, tv), he = zoh(s, te_);
  // Current loop: discrete PI, ZOH of the voltage, winding with back-EMF through the shaft.
  const cd cc = kpc + kic * zc / (zc - 1.0);
  const cd shaft = 1.0 / (p.inertia_kg_m2 * s + p.viscous_Nm_s_per_rad);               // w per torque
  const cd winding = 1.0 / (p.inductance_H * s + p.resistance_ohm + Kt * Kt * shaft);  // i per volt
  const cd lc = cc * hc * winding;
  const cd current_cl = lc / (1.0 + lc);  // i per current setpoint (sequence at Tc)
  // Velocity loop: discrete PI; its current setpoint, held over Tv, read by the current loop at Tc; the shaft.
  const cd cv = kpv + kiv * zv / (zv - 1.0);
  const cd plant_v = (hv / hc) * current_cl * Kt * shaft;  // w per current setpoint (sequence at Tv)
  const cd lv = cv * plant_v;
  const cd w_per_wcmd = lv / (1.0 + lv), w_per_iff = plant_v / (1.0 + lv);
  // Position: the velocity command and current feedforward held over Te and read by the velocity loop at Tv;
  // x = r w / s, sampled at Te.
  const cd up_e = he / hv;
  const cd pv = up_e * w_per_wcmd / s;                        // x per v_cmd (v_cmd = r w_cmd)
  const cd pi = up_e * p.axis_per_motor_rad * w_per_iff / s;  // x per current feedforward
  return close(ze, pv, pi, kv, kf);
}

// The position loop reads x(t_k) without delay (the delays sit in the command paths, outside the loop), so closing
// it adds w_cmd = -(Kv / r) x to the lifted cascade's input.
Eigen::VectorXcd LinearAxisModel::closed_loop_poles(double kv) const {
  Eigen::Matrix<double, 6, 6> a = phi_;
  a.col(kX) -= (kv / params_.axis_per_motor_rad) * gamma_.col(0);
  return Eigen::EigenSolver<Eigen::Matrix<double, 6, 6>>(a, false).eigenvalues();
}

// Nothing in the inner cascade depends on the position (no tilting gravity in the linear model): dropping its row
// and column leaves the velocity and current loops' poles.
Eigen::VectorXcd LinearAxisModel::inner_poles() const {
  Eigen::Matrix<double, 5, 5> a;
  const int keep[5] = {kI, kW, kIc, kIv, kIset};
  for (int r = 0; r < 5; ++r)
    for (int c = 0; c < 5; ++c) a(r, c) = phi_(keep[r], keep[c]);
  return Eigen::EigenSolver<Eigen::Matrix<double, 5, 5>>(a, false).eigenvalues();
}

double LinearAxisModel::circle_radial_error(double radius, double speed) const {
  return radius * (1.0 - std::abs(closed_loop(speed / radius)));
}

}  // namespace vmsim::drives
