#pragma once
// The machine as the NC and the simulation see it: its axes, their travel and kinematic limits.
// Loaded from a machine file (parts/machines/*.toml) in the trade's units and converted once, here.
#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::core {

enum class AxisKind { Linear, Rotary };

struct MachineAxis {
  std::string name;              // "X", "Y", "Z", "A", "B" or "C": the program word that drives it
  int program_axis = 0;          // index into Vec6 (ProgramAxis)
  AxisKind kind = AxisKind::Linear;
  // Axis units are mm for linear axes and rad for rotary ones; limits are in axis units per s, s^2, s^3.
  double travel_min = 0.0, travel_max = 0.0;
  bool continuous = false;       // a rotary axis without travel limits (C tables)
  double max_velocity = 0.0;
  double max_acceleration = 0.0;
  double max_jerk = 0.0;
};

struct Machine {
  std::string name;
  std::string source_file;
  std::string kinematics = "xyz";  // "xyz": Cartesian 3-axis, program X Y Z drive the axes directly
  std::vector<MachineAxis> axes;

  // Index of the axis driven by program word `program_axis`, or -1 when the machine has no such axis.
  int axis_index(int program_axis) const;
};

// Reads a machine file; unknown keys, wrong types and impossible values are errors naming file, line and key.
Machine load_machine(const std::filesystem::path& path);

}  // namespace vmsim::core
