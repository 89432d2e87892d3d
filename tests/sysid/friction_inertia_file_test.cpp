// The friction and inertia identification between machine files (sysid/friction_inertia_file): the motor data and
// gravity model taken from the Mikron UCP 710's axes (parts/machines, the reference for the values), and the
// written [axes.drive] keys read back by the machine-file reader (core/machine, an independent reader of the keys
// parts/README.md documents) inside a machine file.
#include "core/error.hpp"
#include "core/machine.hpp"
#include "core/units.hpp"
#include "sysid/friction_inertia_file.hpp"
#include "tests/test_paths.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

namespace vmsim::sysid {
namespace {

using vmsim::test::kMikronMachine;

const core::MachineAxis& machine_axis(const core::Machine& m, const std::string& name) {
  for (const auto& a : m.axes)
    if (a.name == name) return a;
  throw core::Error("no axis " + name);
}

AxisTrace trace(bool rotary) {
  AxisTrace t;
  t.rotary = rotary;
  t.source = rotary ? "a_trace.csv" : "x_trace.csv";
  return t;
}

// The [axes.drive] keys identification leaves alone (loop gains, winding), to complete a drive table.
const char* kLoopKeys =
    "kv_1000_per_min = 6.0\nvelocity_loop_period_us = 125.0\nvelocity_kp_A_s_per_rad = 6.47\nvelocity_tn_ms = 4.0\n"
    "current_limit_A = 30.0\ncurrent_loop_period_us = 62.5\ncurrent_kp_V_per_A = 56.5\ncurrent_tn_ms = 10.0\n"
    "resistance_ohm = 0.6\ninductance_mH = 6.0\nvoltage_limit_V = 300.0\n";

std::string axis_table(const char* name, bool rotary) {
  return std::string("\n[[axes]]\nname = \"") + name + "\"\ntype = \"" + (rotary ? "rotary" : "linear") + "\"\n" +
         (rotary ? "travel_deg = [-120.0, 120.0]\nmax_velocity_deg_per_s = 90.0\nmax_acceleration_deg_per_s2 = 200.0\n"
                   "max_jerk_deg_per_s3 = 2000.0\n"
                 : "travel_mm = [-100.0, 100.0]\nmax_velocity_m_per_min = 30.0\nmax_acceleration_m_per_s2 = 2.5\n"
                   "max_jerk_m_per_s3 = 10.0\n");
}

// A machine whose X and A drives are the written tables (plus the loop keys), read back by core::load_machine.
core::Machine read_back(const std::string& x_drive, const std::string& a_drive) {
  const std::string text = "[machine]\nname = \"read back\"\nkinematics = \"xyz\"\n" + axis_table("X", false) + "\n" +
                           x_drive + kLoopKeys + axis_table("Y", false) + axis_table("Z", false) +
                           axis_table("A", true) + "\n" + a_drive + kLoopKeys;
  std::random_device rd;
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("vmsim_drive_readback_" + std::to_string(rd()) + ".toml");
  std::ofstream(file) << text;
  core::Machine m;
  try {
    m = core::load_machine(file);
  } catch (...) {
    std::filesystem::remove(file);
    throw;
  }
  std::filesystem::remove(file);
  return m;
}

IdentifiedDrive drive(GravityModel g, double gravity_Nm, double stderr_Nm) {
  IdentifiedDrive d;
  d.coulomb_Nm = 1.234567;
  d.viscous_Nm_s_per_rad = 0.00512345;
  d.inertia_kg_m2 = 0.0103456;
  d.gravity = g;
  d.gravity_Nm = gravity_Nm;
  d.gravity_stderr_Nm = stderr_Nm;
  d.gravity_angle_offset_rad = 0.1;
  d.stretches = 8, d.stretches_positive = 4, d.stretches_negative = 4, d.accel_samples = 5000;
  return d;
}

TEST(FrictionInertiaFile, MotorDataAndGravityComeFromTheMachineAxis) {
  const core::Machine m = core::load_machine(kMikronMachine);
  IdentifyOptions o = identify_options_for_axis(machine_axis(m, "X"), kMikronMachine, trace(false), GravityModel::Auto);
  EXPECT_EQ(o.torque_constant_Nm_per_A, 1.5);
  EXPECT_NEAR(o.axis_per_motor_rad * 2 * core::units::kPi, 20.0, 1e-12);  // the 20 mm screw
  EXPECT_EQ(o.gravity, GravityModel::None);
  EXPECT_EQ(identify_options_for_axis(machine_axis(m, "Z"), kMikronMachine, trace(false), GravityModel::Auto).gravity,
            GravityModel::Constant);
  EXPECT_EQ(identify_options_for_axis(machine_axis(m, "Z"), kMikronMachine, trace(false), GravityModel::None).gravity,
            GravityModel::None)
      << "a model asked for wins over the machine file's";
  o = identify_options_for_axis(machine_axis(m, "A"), kMikronMachine, trace(true), GravityModel::Auto);
  EXPECT_NEAR(o.axis_per_motor_rad * 2 * core::units::kPi * core::units::kRadToDeg, 4.0, 1e-12);  // 4 deg per rev
  EXPECT_EQ(o.gravity, GravityModel::Tilting);
  try {
    identify_options_for_axis(machine_axis(m, "A"), kMikronMachine, trace(false), GravityModel::Auto);
    ADD_FAILURE() << "a trace in mm was accepted for a rotary axis";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("axis A is rotary but the trace x_trace.csv gives millimetres"),
              std::string::npos)
        << e.what();
  }
  core::MachineAxis bare = machine_axis(m, "X");
  bare.drive.reset();
  EXPECT_THROW(identify_options_for_axis(bare, kMikronMachine, trace(false), GravityModel::Auto), core::Error);
}

TEST(FrictionInertiaFile, GravityIsWrittenWhenAskedForOrOutOfTheNoise) {
  EXPECT_FALSE(gravity_is_written(drive(GravityModel::None, 5.0, 0.1), true));
  EXPECT_TRUE(gravity_is_written(drive(GravityModel::Constant, 0.2, 0.1), true));
  EXPECT_FALSE(gravity_is_written(drive(GravityModel::Constant, 0.2, 0.1), false)) << "2 standard errors";
  EXPECT_TRUE(gravity_is_written(drive(GravityModel::Constant, -0.4, 0.1), false)) << "4 standard errors";
}

TEST(FrictionInertiaFile, TheWrittenKeysReadBackAsTheIdentifiedDrive) {
  IdentifyOptions lin;
  lin.torque_constant_Nm_per_A = 1.45;
  lin.axis_per_motor_rad = 16.0 / (2 * core::units::kPi);
  IdentifyOptions rot;
  rot.torque_constant_Nm_per_A = 1.5;
  rot.axis_per_motor_rad = 4.0 * core::units::kDegToRad / (2 * core::units::kPi);
  const IdentifiedDrive x = drive(GravityModel::Constant, 2.9876, 0.01);
  const IdentifiedDrive a = drive(GravityModel::Tilting, 1.1234, 0.01);
  const std::string xt = identified_drive_toml(x, lin, false, "x_trace.csv", true);
  const std::string at = identified_drive_toml(a, rot, true, "a_trace.csv", true);
  EXPECT_EQ(xt.rfind("# vmsim identify-friction x_trace.csv", 0), 0u) << xt;
  const core::Machine m = read_back(xt, at);
  const core::DriveParams& dx = *machine_axis(m, "X").drive;
  EXPECT_NEAR(dx.torque_constant_Nm_per_A, 1.45, 1e-12);
  EXPECT_NEAR(dx.axis_per_motor_rad, lin.axis_per_motor_rad, 1e-12);
  EXPECT_NEAR(dx.inertia_kg_m2, x.inertia_kg_m2,
              5e-6 * x.inertia_kg_m2);  // 6 significant digits: half a unit of the 6th
  EXPECT_NEAR(dx.coulomb_Nm, x.coulomb_Nm, 5e-6 * x.coulomb_Nm);
  EXPECT_NEAR(dx.viscous_Nm_s_per_rad, x.viscous_Nm_s_per_rad, 5e-6 * x.viscous_Nm_s_per_rad);
  EXPECT_EQ(dx.gravity, core::DriveParams::Gravity::Constant);
  EXPECT_NEAR(dx.gravity_Nm, 2.9876, 1e-9);
  const core::DriveParams& da = *machine_axis(m, "A").drive;
  EXPECT_NEAR(da.axis_per_motor_rad, rot.axis_per_motor_rad, 1e-12);
  EXPECT_EQ(da.gravity, core::DriveParams::Gravity::Tilting);
  EXPECT_NEAR(da.gravity_Nm, 1.1234, 1e-9);
  EXPECT_NEAR(da.gravity_angle_offset_rad, 0.1, 1e-6);

  // A gravity term left out is written as none, the fitted value only in a comment.
  const std::string quiet = identified_drive_toml(x, lin, false, "x_trace.csv", false);
  EXPECT_NE(quiet.find("fitted offset 2.99 +- 0.01 N m: not significant"), std::string::npos) << quiet;
  EXPECT_EQ(machine_axis(read_back(quiet, at), "X").drive->gravity, core::DriveParams::Gravity::None);
}

TEST(FrictionInertiaFile, FrictionPointsInTheTracesUnits) {
  IdentifiedDrive d;
  d.points.push_back({0.5, 1.5, 8000, 1.0, 0.0, 2.25, 2.5});
  const std::string deg = friction_points_csv(d, true);
  EXPECT_EQ(deg,
            "velocity_deg_per_s,measured_mean_current_A,fitted_current_A,samples,t_start_s,t_end_s\n"
            "57.2957795,2.25,2.5,8000,0.500000,1.500000\n");
  EXPECT_EQ(friction_points_csv(d, false).substr(0, 18), "velocity_mm_per_s,");
}

}  // namespace
}  // namespace vmsim::sysid
