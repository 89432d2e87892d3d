#pragma once
// Servo models for Chen et al.'s contour-error constrained feed planning (drives/feedplan).
//
// - Frequency responses G(jw) of the axes' closed loops, from which Chen et al.'s circular contour-error model
//   eps = rho |1 - |G(j f/rho)|| (eq. 6-7) bounds the feed (eq. 11-13): a continuous transfer function (Chen et al.
//   2016 eq. 2, the PID servo of its Table 1, or any identified model), or the machine's linearised cascade
//   (drives/linear_model, the exact sampled-data response at Te).
// - ContourErrorModel: the error ratio e(w) = |1 - |G(jw)|| (the worst of the moving axes, since Chen et al.'s eq. 5
//   assumes matched axes), the natural frequency w_n and the largest admissible w0 of eq. 11.
// - TransferFunctionAxis: the time response of a continuous transfer-function servo to setpoints every Te, for
//   simulating Chen et al.'s own case (its servo is not a cascade the machine files describe).
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "drives/axis_model.hpp"

#include <Eigen/Core>

#include <complex>
#include <functional>
#include <memory>
#include <vector>

namespace vmsim::methods {

// G(s) = num(s) / den(s), coefficients in descending powers of s; proper (deg num <= deg den), den's leading
// coefficient != 0, G(0) = 1 for a position servo (checked where it matters). {1}/{1} is an ideal axis.
struct TransferFunction {
  std::vector<double> num, den;
  std::complex<double> at(std::complex<double> s) const;
  std::complex<double> at_omega(double omega_rad_s) const { return at({0.0, omega_rad_s}); }
};

// Chen et al. 2016 Fig. 1 / Table 1: a PID on the position error (V/mm, V/(mm s), V/(mm/s)), current amplifier ka
// (A/V), torque constant kt (N m/A), inertia J, viscous damping B, screw lead rg (mm/rad).
struct PidServoParams {
  double kp = 10.0, ki = 50.0, kd = 0.3;
  double ka = 6.5723, kt = 0.4769, inertia = 7.0028e-3, damping = 0.023569, rg = 1.5915;
};
// Chen et al. 2016 Table 1, X and Y axes.
PidServoParams chen2016_pid_x();
PidServoParams chen2016_pid_y();
// Chen et al. 2016 eq. 2 (with the numerator's evident kp s term): K = ka kt rg,
//   G(s) = K (kd s^2 + kp s + ki) / (J s^3 + (B + K kd) s^2 + K kp s + K ki)   (Table 2's A1..A7 for the X axis).
TransferFunction pid_servo_transfer_function(const PidServoParams& p);

// One axis' closed-loop response X/X_d at angular frequency w (rad/s), valid on (0, omega_max].
struct AxisFrequencyResponse {
  std::function<std::complex<double>(double)> g;
  double omega_max = 1e5;  // continuous models: far above any contouring frequency; sampled ones: below pi/Te
};
AxisFrequencyResponse frequency_response(const TransferFunction& tf);
// The machine axis' linearised cascade (drives/linear_model): its exact sampled-data response at Te.
AxisFrequencyResponse frequency_response(const core::DriveParams& drive, double te_s);

// Chen et al. 2016 section 2 and eq. 9-13 for a set of axes (those the path moves).
class ContourErrorModel {
 public:
  // Tabulates e(w) = max_axes |1 - |G(jw)|| on a logarithmic grid and finds w_n. Throws core::Error for no axes or a
  // response that is not finite or not 1 at low frequency (not a position servo).
  explicit ContourErrorModel(std::vector<AxisFrequencyResponse> axes);

  // eps / rho of a circle run at angular speed w (eq. 6-7).
  double error_ratio(double omega) const;
  // The natural frequency w_n bounding eq. 11's w0: the first resonance peak of |G| (the first local maximum of the
  // tabulated |G| of any axis), or the bandwidth (|G| = 1/sqrt 2) when |G| has no peak before it, or omega_max.
  double natural_frequency() const { return omega_n_; }
  // Eq. 11: the largest w0 <= w_n such that e(w) <= kappa eps0 for every w in [0, w0] (the first crossing of
  // 1 - kappa eps0 = |G| or 1 + kappa eps0 = |G|, whichever comes first; w_n when none does).
  double omega0(double kappa_eps0) const;
  // Eq. 12-13: the largest feed whose circle of radius rho keeps the error within eps0: w0(eps0 / rho) rho.
  double max_feed(double rho_mm, double eps0_mm) const;

 private:
  std::vector<AxisFrequencyResponse> axes_;
  std::vector<double> w_, env_;  // grid and the running maximum of e over [0, w]
  double omega_n_ = 0.0;
};

// A continuous transfer-function servo as an AxisModel: setpoint k reaches it at t_k and the reference moves
// linearly from setpoint k-1 to setpoint k over [t_k, t_k + Te) (a first-order hold one period late: the drive
// interpolates between the last two setpoints it received, so a smooth setpoint path is followed as a smooth
// curve, as fine interpolation in a drive does). Exact discretisation of the controllable canonical state space
// (matrix exponential of the system augmented with the ramp).
class TransferFunctionAxis final : public drives::AxisModel {
 public:
  TransferFunctionAxis(const TransferFunction& tf, double te_s);
  void reset(double position) override;
  drives::AxisSample step(const drives::AxisCommand& command) override;
  std::unique_ptr<drives::AxisModel> clone() const override;

 private:
  Eigen::MatrixXd phi_;
  Eigen::VectorXd gamma0_, gamma1_, c_;
  double d_ = 0.0, te_ = 1e-3;
  Eigen::VectorXd x_, x_rest_;  // state; steady state per unit position
  double r_prev_ = 0.0, y_ = 0.0, v_ = 0.0;
};

// Setpoints through one TransferFunctionAxis per column (the same convention as drives::simulate_axes: row 0 at
// rest at the first setpoint, row k+1 after setpoint k, then settle_s more with the last setpoint held). Returns
// the actual positions, rows x columns.
Eigen::MatrixXd simulate_transfer_functions(const core::Setpoints& setpoints, const std::vector<TransferFunction>& axes,
                                            double settle_s = 0.2);

}  // namespace vmsim::methods
