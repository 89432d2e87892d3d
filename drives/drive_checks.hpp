#pragma once
// What the linearised cascade (drives/linear_model) says about a drive before it runs: whether its loops are stable,
// how far its position gain is from instability, how well damped it is; and, for the run's own check of the
// following error (sim/drive_checks), the error its linear model predicts at a given velocity and acceleration.
#include "core/machine.hpp"
#include "core/warning.hpp"

#include <Eigen/Core>

#include <string>

namespace vmsim::drives {

struct DriveStability {
  double kv_te = 0;              // Kv * Te (the position loop's gain per period)
  double inner_pole_radius = 0;  // largest |z| of the velocity and current loops, position loop open
  double pole_radius = 0;        // largest |z| of the whole cascade, position loop closed
  double min_damping = 1;        // smallest damping ratio of the closed cascade's poles (z = e^{s Te})
  double gain_margin = 0;        // Kv may be multiplied by this before the closed cascade turns unstable (inf: never
                                 // up to 1e4); 0 when the inner loops are unstable already
  Eigen::VectorXcd poles;        // the closed cascade's, z-plane, per Te
  // The linear model's following error e = x_d - x at low frequency, e ~ c1 v + c2 a (v, a of the setpoints): from
  // E(z) = 1 - G(z) = c1 s + c2 s^2 + ... (closed_loop), s = jw. Meaningful only when the cascade is stable.
  double lag_s = 0, lag_s2 = 0;
};

// Throws core::Error when the loop periods do not nest (as LinearAxisModel).
DriveStability drive_stability(const core::DriveParams& params, double te_s);

// The findings of drive_stability for axis `axis` of the machine file `machine_file`: Invalid for an unstable loop
// (the simulation could not mean anything), warnings for a gain margin under 2 or a closed-loop damping ratio under
// 0.1. Each message names the axis, the figures and the [axes.drive] keys that set them.
core::Warnings check_drive(const core::DriveParams& params, double te_s, const std::string& axis,
                           const std::string& machine_file);

}  // namespace vmsim::drives
