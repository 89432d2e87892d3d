#pragma once
// The machine as the NC and the simulation see it: its axes, their travel and kinematic limits.
// Loaded from a machine file (parts/machines/*.toml) in the trade's units and converted once, here.
#include <Eigen/Core>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::core {

enum class AxisKind { Linear, Rotary };

// The axis drive of the feed-drive simulation paper Fig. 2 / Duong et al. Fig. 6: position loop at Te (P + velocity and
// torque feedforward, each path with its "delay"), velocity PI, current PI on the motor, mechanics. SI units on the
// motor side; `axis_per_motor_rad` converts motor angle to axis units (mm or rad).
struct DriveParams {
  // Position loop (period: the job's Te).
  double kv_per_s = 100.0;  // Kv; files give it in (m/min)/mm = 1000/min: 1 (m/min)/mm = 16.667 1/s
  double kf = 0.0;          // velocity feedforward gain (1 = full)
  double ka = 0.0;          // torque feedforward gain on J * a_d (1 = full)
  int position_delay_samples =
      0;  // dead time of the position path, in Te (the feed-drive simulation paper section 2.2)
  int feedforward_delay_samples = 0;  // dead time of the feedforward paths, in Te
  // Velocity loop: PI from motor speed error (rad/s) to current setpoint (A), saturated at current_limit_A.
  double velocity_period_s = 125e-6;
  double velocity_kp_A_s_per_rad = 1.0;
  double velocity_tn_s = 0.005;  // integral action time
  double current_limit_A = 20.0;
  // Current loop: PI from current error (A) to motor voltage (V), saturated at voltage_limit_V, on R-L + back-EMF.
  double current_period_s = 62.5e-6;
  double current_kp_V_per_A = 50.0;
  double current_tn_s = 0.010;
  double resistance_ohm = 1.0;
  double inductance_H = 0.01;
  double torque_constant_Nm_per_A = 1.5;  // also the back-EMF constant in V s/rad (SI)
  double voltage_limit_V = 300.0;
  // Mechanics at the motor shaft: J dw/dt = Kt i - B w - friction(w) - gravity.
  double inertia_kg_m2 = 0.01;
  double coulomb_Nm = 0.0;
  double viscous_Nm_s_per_rad = 0.0;
  double stribeck_static_Nm = 0.0;  // 0: no Stribeck term; else breakaway torque > coulomb_Nm
  double stribeck_velocity_rad_per_s = 1.0;
  double axis_per_motor_rad = 20.0 / (2 * 3.14159265358979323846);  // screw lead / 2 pi, or gear ratio
  // Gravity torque at the motor: none, constant (vertical axis), or gravity_Nm * sin(angle - offset) (tilting).
  enum class Gravity { None, Constant, Tilting } gravity = Gravity::None;
  double gravity_Nm = 0.0;
  double gravity_angle_offset_rad = 0.0;
};

struct MachineAxis {
  std::string name;      // "X", "Y", "Z", "A", "B" or "C": the program word that drives it
  int program_axis = 0;  // index into Vec6 (ProgramAxis)
  AxisKind kind = AxisKind::Linear;
  // Axis units are mm for linear axes and rad for rotary ones; limits are in axis units per s, s^2, s^3.
  double travel_min = 0.0, travel_max = 0.0;
  bool continuous = false;  // a rotary axis without travel limits (C tables)
  double max_velocity = 0.0;
  double max_acceleration = 0.0;
  double max_jerk = 0.0;
  std::optional<DriveParams> drive;  // [axes.drive]; absent: the axis cannot be simulated through its drive
};

// One joint of a kinematic chain ([kinematics] workpiece / tool in the machine file). Every direction and point is
// given in the machine's base frame with every joint at zero (the "product of exponentials" description of a serial
// chain: Brockett 1984; Lynch & Park, Modern Robotics, section 4.1): the joint at value q translates everything after
// it in its chain by q * direction (linear, mm), or turns it by q about the line through point_mm along direction,
// right-handed (rotary, rad).
struct ChainJoint {
  int program_axis = 0;  // the machine axis (ProgramAxis index: X Y Z A B C) whose position is this joint's value
  AxisKind kind = AxisKind::Linear;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  // unit vector
  Eigen::Vector3d point_mm = Eigen::Vector3d::Zero();    // rotary joints: a point on the axis
  std::string where;  // "file:line:col" of the joint in the machine file, for messages
};

// kinematics = "chain": two serial chains from the machine's base, one carrying the workpiece (the table stack),
// one carrying the tool (the head stack), documented in parts/README.md.
struct KinematicChain {
  std::vector<ChainJoint> workpiece;                              // base -> workpiece, in order
  std::vector<ChainJoint> tool;                                   // base -> spindle nose, in order
  Eigen::Vector3d workpiece_origin_mm = Eigen::Vector3d::Zero();  // workpiece zero in the base frame, joints at zero
  Eigen::Vector3d gauge_point_mm = Eigen::Vector3d::Zero();       // spindle nose (gauge point), joints at zero
  Eigen::Vector3d tool_direction = Eigen::Vector3d::UnitZ();      // unit, tip -> spindle, joints at zero
};

struct Machine {
  std::string name;
  std::string source_file;
  // "xyz": Cartesian 3-axis, program X Y Z drive the axes directly; "chain": the chains in `chain`.
  std::string kinematics = "xyz";
  std::vector<MachineAxis> axes;
  std::optional<KinematicChain> chain;  // kinematics == "chain"

  // Index of the axis driven by program word `program_axis`, or -1 when the machine has no such axis.
  int axis_index(int program_axis) const;
};

// Reads a machine file; unknown keys, wrong types and impossible values are errors naming file, line and key.
Machine load_machine(const std::filesystem::path& path);

}  // namespace vmsim::core
