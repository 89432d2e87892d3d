#include "methods/feedplan_servo.hpp"

#include "core/error.hpp"
#include "drives/linear_model.hpp"

#include <Eigen/LU>
#include <fmt/format.h>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::methods {

namespace {

using cd = std::complex<double>;

// Logarithmic grid of the tabulated error ratio: 1e-3 rad/s up to omega_max, 400 points per decade (steps of 0.58 %).
constexpr double kGridLow = 1e-3;
constexpr int kPerDecade = 400;

}  // namespace

cd TransferFunction::at(cd s) const {
  cd n = 0.0, d = 0.0;
  for (double c : num) n = n * s + c;
  for (double c : den) d = d * s + c;
  return n / d;
}

PidServoParams chen2016_pid_x() { return {10.0, 50.0, 0.3, 6.5723, 0.4769, 7.0028e-3, 0.023569, 1.5915}; }
PidServoParams chen2016_pid_y() { return {12.344, 61.718, 0.367, 6.2274, 0.4769, 8.1904e-3, 0.043009, 1.5915}; }

TransferFunction pid_servo_transfer_function(const PidServoParams& p) {
  for (double v : {p.kp, p.ki, p.kd, p.ka, p.kt, p.inertia, p.rg})
    if (!(v > 0) || !std::isfinite(v))
      throw core::Error("PID servo (Chen et al. 2016 eq. 2): kp, ki, kd, ka, kt, J and rg must be > 0");
  if (!(p.damping >= 0)) throw core::Error("PID servo (Chen et al. 2016 eq. 2): the damping B must be >= 0");
  const double K = p.ka * p.kt * p.rg;
  TransferFunction tf;
  tf.num = {K * p.kd, K * p.kp, K * p.ki};
  tf.den = {p.inertia, p.damping + K * p.kd, K * p.kp, K * p.ki};
  return tf;
}

AxisFrequencyResponse frequency_response(const TransferFunction& tf) {
  if (tf.den.empty() || tf.den.front() == 0.0 || tf.num.size() > tf.den.size())
    throw core::Error(
        "transfer function: the denominator must have a non-zero leading coefficient and a degree at "
        "least the numerator's");
  AxisFrequencyResponse r;
  r.g = [tf](double w) { return tf.at_omega(w); };
  r.omega_max = 1e5;
  return r;
}

AxisFrequencyResponse frequency_response(const core::DriveParams& drive, double te_s) {
  auto model = std::make_shared<drives::LinearAxisModel>(drive, te_s);
  AxisFrequencyResponse r;
  r.g = [model](double w) { return model->closed_loop(w); };
  r.omega_max = 0.999 * 3.14159265358979323846 / te_s;  // below the Nyquist frequency of the sampled loop
  return r;
}

ContourErrorModel::ContourErrorModel(std::vector<AxisFrequencyResponse> axes) : axes_(std::move(axes)) {
  if (axes_.empty()) throw core::Error("contour-error model: no axis response");
  double wmax = 1e300;
  for (const auto& a : axes_) wmax = std::min(wmax, a.omega_max);
  if (!(wmax > kGridLow * 10)) throw core::Error("contour-error model: the responses' frequency range is too short");
  const int n = static_cast<int>(std::ceil(std::log10(wmax / kGridLow) * kPerDecade));
  w_.resize(static_cast<std::size_t>(n) + 1);
  env_.resize(w_.size());
  for (const auto& a : axes_) {
    const cd g0 = a.g(kGridLow);
    if (!std::isfinite(g0.real()) || !std::isfinite(g0.imag()) || std::abs(std::abs(g0) - 1.0) > 1e-3)
      throw core::Error(
          fmt::format("contour-error model: |G| = {:.6g} at {} rad/s, expected 1 (a position servo "
                      "follows slow commands)",
                      std::abs(g0), kGridLow));
  }
  // Natural frequency: the first local maximum of |G| of any axis, else the first -3 dB frequency, else omega_max.
  omega_n_ = wmax;
  std::vector<double> prev(axes_.size(), 0.0), prev2(axes_.size(), 0.0);
  double run = 0.0;
  for (int i = 0; i <= n; ++i) {
    const double w = i == n ? wmax : kGridLow * std::pow(10.0, double(i) / kPerDecade);
    w_[static_cast<std::size_t>(i)] = w;
    double e = 0.0;
    for (std::size_t a = 0; a < axes_.size(); ++a) {
      const double m = std::abs(axes_[a].g(w));
      if (!std::isfinite(m)) throw core::Error(fmt::format("contour-error model: |G| is not finite at {} rad/s", w));
      e = std::max(e, std::abs(1.0 - m));
      if (i >= 2 && prev[a] > prev2[a] && prev[a] >= m && prev[a] > 1.0)
        omega_n_ = std::min(omega_n_, w_[static_cast<std::size_t>(i - 1)]);
      if (m < 1.0 / std::sqrt(2.0)) omega_n_ = std::min(omega_n_, w);
      prev2[a] = prev[a];
      prev[a] = m;
    }
    run = std::max(run, e);
    env_[static_cast<std::size_t>(i)] = run;
  }
}

