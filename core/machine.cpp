#include "core/machine.hpp"

#include "core/error.hpp"
#include "core/toml_reader.hpp"
#include "core/toolpath.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>

#include <cmath>

namespace vmsim::core {

int Machine::axis_index(int program_axis) const {
  for (std::size_t i = 0; i < axes.size(); ++i)
    if (axes[i].program_axis == program_axis) return static_cast<int>(i);
  return -1;
}

namespace {

int program_axis_of(const std::string& name) {
  static const char* names[] = {"X", "Y", "Z", "A", "B", "C"};
  for (int i = 0; i < 6; ++i)
    if (name == names[i]) return i;
  return -1;
}

DriveParams read_drive(const TomlTable& t, const MachineAxis& ax) {
  DriveParams d;
  const bool linear = ax.kind == AxisKind::Linear;
  d.kv_per_s = t.positive("kv_1000_per_min") * units::kKvMPerMinPerMmToPerS;
  d.kf = t.opt_nonnegative("kf").value_or(0.0);
  d.ka = t.opt_nonnegative("ka").value_or(0.0);
  auto samples = [&](const char* key) {
    const long long n = t.opt_integer(key).value_or(0);
    if (n < 0 || n > 100) t.fail(key, fmt::format("expected 0..100 samples, found {}", n));
    return static_cast<int>(n);
  };
  d.position_delay_samples = samples("position_delay_samples");
  d.feedforward_delay_samples = samples("feedforward_delay_samples");
  d.velocity_period_s = t.positive("velocity_loop_period_us") * 1e-6;
  d.velocity_kp_A_s_per_rad = t.positive("velocity_kp_A_s_per_rad");
  d.velocity_tn_s = t.positive("velocity_tn_ms") * 1e-3;
  d.current_limit_A = t.positive("current_limit_A");
  d.current_period_s = t.positive("current_loop_period_us") * 1e-6;
  if (d.current_period_s > d.velocity_period_s)
    t.fail("current_loop_period_us", "expected a period no longer than the velocity loop's");
  d.current_kp_V_per_A = t.positive("current_kp_V_per_A");
  d.current_tn_s = t.positive("current_tn_ms") * 1e-3;
  d.resistance_ohm = t.positive("resistance_ohm");
  d.inductance_H = t.positive("inductance_mH") * 1e-3;
  d.torque_constant_Nm_per_A = t.positive("torque_constant_Nm_per_A");
  d.voltage_limit_V = t.positive("voltage_limit_V");
  d.inertia_kg_m2 = t.positive("inertia_kg_m2");
  d.coulomb_Nm = t.opt_nonnegative("coulomb_friction_Nm").value_or(0.0);
  d.viscous_Nm_s_per_rad = t.opt_nonnegative("viscous_friction_Nm_s_per_rad").value_or(0.0);
  if (auto st = t.opt_nonnegative("stribeck_static_Nm")) {
    if (*st <= d.coulomb_Nm) t.fail("stribeck_static_Nm", "expected a breakaway torque above coulomb_friction_Nm");
    d.stribeck_static_Nm = *st;
    d.stribeck_velocity_rad_per_s = t.positive("stribeck_velocity_rad_per_s");
  }
  if (linear) {
    d.axis_per_motor_rad = t.positive("screw_lead_mm") / (2 * units::kPi);
  } else {
    d.axis_per_motor_rad = t.positive("gear_deg_per_motor_rev") * units::kDegToRad / (2 * units::kPi);
  }
  const std::string g = t.opt_choice("gravity", {"none", "constant", "tilting"}).value_or("none");
  if (g != "none") {
    d.gravity = g == "constant" ? DriveParams::Gravity::Constant : DriveParams::Gravity::Tilting;
    if (g == "tilting" && linear) t.fail("gravity", "\"tilting\" is for rotary axes (a linear axis is \"constant\")");
    d.gravity_Nm = t.number("gravity_torque_Nm");
    d.gravity_angle_offset_rad = t.opt_number("gravity_angle_offset_deg").value_or(0.0) * units::kDegToRad;
  }
  t.finish();
  return d;
}

MachineAxis read_axis(const TomlTable& t) {
  // A limit that is finite in the file can overflow in the unit conversion (1e308 m/min); an infinite limit
  // would silently switch off the check it stands for.
  const auto limit = [&t](const char* key, double factor) {
    const double v = t.positive(key) * factor;
    if (!std::isfinite(v)) t.fail(key, "expected a finite limit (the value overflows when converted to mm or rad)");
    return v;
  };
  MachineAxis ax;
  ax.name = t.choice("name", {"X", "Y", "Z", "A", "B", "C"});
  ax.program_axis = program_axis_of(ax.name);
  const std::string type = t.choice("type", {"linear", "rotary"});
  ax.kind = type == "linear" ? AxisKind::Linear : AxisKind::Rotary;
  if ((ax.program_axis < 3) != (ax.kind == AxisKind::Linear))
    t.fail("type", fmt::format("axis {} must be {}", ax.name, ax.program_axis < 3 ? "linear" : "rotary"));
  if (ax.kind == AxisKind::Linear) {
    auto travel = t.numbers("travel_mm", 2);
    ax.travel_min = travel[0];
    ax.travel_max = travel[1];
    ax.max_velocity = limit("max_velocity_m_per_min", units::kMPerMinToMmPerS);
    ax.max_acceleration = limit("max_acceleration_m_per_s2", units::kMPerS2ToMmPerS2);
    ax.max_jerk = limit("max_jerk_m_per_s3", units::kMPerS3ToMmPerS3);
  } else {
    if (auto travel = t.opt_numbers("travel_deg", 2)) {
      ax.travel_min = (*travel)[0] * units::kDegToRad;
      ax.travel_max = (*travel)[1] * units::kDegToRad;
    } else {
      ax.continuous = true;
      ax.travel_min = -1e300;
      ax.travel_max = 1e300;
    }
    ax.max_velocity = limit("max_velocity_deg_per_s", units::kDegToRad);
    ax.max_acceleration = limit("max_acceleration_deg_per_s2", units::kDegToRad);
    ax.max_jerk = limit("max_jerk_deg_per_s3", units::kDegToRad);
  }
  if (!ax.continuous && !(ax.travel_min < ax.travel_max))
    t.fail(ax.kind == AxisKind::Linear ? "travel_mm" : "travel_deg", "expected [min, max] with min < max");
  // Documentation of where each value comes from; read so that it is not an unknown key.
  (void)t.opt_string("source");
  if (auto d = t.opt_table("drive")) ax.drive = read_drive(*d, ax);
  t.finish();
  return ax;
}

// A unit vector from a 3-number key; a zero (or denormal) vector has no direction.
Eigen::Vector3d unit_vector(const TomlTable& t, const std::string& key) {
  const auto v = t.numbers(key, 3);
  const Eigen::Vector3d d(v[0], v[1], v[2]);
  const double n = d.norm();
  if (!(n > 1e-9) || !std::isfinite(n)) t.fail(key, "expected a direction: three numbers, not all zero");
  return d / n;
}

// "file:line:col" of a node of the file, for messages that come after loading (the chain's family, its inverse).
std::string location(const toml::table& root, const std::string& file, const std::string& path) {
  const toml::node_view<const toml::node> n = root.at_path(path);
  if (n && n.node()->source().begin.line > 0)
    return fmt::format("{}:{}:{}", file, n.node()->source().begin.line, n.node()->source().begin.column);
  return file;
}

// [kinematics] of a kinematics = "chain" machine: the two chains, their fixed offsets, and the checks a chain
// needs before any transform can use it (each machine axis in exactly one joint, joint types matching the axes,
// directions that are directions, linear joints that span space).
KinematicChain read_chain(const TomlTable& kt, const toml::table& root, const Machine& m) {
  KinematicChain ch;
  if (auto o = kt.opt_numbers("workpiece_origin_mm", 3)) ch.workpiece_origin_mm = {(*o)[0], (*o)[1], (*o)[2]};
  if (auto g = kt.opt_numbers("gauge_point_mm", 3)) ch.gauge_point_mm = {(*g)[0], (*g)[1], (*g)[2]};
  if (kt.has("tool_direction")) ch.tool_direction = unit_vector(kt, "tool_direction");
  // Which chain and joint uses each program axis, for "used twice" messages.
  std::string used_by[6];
  for (const char* chain_key : {"workpiece", "tool"}) {
    std::vector<ChainJoint>& joints = std::string(chain_key) == "workpiece" ? ch.workpiece : ch.tool;
    const std::vector<TomlTable> tables = kt.array_of_tables(chain_key);
    for (std::size_t i = 0; i < tables.size(); ++i) {
      const TomlTable& jt = tables[i];
      ChainJoint j;
      const std::string name = jt.choice("axis", {"X", "Y", "Z", "A", "B", "C"});
      j.program_axis = program_axis_of(name);
      const std::string here = fmt::format("kinematics.{}[{}]", chain_key, i);
      if (!used_by[j.program_axis].empty())
        jt.fail("axis", fmt::format("axis {} is already the joint {} (each axis drives one joint)", name,
                                    used_by[j.program_axis]));
      used_by[j.program_axis] = here;
      const int ai = m.axis_index(j.program_axis);
      if (ai < 0) jt.fail("axis", fmt::format("the machine has no axis {} (expected one of its [[axes]])", name));
      const std::string type = jt.choice("type", {"linear", "rotary"});
      j.kind = type == "linear" ? AxisKind::Linear : AxisKind::Rotary;
      if (j.kind != m.axes[static_cast<std::size_t>(ai)].kind)
        jt.fail("type", fmt::format("axis {} is a {} axis in [[axes]]", name,
                                    j.kind == AxisKind::Linear ? "rotary" : "linear"));
      j.direction = unit_vector(jt, "direction");
      if (j.kind == AxisKind::Rotary) {
        const auto p = jt.numbers("point_mm", 3);
        j.point_mm = {p[0], p[1], p[2]};
      } else if (jt.has("point_mm")) {
        jt.fail("point_mm", "a linear joint has no axis point (point_mm is for rotary joints)");
      }
      j.where = location(root, jt.file(), here);
      jt.finish();
      joints.push_back(std::move(j));
    }
  }
  for (const MachineAxis& ax : m.axes)
    if (used_by[ax.program_axis].empty())
      kt.fail("workpiece", fmt::format("axis {} is in neither chain (expected a joint with axis = \"{}\" in "
                                       "kinematics.workpiece or kinematics.tool)",
                                       ax.name, ax.name));
  // The linear joints must span space with every joint at zero, or no tip position can be reached uniquely.
  Eigen::Matrix3d lin = Eigen::Matrix3d::Zero();
  int n = 0;
  for (const auto* chain : {&ch.workpiece, &ch.tool})
    for (const ChainJoint& j : *chain)
      if (j.kind == AxisKind::Linear && n < 3) lin.col(n++) = j.direction;
  if (n == 3 && std::abs(lin.determinant()) < 1e-6)
    kt.fail("tool", "the linear joints' directions are (nearly) parallel to one plane: X, Y and Z must span space");
  kt.finish();
  return ch;
}

}  // namespace

Machine load_machine(const std::filesystem::path& path) {
  const toml::table root = parse_toml_file(path);
  TomlTable top(root, path.string(), "");
  Machine m;
  m.source_file = path.string();
  {
    TomlTable mt = top.table("machine");
    m.name = mt.string("name");
    m.kinematics = mt.opt_choice("kinematics", {"xyz", "chain"}).value_or("xyz");
    (void)mt.opt_string("source");
    mt.finish();
  }
  for (const TomlTable& at : top.array_of_tables("axes")) {
    MachineAxis ax = read_axis(at);
    if (m.axis_index(ax.program_axis) >= 0) at.fail("name", "axis " + ax.name + " is defined twice");
    m.axes.push_back(ax);
  }
  if (m.axes.empty()) top.fail("axes", "expected at least one [[axes]] table");
  for (const char* needed : {"X", "Y", "Z"})
    if (m.axis_index(program_axis_of(needed)) < 0)
      top.fail("axes", fmt::format("kinematics \"{}\" needs an axis named {}", m.kinematics, needed));
  if (m.kinematics == "chain") {
    if (!top.has("kinematics"))
      top.fail("machine", "kinematics = \"chain\" needs a [kinematics] table with the workpiece and tool chains");
    m.chain = read_chain(top.table("kinematics"), root, m);
  } else if (top.has("kinematics")) {
    top.fail("kinematics", "a [kinematics] table needs kinematics = \"chain\" in [machine]");
  }
  top.finish();
  return m;
}

}  // namespace vmsim::core
