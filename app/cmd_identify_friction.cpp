// vmsim identify-friction TRACE.csv: the friction law and the inertia of one axis from a measured trace
// (the feed-drive simulation paper section 3.1, sysid::identify_friction_inertia), written as the [axes.drive] keys
// of a machine file.
#include "app/commands_sysid.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/machine.hpp"
#include "core/hash.hpp"
#include "core/units.hpp"
#include "sysid/friction_inertia.hpp"
#include "sysid/friction_inertia_file.hpp"
#include "sysid/trace_formats.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>

namespace vmsim::app {

namespace {

// --control-gain: one virtual motor radian is one axis unit at the load, 1e-3 m on a linear axis, 1 rad on a rotary.
double load_metres_per_rad(bool rotary) { return rotary ? 1.0 : 1e-3; }

// The identified parameters at the load (--control-gain): linear axis M kg, Fv N s/m, Fc N, offset N; rotary axis
// J kg m^2, N m s/rad, N m, N m.
nlohmann::json load_side(const sysid::IdentifiedDrive& d, bool rotary) {
  const double r = load_metres_per_rad(rotary);
  return {{"unit", rotary ? "N m (torque at the axis)" : "N (force at the load)"},
          {rotary ? "inertia_kg_m2" : "mass_kg", d.inertia_kg_m2 / (r * r)},
          {rotary ? "viscous_Nm_s_per_rad" : "viscous_N_s_per_m", d.viscous_Nm_s_per_rad / (r * r)},
          {rotary ? "coulomb_Nm" : "coulomb_N", d.coulomb_Nm / r},
          {rotary ? "offset_Nm" : "offset_N", d.gravity_Nm / r}};
}

// The motor data: the machine file's axis, then the explicit options on top of it. `given`: the gravity model was
// asked for (--gravity) or taken from the machine file, not left to the fit.
sysid::IdentifyOptions friction_options(const IdentifyFrictionArgs& args, const sysid::AxisTrace& trace, bool& given) {
  const auto gravity = sysid::parse_gravity_model(args.gravity);
  if (!gravity)
    throw core::Error(fmt::format("--gravity: expected auto, none, constant or tilting, found '{}'", args.gravity));
  sysid::IdentifyOptions opt;
  opt.gravity = *gravity;
  given = *gravity != sysid::GravityModel::Auto;
  if (args.axis && !args.machine)
    throw core::Error("--axis names an axis of --machine FILE; give the machine file too");
  if (args.machine) {
    const core::Machine machine = core::load_machine(*args.machine);
    const std::string name = args.axis.value_or("");
    const core::MachineAxis* axis = nullptr;
    std::string names;
    for (const auto& ax : machine.axes) {
      names += (names.empty() ? "" : ", ") + ax.name;
      if (ax.name == name) axis = &ax;
    }
    if (!axis)
      throw core::Error(
          core::located(args.machine->string(), 0, fmt::format("no axis '{}' (the machine has {})", name, names)));
    opt = sysid::identify_options_for_axis(*axis, args.machine->string(), trace, *gravity);
    given = true;
  }
  const bool rotary = trace.rotary;
  if (args.control_gain) {
    if (args.torque_constant_Nm_per_A || args.lead_mm || args.gear_deg_per_rev || args.machine)
      throw core::Error(
          "--control-gain gives the force (torque) at the load directly: it replaces --torque-constant, "
          "--lead-mm, --gear-deg-per-rev and --machine");
    // A virtual motor one radian of which is one axis unit at the load (1 mm, or 1 rad): then Kt i is the load
    // force times 1e-3 m/rad (the load torque on a rotary axis), and the results convert back in load_side().
    opt.axis_per_motor_rad = 1.0;
    opt.torque_constant_Nm_per_A = *args.control_gain * load_metres_per_rad(rotary);
    if (args.smoothing_ms) opt.smoothing_s = *args.smoothing_ms * 1e-3;
    return opt;
  }
  if (args.torque_constant_Nm_per_A) opt.torque_constant_Nm_per_A = *args.torque_constant_Nm_per_A;
  if (args.lead_mm) {
    if (rotary)
      throw core::Error(fmt::format("--lead-mm is for a linear axis; {} gives degrees (use --gear-deg-per-rev)",
                                    args.trace.string()));
    opt.axis_per_motor_rad = *args.lead_mm / (2 * core::units::kPi);
  }
  if (args.gear_deg_per_rev) {
    if (!rotary)
      throw core::Error(fmt::format("--gear-deg-per-rev is for a rotary axis; {} gives millimetres (use --lead-mm)",
                                    args.trace.string()));
    opt.axis_per_motor_rad = *args.gear_deg_per_rev * core::units::kDegToRad / (2 * core::units::kPi);
  }
  if (!(opt.torque_constant_Nm_per_A > 0.0))
    throw core::Error(
        "the motor's torque constant is needed (currents to torques): give --torque-constant NM_PER_A or "
        "--machine FILE --axis NAME");
  if (!(opt.axis_per_motor_rad > 0.0))
    throw core::Error(fmt::format("the {} is needed (axis to motor speed): give {} or --machine FILE --axis NAME",
                                  rotary ? "gear ratio" : "screw lead",
                                  rotary ? "--gear-deg-per-rev DEG" : "--lead-mm MM"));
  if (args.smoothing_ms) opt.smoothing_s = *args.smoothing_ms * 1e-3;
  return opt;
}

void print_result(const IdentifyFrictionArgs& args, const sysid::AxisTrace& trace,
                  const std::vector<std::string>& ignored, const sysid::IdentifyOptions& opt,
                  const sysid::IdentifiedDrive& d) {
  const bool rotary = trace.rotary;
  const char* unit = rotary ? "deg" : "mm";
  const double to_file = rotary ? core::units::kRadToDeg : 1.0;  // axis units (mm, rad) -> the trace's units
  const Eigen::Index n = trace.t_s.size();
  const double duration = trace.t_s[n - 1] - trace.t_s[0];
  std::printf("trace %s: %lld samples over %.3f s (every %.4g ms), %s\n", args.trace.string().c_str(),
              static_cast<long long>(n), duration, duration / static_cast<double>(n - 1) * 1e3,
              trace.position.size() ? (rotary ? "position_deg" : "position_mm")
                                    : (rotary ? "velocity_deg_per_s" : "velocity_mm_per_s"));
  if (!ignored.empty()) std::printf("ignored columns: %s\n", fmt::format("{}", fmt::join(ignored, ", ")).c_str());
  if (args.control_gain)
    std::printf("control signal x %.6g = the %s (--control-gain); below as a virtual motor of one %s per rad\n",
                *args.control_gain, rotary ? "torque at the axis, N m" : "force at the load, N", rotary ? "rad" : "mm");
  std::printf("motor: Kt %.4g N m/A, %s\n", opt.torque_constant_Nm_per_A,
              rotary ? fmt::format("gear {:.6g} deg per motor revolution", opt.axis_per_motor_rad * 360.0).c_str()
                     : fmt::format("screw lead {:.6g} mm", opt.axis_per_motor_rad * 2 * core::units::kPi).c_str());
  std::printf("peaks: |v| %.5g %s/s, |a| %.5g %s/s^2\n", d.peak_velocity * to_file, unit, d.peak_acceleration * to_file,
              unit);
  std::printf("friction law (%d constant-velocity stretches: %d positive, %d negative; fit residual %.4g A rms):\n",
              d.stretches, d.stretches_positive, d.stretches_negative, d.friction_rms_residual_A);
  std::printf("  Coulomb friction   %.6g N m  = %.6g A\n", d.coulomb_Nm, d.coulomb_A);
  std::printf("  viscous friction   %.6g N m s/rad  = %.6g A per (%s/s)\n", d.viscous_Nm_s_per_rad,
              d.viscous_A_s_per_axis_unit / to_file, unit);
  switch (d.gravity) {
    case sysid::GravityModel::None:
      std::printf("  gravity offset     none (not fitted)\n");
      break;
    case sysid::GravityModel::Constant:
      std::printf("  gravity offset     %.6g N m (+- %.2g)  = %.6g A (constant)\n", d.gravity_Nm, d.gravity_stderr_Nm,
                  d.gravity_A);
      break;
    default:
      std::printf("  gravity            %.6g N m (+- %.2g) x sin(angle - %.4g deg)  = %.6g A (tilting)\n", d.gravity_Nm,
                  d.gravity_stderr_Nm, d.gravity_angle_offset_rad * core::units::kRadToDeg, d.gravity_A);
  }
  std::printf("inertia (eq. 2 on %d accelerating samples; residual %.4g A rms):\n", d.accel_samples,
              d.inertia_rms_residual_A);
  std::printf("  J                  %.6g kg m^2 at the motor\n", d.inertia_kg_m2);
  if (args.control_gain) {
    const nlohmann::json l = load_side(d, rotary);
    if (rotary)
      std::printf(
          "at the axis (--control-gain %.6g N m per unit of control): J %.6g kg m^2, viscous %.6g N m s/rad, "
          "Coulomb %.6g N m, offset %.6g N m\n",
          *args.control_gain, l["inertia_kg_m2"].get<double>(), l["viscous_Nm_s_per_rad"].get<double>(),
          l["coulomb_Nm"].get<double>(), l["offset_Nm"].get<double>());
    else
      std::printf(
          "at the load (--control-gain %.6g N per unit of control): M %.6g kg, Fv %.6g N s/m, Fc %.6g N, "
          "offset %.6g N\n",
          *args.control_gain, l["mass_kg"].get<double>(), l["viscous_N_s_per_m"].get<double>(),
          l["coulomb_N"].get<double>(), l["offset_N"].get<double>());
  }
  if (d.coulomb_Nm < 0.0 || d.viscous_Nm_s_per_rad < 0.0 || d.inertia_kg_m2 <= 0.0)
    std::fprintf(stderr,
                 "vmsim: warning: a friction coefficient or the inertia came out negative: the trace does not "
                 "determine it (machine files need values >= 0)\n");
}

nlohmann::json report_json(const IdentifyFrictionArgs& args, const sysid::IdentifyOptions& opt,
                           const sysid::IdentifiedDrive& d, bool rotary) {
  nlohmann::json report;
  report["vmsim"] = VMSIM_VERSION;
  report["command"] = "identify-friction";
  report["inputs"]["trace"] = {{"path", args.trace.string()}, {"sha256", core::sha256_file_hex(args.trace)}};
  if (args.machine)
    report["inputs"]["machine"] = {{"path", args.machine->string()},
                                   {"sha256", core::sha256_file_hex(*args.machine)},
                                   {"axis", args.axis.value_or("")}};
  report["motor"] = {{"torque_constant_Nm_per_A", opt.torque_constant_Nm_per_A},
                     {"axis_per_motor_rad", opt.axis_per_motor_rad}};
  if (args.control_gain) {
    report["control_gain"] = *args.control_gain;
    report["load_side"] = load_side(d, rotary);
  }
  report["friction"] = {{"coulomb_Nm", d.coulomb_Nm},
                        {"coulomb_A", d.coulomb_A},
                        {"viscous_Nm_s_per_rad", d.viscous_Nm_s_per_rad},
                        {"gravity", sysid::gravity_model_name(d.gravity)},
                        {"gravity_Nm", d.gravity_Nm},
                        {"gravity_stderr_Nm", d.gravity_stderr_Nm},
                        {"gravity_angle_offset_deg", d.gravity_angle_offset_rad * core::units::kRadToDeg},
                        {"stretches", d.stretches},
                        {"rms_residual_A", d.friction_rms_residual_A}};
  report["inertia"] = {{"inertia_kg_m2", d.inertia_kg_m2},
                       {"accelerating_samples", d.accel_samples},
                       {"rms_residual_A", d.inertia_rms_residual_A}};
  report["files"] = {"drive_identified.toml", "friction_fit.csv", "report.json"};
  return report;
}

}  // namespace

int run_identify_friction(const IdentifyFrictionArgs& args) {
  require_utf8_input(args.trace, "the trace");
  std::vector<std::string> ignored;
  sysid::TraceChannels channels;
  if (args.mat) channels.variables = sysid::parse_mat_variables(*args.mat);
  channels.unit = args.trace_unit;
  const sysid::AxisTrace trace = sysid::read_axis_trace(args.trace, channels, &ignored);
  bool gravity_given = false;
  const sysid::IdentifyOptions opt = friction_options(args, trace, gravity_given);
  const sysid::IdentifiedDrive d = sysid::identify_friction_inertia(trace, opt);
  print_result(args, trace, ignored, opt, d);
  if (!args.out_dir) return 0;

  // Written in staging, swapped into place whole (core/output_dir.hpp).
  core::OutputDir out(*args.out_dir, "vmsim identify-friction");
  const std::filesystem::path dir = out.path();
  const bool write_gravity = sysid::gravity_is_written(d, gravity_given);
  core::write_file_atomic(
      dir / "drive_identified.toml",
      sysid::identified_drive_toml(d, opt, trace.rotary, args.trace.filename().string(), write_gravity));
  core::write_file_atomic(dir / "friction_fit.csv", sysid::friction_points_csv(d, trace.rotary));
  write_report(dir / "report.json", report_json(args, opt, d, trace.rotary));  // and report.html
  out.commit();
  const std::filesystem::path shown = out.target();
  std::printf("wrote %s, %s, %s\n", (shown / "drive_identified.toml").string().c_str(),
              (shown / "friction_fit.csv").string().c_str(), (shown / "report.json").string().c_str());
  return 0;
}

}  // namespace vmsim::app