double ContourErrorModel::error_ratio(double omega) const {
  double e = 0.0;
  for (const auto& a : axes_) e = std::max(e, std::abs(1.0 - std::abs(a.g(omega))));
  return e;
}

double ContourErrorModel::omega0(double x) const {
  if (!(x > 0)) return 0.0;
  // First grid point where the running maximum reaches x, if that is below w_n.
  const auto it = std::lower_bound(env_.begin(), env_.end(), x);
  if (it == env_.end()) return omega_n_;
  const std::size_t i = static_cast<std::size_t>(it - env_.begin());
  if (w_[i] > omega_n_ && (i == 0 || w_[i - 1] >= omega_n_)) return omega_n_;
  // e < x on [0, w_{i-1}], e(w_i) >= x: the crossing lies in between. Illinois regula falsi on e(w) - x.
  double a = i == 0 ? 0.0 : w_[i - 1], b = w_[i];
  double fa = (a > 0 ? error_ratio(a) : 0.0) - x, fb = error_ratio(b) - x;
  if (fb < 0) fb = 0;  // the running maximum reached x at b only through a neighbour: treat b as the crossing
  int side = 0;
  for (int it2 = 0; it2 < 100 && b - a > 1e-13 * b; ++it2) {
    const double c = fb - fa != 0 ? (a * fb - b * fa) / (fb - fa) : 0.5 * (a + b);
    const double fc = error_ratio(c) - x;
    if (fc >= 0) {
      b = c, fb = fc;
      if (side == -1) fa /= 2;
      side = -1;
    } else {
      a = c, fa = fc;
      if (side == 1) fb /= 2;
      side = 1;
    }
  }
  return std::min(a, omega_n_);  // a: the largest point known to satisfy e <= x
}

double ContourErrorModel::max_feed(double rho_mm, double eps0_mm) const {
  if (!std::isfinite(rho_mm)) return std::numeric_limits<double>::infinity();
  return omega0(eps0_mm / rho_mm) * rho_mm;
}

// ---- time response ----------------------------------------------------------------------------------------------

