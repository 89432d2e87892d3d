#include "drives/drive_checks.hpp"

#include "drives/linear_model.hpp"

#include <fmt/format.h>

#include <cmath>
#include <complex>
#include <limits>

namespace vmsim::drives {

namespace {

double radius(const Eigen::VectorXcd& poles) { return poles.size() ? poles.cwiseAbs().maxCoeff() : 0.0; }

// Damping ratio of a z-plane pole, through s = ln(z) / Te: -Re s / |s| (1 for a pole at the origin or on (0, 1)).
double damping(std::complex<double> z) {
  if (std::abs(z) < 1e-300) return 1.0;
  const std::complex<double> s = std::log(z);
  return std::abs(s) > 0 ? -s.real() / std::abs(s) : 1.0;
}

// Kv in the files' unit, (m/min)/mm = (1000 deg/min)/deg = 1000/min.
double kv_file(double kv_per_s) { return kv_per_s * 60.0 / 1000.0; }

}  // namespace

DriveStability drive_stability(const core::DriveParams& p, double te_s) {
  const LinearAxisModel model(p, te_s);
  DriveStability d;
  d.kv_te = p.kv_per_s * te_s;
  d.inner_pole_radius = radius(model.inner_poles());
  d.poles = model.closed_loop_poles();
  d.pole_radius = radius(d.poles);
  for (Eigen::Index k = 0; k < d.poles.size(); ++k) d.min_damping = std::min(d.min_damping, damping(d.poles[k]));
  if (d.inner_pole_radius < 1.0 && p.kv_per_s > 0) {
    // The factor on Kv where the largest pole reaches |z| = 1: doubling up to 1e4, then bisection.
    auto stable = [&](double f) { return radius(model.closed_loop_poles(f * p.kv_per_s)) < 1.0; };
    double lo = 0, hi = 1;
    while (hi <= 1e4 && stable(hi)) lo = hi, hi *= 2;
    if (hi > 1e4) {
      d.gain_margin = std::numeric_limits<double>::infinity();
    } else {
      for (int it = 0; it < 50; ++it) {
        const double mid = 0.5 * (lo + hi);
        (stable(mid) ? lo : hi) = mid;
      }
      d.gain_margin = lo;
    }
  }
  if (d.pole_radius < 1.0) {
    // Low-frequency expansion of E = 1 - G at w small against the loop (Kv) and the period: E = j w c1 - w^2 c2.
    const double w = 1e-3 * std::min(std::max(p.kv_per_s, 1.0), 1.0 / te_s);
    const std::complex<double> e = 1.0 - model.closed_loop(w);
    d.lag_s = e.imag() / w;
    d.lag_s2 = -e.real() / (w * w);
  }
  return d;
}

core::Warnings check_drive(const core::DriveParams& p, double te_s, const std::string& axis,
                           const std::string& machine_file) {
  const DriveStability d = drive_stability(p, te_s);
  core::Warnings out;
  const std::string where = fmt::format("{}: axis {} [axes.drive]", machine_file, axis);
  if (d.inner_pole_radius >= 1.0) {
    // The velocity loop's proportional gain per period, the discrete loop's figure: a P loop on a free inertia is
    // unstable above 2.
    const double kvel = p.velocity_kp_A_s_per_rad * p.torque_constant_Nm_per_A * p.velocity_period_s / p.inertia_kg_m2;
    out.push_back(
        {"drive_unstable", axis,
         fmt::format("{}: the velocity and current loops are unstable (a pole at |z| = {:.3g} per {:g} ms, "
                     "position loop open; velocity_kp * Kt * Tv / J = {:.3g}, which a stable velocity loop keeps "
                     "well under 2): check velocity_kp_A_s_per_rad, velocity_tn_ms, current_kp_V_per_A, "
                     "current_tn_ms, inertia_kg_m2, torque_constant_Nm_per_A, inductance_mH and their units",
                     where, d.inner_pole_radius, te_s * 1e3, kvel),
         core::Warning::Severity::Invalid});
    return out;
  }
  if (d.pole_radius >= 1.0) {
    out.push_back(
        {"position_loop_unstable", axis,
         fmt::format("{}: the position loop is unstable at kv_1000_per_min = {:g} (Kv = {:g} 1/s, Kv * Te = "
                     "{:.3g}; a pole at |z| = {:.3g} per period): it is stable only below kv_1000_per_min = "
                     "{:.3g} with these inner loops; check kv_1000_per_min (in (m/min)/mm, i.e. 1000/min) and "
                     "the job's period_ms",
                     where, kv_file(p.kv_per_s), p.kv_per_s, d.kv_te, d.pole_radius,
                     kv_file(p.kv_per_s * d.gain_margin)),
         core::Warning::Severity::Invalid});
    return out;
  }
  if (d.gain_margin < 2.0)
    out.push_back({"small_gain_margin", axis,
                   fmt::format("{}: the position loop turns unstable at {:.2f} times kv_1000_per_min = {:g} (a gain "
                               "margin under 2, 6 dB): the drive will ring; lower kv_1000_per_min or speed up the "
                               "velocity loop",
                               where, d.gain_margin, kv_file(p.kv_per_s))});
  if (d.min_damping < 0.1)
    out.push_back({"poorly_damped", axis,
                   fmt::format("{}: a closed-loop pole of the cascade has a damping ratio of {:.3f} (under 0.1): the "
                               "axis will ring after every change of acceleration; check kv_1000_per_min, "
                               "velocity_kp_A_s_per_rad and velocity_tn_ms",
                               where, d.min_damping)});
  return out;
}

}  // namespace vmsim::drives
