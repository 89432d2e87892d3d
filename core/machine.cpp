#include "core/machine.hpp"

#include "core/error.hpp"
#include "core/toml_reader.hpp"
#include "core/toolpath.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

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
  t.finish();
  return ax;
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
    m.kinematics = mt.opt_choice("kinematics", {"xyz"}).value_or("xyz");
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
  top.finish();
  return m;
}

}  // namespace vmsim::core