TransferFunctionAxis::TransferFunctionAxis(const TransferFunction& tf, double te_s) : te_(te_s) {
  if (!(te_s > 0)) throw core::Error("transfer-function axis: Te must be > 0");
  if (tf.den.empty() || tf.den.front() == 0.0 || tf.num.empty() || tf.num.size() > tf.den.size())
    throw core::Error(
        "transfer-function axis: need a proper transfer function (den's degree >= num's, leading "
        "coefficient != 0)");
  const int n = static_cast<int>(tf.den.size()) - 1;
  const double a0 = tf.den.front();
  std::vector<double> a(tf.den.size()), b(tf.den.size(), 0.0);
  for (std::size_t i = 0; i < tf.den.size(); ++i) a[i] = tf.den[i] / a0;
  for (std::size_t i = 0; i < tf.num.size(); ++i) b[tf.den.size() - tf.num.size() + i] = tf.num[i] / a0;
  // Controllable canonical form: x' = A x + B r, y = C x + D r.
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i + 1 < n; ++i) A(i, i + 1) = 1.0;
  for (int j = 0; j < n; ++j) A(n - 1, j) = -a[static_cast<std::size_t>(n - j)];
  Eigen::VectorXd B = Eigen::VectorXd::Zero(n);
  if (n > 0) B(n - 1) = 1.0;  // n == 0: a pure gain, no state
  d_ = b[0];
  c_.resize(n);
  for (int j = 0; j < n; ++j) c_(j) = b[static_cast<std::size_t>(n - j)] - b[0] * a[static_cast<std::size_t>(n - j)];
  // Augmented with the ramp input r(tau) = w + c tau / Te: [x; w; c]' = [[A, B, 0]; [0, 0, 1/Te]; [0, 0, 0]] [x; w; c].
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + 2, n + 2);
  M.topLeftCorner(n, n) = A;
  M.block(0, n, n, 1) = B;
  M(n, n + 1) = 1.0 / te_s;
  const Eigen::MatrixXd E = (M * te_s).exp();
  phi_ = E.topLeftCorner(n, n);
  gamma0_ = E.block(0, n, n, 1);
  gamma1_ = E.block(0, n + 1, n, 1);
  if (n == 0) {  // a pure gain
    if (std::abs(d_ - 1.0) > 1e-6)
      throw core::Error(fmt::format("transfer-function axis: G(0) = {:.6g}, a position servo needs 1", d_));
    x_rest_.resize(0);
    reset(0.0);
    return;
  }
  if (a[static_cast<std::size_t>(n)] == 0.0)
    throw core::Error("transfer-function axis: G(0) is not finite (a pole at 0)");
  x_rest_ = -A.partialPivLu().solve(B);
  const double g0 = c_.dot(x_rest_) + d_;
  if (std::abs(g0 - 1.0) > 1e-6)
    throw core::Error(fmt::format("transfer-function axis: G(0) = {:.6g}, a position servo needs 1", g0));
  reset(0.0);
}

void TransferFunctionAxis::reset(double position) {
  x_ = x_rest_ * position;
  r_prev_ = position;
  y_ = position;
  v_ = 0.0;
}

drives::AxisSample TransferFunctionAxis::step(const drives::AxisCommand& command) {
  const double r = command.position;
  x_ = phi_ * x_ + gamma0_ * r_prev_ + gamma1_ * (r - r_prev_);
  r_prev_ = r;
  drives::AxisSample s;
  s.position = c_.dot(x_) + d_ * r;
  s.velocity = (s.position - y_) / te_;
  s.acceleration = (s.velocity - v_) / te_;
  y_ = s.position;
  v_ = s.velocity;
  return s;
}

std::unique_ptr<drives::AxisModel> TransferFunctionAxis::clone() const {
  return std::make_unique<TransferFunctionAxis>(*this);
}

Eigen::MatrixXd simulate_transfer_functions(const core::Setpoints& sp, const std::vector<TransferFunction>& axes,
                                            double settle_s) {
  if (static_cast<Eigen::Index>(axes.size()) != sp.position.cols())
    throw core::Error(fmt::format("transfer-function servo: {} axis models for {} setpoint columns", axes.size(),
                                  sp.position.cols()));
  if (sp.samples() == 0) throw core::Error("setpoints: no samples to simulate");
  const Eigen::Index ns = sp.samples();
  const Eigen::Index rows = ns + static_cast<Eigen::Index>(std::llround(std::max(0.0, settle_s) / sp.period_s));
  Eigen::MatrixXd out(rows, sp.position.cols());
  for (Eigen::Index a = 0; a < sp.position.cols(); ++a) {
    TransferFunctionAxis ax(axes[static_cast<std::size_t>(a)], sp.period_s);
    ax.reset(sp.position(0, a));
    out(0, a) = sp.position(0, a);
    for (Eigen::Index k = 0; k + 1 < rows; ++k) {
      drives::AxisCommand c;
      c.position = sp.position(std::min(k, ns - 1), a);
      out(k + 1, a) = ax.step(c).position;
    }
  }
  return out;
}

}  // namespace vmsim::methods
