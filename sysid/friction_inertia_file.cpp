#include "sysid/friction_inertia_file.hpp"

#include "core/error.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <cmath>

namespace vmsim::sysid {

std::optional<GravityModel> parse_gravity_model(const std::string& name) {
  for (GravityModel g : {GravityModel::Auto, GravityModel::None, GravityModel::Constant, GravityModel::Tilting})
    if (name == gravity_model_name(g)) return g;
  return std::nullopt;
}

IdentifyOptions identify_options_for_axis(const core::MachineAxis& axis, const std::string& machine_file,
                                          const AxisTrace& trace, GravityModel gravity) {
  if ((axis.kind == core::AxisKind::Rotary) != trace.rotary)
    throw core::Error(fmt::format("{}: axis {} is {} but the trace {} gives {}", machine_file, axis.name,
                                  trace.rotary ? "linear" : "rotary", trace.source,
                                  trace.rotary ? "degrees" : "millimetres"));
  if (!axis.drive)
    throw core::Error(core::located(
        machine_file, 0, fmt::format("axis {} has no [axes.drive] table (torque constant, lead or gear)", axis.name)));
  IdentifyOptions o;
  o.torque_constant_Nm_per_A = axis.drive->torque_constant_Nm_per_A;
  o.axis_per_motor_rad = axis.drive->axis_per_motor_rad;
  o.gravity = gravity;
  if (gravity == GravityModel::Auto) {
    switch (axis.drive->gravity) {
      case core::DriveParams::Gravity::None:
        o.gravity = GravityModel::None;
        break;
      case core::DriveParams::Gravity::Constant:
        o.gravity = GravityModel::Constant;
        break;
      case core::DriveParams::Gravity::Tilting:
        o.gravity = GravityModel::Tilting;
        break;
    }
  }
  return o;
}

bool gravity_is_written(const IdentifiedDrive& d, bool gravity_model_given) {
  const bool significant = std::abs(d.gravity_Nm) > 3.0 * d.gravity_stderr_Nm;
  return d.gravity != GravityModel::None && (gravity_model_given || significant);
}

std::string identified_drive_toml(const IdentifiedDrive& d, const IdentifyOptions& options, bool rotary,
                                  const std::string& trace_name, bool write_gravity) {
  std::string toml = fmt::format(
      "# vmsim identify-friction {} (the feed-drive simulation paper section 3.1)\n"
      "# friction: {} constant-velocity stretches ({} positive, {} negative), residual {:.4g} A rms\n"
      "# inertia: eq. 2 on {} accelerating samples, residual {:.4g} A rms\n"
      "# The identified keys of the axis' [axes.drive] table; the loop gains and the winding stay as they are.\n"
      "[axes.drive]\n"
      "torque_constant_Nm_per_A = {:.9g}\n",
      trace_name, d.stretches, d.stretches_positive, d.stretches_negative, d.friction_rms_residual_A, d.accel_samples,
      d.inertia_rms_residual_A, options.torque_constant_Nm_per_A);
  if (rotary)
    toml += fmt::format("gear_deg_per_motor_rev = {:.9g}\n", options.axis_per_motor_rad * 360.0);
  else
    toml += fmt::format("screw_lead_mm = {:.9g}\n", options.axis_per_motor_rad * 2 * core::units::kPi);
  toml += fmt::format("inertia_kg_m2 = {:.6g}\ncoulomb_friction_Nm = {:.6g}\nviscous_friction_Nm_s_per_rad = {:.6g}\n",
                      d.inertia_kg_m2, d.coulomb_Nm, d.viscous_Nm_s_per_rad);
  if (write_gravity) {
    toml += fmt::format("gravity = \"{}\"\ngravity_torque_Nm = {:.6g}            # +- {:.2g}\n",
                        gravity_model_name(d.gravity), d.gravity_Nm, d.gravity_stderr_Nm);
    if (d.gravity == GravityModel::Tilting)
      toml += fmt::format("gravity_angle_offset_deg = {:.6g}\n", d.gravity_angle_offset_rad * core::units::kRadToDeg);
  } else if (d.gravity != GravityModel::None) {
    toml += fmt::format("gravity = \"none\"                  # fitted offset {:.3g} +- {:.2g} N m: not significant\n",
                        d.gravity_Nm, d.gravity_stderr_Nm);
  } else {
    toml += "gravity = \"none\"\n";
  }
  return toml;
}

std::string friction_points_csv(const IdentifiedDrive& d, bool rotary) {
  const double to_file = rotary ? core::units::kRadToDeg : 1.0;  // axis units (mm, rad) -> the trace's units
  std::string csv = fmt::format(
      "velocity_{}_per_s,measured_mean_current_A,fitted_current_A,samples,t_start_s,t_end_s\n", rotary ? "deg" : "mm");
  for (const FrictionPoint& p : d.points)
    csv += fmt::format("{:.9g},{:.9g},{:.9g},{},{:.6f},{:.6f}\n", p.velocity * to_file, p.mean_current_A,
                       p.fitted_current_A, p.samples, p.t_start_s, p.t_end_s);
  return csv;
}

}  // namespace vmsim::sysid
