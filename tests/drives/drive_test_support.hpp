#pragma once
// Shared helpers of the drives tests: the Mikron machine file, setpoint builders, and explicit parameter sets.
#include "core/machine.hpp"
#include "core/setpoints.hpp"

#include <Eigen/Core>

#include <cmath>
#include <filesystem>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

namespace vmsim::drives::test {

inline core::Machine mikron() {
  return core::load_machine(std::filesystem::path(VMSIM_SOURCE_DIR) / "parts/machines/mikron_ucp710.toml");
}

// The machine restricted to the named axes (in the machine file's order), e.g. {"X", "Y"} for a circle.
// The Mikron X axis's drive.
inline core::DriveParams mikron_x() { return *mikron().axes[0].drive; }

inline core::Machine only_axes(const core::Machine& m, const std::vector<std::string>& names) {
  core::Machine out = m;
  out.axes.clear();
  for (const auto& ax : m.axes)
    for (const auto& n : names)
      if (ax.name == n) out.axes.push_back(ax);
  return out;
}

// Setpoints every te from f(t) (one value per axis) for `samples` samples.
inline core::Setpoints sampled(const core::Machine& m, double te, Eigen::Index samples,
                               const std::function<void(double t, double* out)>& f) {
  core::Setpoints sp;
  sp.period_s = te;
  for (const auto& ax : m.axes) sp.axis_names.push_back(ax.name);
  sp.position.resize(samples, static_cast<Eigen::Index>(m.axes.size()));
  std::vector<double> row(m.axes.size());
  for (Eigen::Index k = 0; k < samples; ++k) {
    f(static_cast<double>(k) * te, row.data());
    for (Eigen::Index a = 0; a < sp.position.cols(); ++a) sp.position(k, a) = row[static_cast<std::size_t>(a)];
  }
  sp.path_speed_mm_per_s.setZero(samples);
  sp.path_length_mm.setZero(samples);
  sp.move_index.setZero(samples);
  return sp;
}

// Inner loops made close to ideal for the position loop (reference behaviour of Duong et al. Fig. 6 with a perfect
// velocity loop): the Mikron X motor and mechanics, current loop at 5 kHz bandwidth and velocity loop at 1 kHz,
// both sampled at 5 us, limits far out of reach, no friction. Gains by the same rules as the machine file
// (current Kp = L wc, Tn = L/R; velocity Kp = J wv / Kt, Tn = 4 / wv).
inline core::DriveParams ideal_inner_loops(const core::DriveParams& base) {
  core::DriveParams p = base;
  const double wc = 2 * std::numbers::pi * 5000.0, wv = 2 * std::numbers::pi * 1000.0;
  p.current_period_s = p.velocity_period_s = 5e-6;
  p.current_kp_V_per_A = p.inductance_H * wc;
  p.current_tn_s = p.inductance_H / p.resistance_ohm;
  p.velocity_kp_A_s_per_rad = p.inertia_kg_m2 * wv / p.torque_constant_Nm_per_A;
  p.velocity_tn_s = 4.0 / wv;
  p.current_limit_A = 1e4;
  p.voltage_limit_V = 1e6;
  p.coulomb_Nm = 0.0;
  p.stribeck_static_Nm = 0.0;
  return p;
}

}  // namespace vmsim::drives::test
