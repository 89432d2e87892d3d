// Friction and inertia identification (the feed-drive simulation paper section 3.1). Reference: the parameters of the
// simulated axis itself. The cascade drive model (drives/cascade_axis) with the Mikron UCP 710's X, Z and A drives runs
// the excitation the feed-drive simulation paper describes (constant-velocity moves at several speeds both ways,
// accelerated moves between them); its current gets Gaussian noise (fixed seed) and its position an encoder's 0.1 um
// quantisation; the identification must return the model's Coulomb and viscous friction, gravity and inertia within 2
// %.
#include "core/error.hpp"
#include "core/machine.hpp"
#include "core/units.hpp"
#include "drives/cascade_axis.hpp"
#include "sysid/friction_inertia.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

using namespace vmsim;
using namespace vmsim::drives;
using namespace vmsim::sysid;

namespace {

using vmsim::core::units::kPi;

core::MachineAxis mikron_axis(const std::string& name) {
  const core::Machine m = core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml");
  for (const auto& ax : m.axes)
    if (ax.name == name) return ax;
  throw std::runtime_error("no axis " + name);
}

// Setpoints every Te: from rest at x0, for each speed a smooth ramp (velocity V sin^2, peak acceleration a_max),
// a cruise of `cruise_s`, a ramp down and a 0.15 s rest; speeds alternate in sign so the axis comes back.
struct Excitation {
  std::vector<double> x;  // position setpoints, axis units
};

Excitation excitation(double x0, const std::vector<double>& speeds, double a_max, double cruise_s, double te) {
  Excitation e;
  double x = x0;
  e.x.push_back(x);
  auto run = [&](double duration, auto velocity) {
    const int n = static_cast<int>(std::lround(duration / te));
    for (int k = 1; k <= n; ++k) {
      x += 0.5 * (velocity((k - 1) * te) + velocity(k * te)) * te;
      e.x.push_back(x);
    }
  };
  for (double v : speeds) {
    const double tr = std::max(0.05, kPi * std::abs(v) / (2 * a_max));
    run(tr, [&](double t) { return v * std::pow(std::sin(kPi * t / (2 * tr)), 2); });
    run(cruise_s, [&](double) { return v; });
    run(tr, [&](double t) { return v * std::pow(std::cos(kPi * t / (2 * tr)), 2); });
    run(0.15, [](double) { return 0.0; });
  }
  return e;
}

// The drive following the setpoints, measured as a drive's servo trace does it: every current-loop period
// (62.5 us), position quantised to `quantum`, current with Gaussian noise. (Sampled once per Te, the current would
// always be caught at the same phase of the sawtooth the position loop's held output drives: see identify.hpp.)
AxisTrace simulate(const core::MachineAxis& ax, const Excitation& e, double te, double noise_A, double quantum,
                   unsigned seed, bool velocity_column = false) {
  CascadeAxis axis(*ax.drive, te, ax.kind);
  axis.reset(e.x.front());
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_A);
  const auto steps = static_cast<Eigen::Index>(e.x.size()) + 200;  // 0.2 s settling at the end
  const int inner = axis.inner_steps();
  const double tc = axis.current_period_s();
  const Eigen::Index n = steps * inner;
  AxisTrace tr;
  tr.source = "simulated " + ax.name;
  tr.t_s.resize(n);
  tr.current_A.resize(n);
  (velocity_column ? tr.velocity : tr.position).resize(n);
  std::vector<InnerSample> period(static_cast<std::size_t>(inner));
  double prev = e.x.front(), prev_v = 0.0;
  for (Eigen::Index k = 0; k < steps; ++k) {
    const double xd = e.x[std::min<std::size_t>(k, e.x.size() - 1)];
    AxisCommand c;
    c.position = xd;
    c.velocity = (xd - prev) / te;  // backward differences, as the NC sends them
    c.acceleration = (c.velocity - prev_v) / te;
    prev = xd, prev_v = c.velocity;
    axis.step(c, period.data());
    for (int j = 0; j < inner; ++j) {
      const InnerSample& s = period[j];
      const Eigen::Index m = k * inner + j;
      tr.t_s[m] = k * te + j * tc;
      tr.current_A[m] = s.current_A + noise(rng);
      if (velocity_column)
        tr.velocity[m] = s.velocity;
      else
        tr.position[m] = quantum > 0 ? quantum * std::round(s.position / quantum) : s.position;
    }
  }
  return tr;
}

IdentifyOptions options_for(const core::MachineAxis& ax) {
  IdentifyOptions o;
  o.torque_constant_Nm_per_A = ax.drive->torque_constant_Nm_per_A;
  o.axis_per_motor_rad = ax.drive->axis_per_motor_rad;
  return o;
}

double rel(double got, double want) { return std::abs(got - want) / std::abs(want); }

void print(const char* what, const IdentifiedDrive& d, const core::DriveParams& p) {
  std::printf(
      "%s: Coulomb %.4f N m (%+.2f %%), viscous %.6f N m s/rad (%+.2f %%), inertia %.5f kg m^2 (%+.2f %%), "
      "gravity %.4f N m, %d stretches, %d accelerating samples, residuals %.4f / %.4f A\n",
      what, d.coulomb_Nm, 100 * (d.coulomb_Nm / p.coulomb_Nm - 1), d.viscous_Nm_s_per_rad,
      100 * (d.viscous_Nm_s_per_rad / p.viscous_Nm_s_per_rad - 1), d.inertia_kg_m2,
      100 * (d.inertia_kg_m2 / p.inertia_kg_m2 - 1), d.gravity_Nm, d.stretches, d.accel_samples,
      d.friction_rms_residual_A, d.inertia_rms_residual_A);
}

const std::vector<double> kSpeedsMPerMin = {0.5, -0.5, 1, -1, 2, -2, 4, -4, 8, -8, 12, -12, 18, -18, 25, -25};

std::vector<double> linear_speeds() {
  std::vector<double> v;
  for (double s : kSpeedsMPerMin) v.push_back(s * core::units::kMPerMinToMmPerS);
  return v;
}

}  // namespace

// X: horizontal ball-screw axis, position trace. Gravity is fitted (auto) and must come out near zero.
TEST(Identify, RecoversHorizontalAxisFromPositionTrace) {
  const core::MachineAxis ax = mikron_axis("X");
  const double te = 1e-3;
  const AxisTrace tr = simulate(ax, excitation(-150.0, linear_speeds(), 2000.0, 0.6, te), te, 0.05, 1e-4, 1);
  const IdentifiedDrive d = identify_friction_inertia(tr, options_for(ax));
  print("X", d, *ax.drive);
  EXPECT_LT(rel(d.coulomb_Nm, ax.drive->coulomb_Nm), 0.02);
  EXPECT_LT(rel(d.viscous_Nm_s_per_rad, ax.drive->viscous_Nm_s_per_rad), 0.02);
  EXPECT_LT(rel(d.inertia_kg_m2, ax.drive->inertia_kg_m2), 0.02);
  EXPECT_EQ(d.gravity, GravityModel::Constant);  // auto: both directions present
  EXPECT_LT(std::abs(d.gravity_Nm), 0.02 * ax.drive->coulomb_Nm);
  EXPECT_EQ(d.stretches, 16);
  EXPECT_EQ(d.stretches_positive, 8);
  EXPECT_NEAR(d.coulomb_A, ax.drive->coulomb_Nm / ax.drive->torque_constant_Nm_per_A, 0.02);
  EXPECT_GT(d.accel_samples, 10000);
}

// The same axis measured by a velocity column instead of positions.
TEST(Identify, RecoversHorizontalAxisFromVelocityTrace) {
  const core::MachineAxis ax = mikron_axis("X");
  const double te = 1e-3;
  const AxisTrace tr = simulate(ax, excitation(-150.0, linear_speeds(), 2000.0, 0.6, te), te, 0.05, 0.0, 2, true);
  IdentifyOptions o = options_for(ax);
  o.gravity = GravityModel::None;
  const IdentifiedDrive d = identify_friction_inertia(tr, o);
  print("X (velocity)", d, *ax.drive);
  EXPECT_LT(rel(d.coulomb_Nm, ax.drive->coulomb_Nm), 0.02);
  EXPECT_LT(rel(d.viscous_Nm_s_per_rad, ax.drive->viscous_Nm_s_per_rad), 0.02);
  EXPECT_LT(rel(d.inertia_kg_m2, ax.drive->inertia_kg_m2), 0.02);
  EXPECT_EQ(d.gravity_Nm, 0.0);
}

// Z: vertical axis carrying 3 N m of gravity at the motor. The half-sum of the currents at +v and -v gives it.
TEST(Identify, RecoversVerticalAxisWithGravity) {
  const core::MachineAxis ax = mikron_axis("Z");
  ASSERT_EQ(ax.drive->gravity, core::DriveParams::Gravity::Constant);
  const double te = 1e-3;
  const AxisTrace tr = simulate(ax, excitation(-150.0, linear_speeds(), 1800.0, 0.6, te), te, 0.05, 1e-4, 3);
  IdentifyOptions o = options_for(ax);
  o.gravity = GravityModel::Constant;
  const IdentifiedDrive d = identify_friction_inertia(tr, o);
  print("Z", d, *ax.drive);
  EXPECT_LT(rel(d.coulomb_Nm, ax.drive->coulomb_Nm), 0.02);
  EXPECT_LT(rel(d.viscous_Nm_s_per_rad, ax.drive->viscous_Nm_s_per_rad), 0.02);
  EXPECT_LT(rel(d.inertia_kg_m2, ax.drive->inertia_kg_m2), 0.02);
  EXPECT_LT(rel(d.gravity_Nm, ax.drive->gravity_Nm), 0.02);
  EXPECT_GT(d.gravity_stderr_Nm, 0.0);
  EXPECT_LT(d.gravity_stderr_Nm, 0.01 * ax.drive->gravity_Nm);
}

// A: tilting table, gravity G sin(angle - offset) through a worm gear; positions in degrees converted to rad.
TEST(Identify, RecoversTiltingAxis) {
  const core::MachineAxis ax = mikron_axis("A");
  ASSERT_EQ(ax.drive->gravity, core::DriveParams::Gravity::Tilting);
  const double te = 1e-3;
  std::vector<double> speeds;
  for (double s : {3.0, -3.0, 6.0, -6.0, 12.0, -12.0, 20.0, -20.0, 30.0, -30.0, 45.0, -45.0})
    speeds.push_back(s * core::units::kDegToRad);
  const AxisTrace tr = simulate(
      ax, excitation(-60 * core::units::kDegToRad, speeds, 150 * core::units::kDegToRad, 1.2, te), te, 0.02, 1e-6, 4);
  IdentifyOptions o = options_for(ax);
  o.gravity = GravityModel::Tilting;
  const IdentifiedDrive d = identify_friction_inertia(tr, o);
  print("A", d, *ax.drive);
  EXPECT_LT(rel(d.coulomb_Nm, ax.drive->coulomb_Nm), 0.02);
  EXPECT_LT(rel(d.viscous_Nm_s_per_rad, ax.drive->viscous_Nm_s_per_rad), 0.02);
  EXPECT_LT(rel(d.inertia_kg_m2, ax.drive->inertia_kg_m2), 0.02);
  EXPECT_LT(rel(d.gravity_Nm, ax.drive->gravity_Nm), 0.02);
  EXPECT_NEAR(d.gravity_angle_offset_rad, ax.drive->gravity_angle_offset_rad, 0.02);
}

// What the trace cannot tell: gravity from one direction only; too few stretches; no acceleration.
TEST(Identify, RefusesTracesThatCannotDetermineTheParameters) {
  const core::MachineAxis ax = mikron_axis("X");
  const double te = 1e-3;
  std::vector<double> one_way;
  for (double s : {2.0, 4.0, 8.0, 16.0}) one_way.push_back(s * core::units::kMPerMinToMmPerS);
  const AxisTrace tr = simulate(ax, excitation(-150.0, one_way, 2000.0, 0.4, te), te, 0.05, 1e-4, 5);
  IdentifyOptions o = options_for(ax);
  o.gravity = GravityModel::Constant;
  try {
    identify_friction_inertia(tr, o);
    FAIL() << "gravity fitted from one direction";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("one direction"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("simulated X"), std::string::npos) << e.what();
  }
  o.gravity = GravityModel::Auto;  // resolves to none: Coulomb + viscous from one direction is fine
  const IdentifiedDrive d = identify_friction_inertia(tr, o);
  EXPECT_EQ(d.gravity, GravityModel::None);
  EXPECT_LT(rel(d.coulomb_Nm, ax.drive->coulomb_Nm), 0.03);

  const AxisTrace two = simulate(ax, excitation(-150.0, {50.0, -50.0}, 2000.0, 0.4, te), te, 0.05, 1e-4, 6);
  EXPECT_THROW(identify_friction_inertia(two, options_for(ax)), core::Error);
  IdentifyOptions no_kt = options_for(ax);
  no_kt.torque_constant_Nm_per_A = 0.0;
  EXPECT_THROW(identify_friction_inertia(tr, no_kt), core::Error);
}

namespace {

std::filesystem::path temp_file(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / ("vmsim_identify_" + std::to_string(::getpid()) + "_" + name);
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

std::string read_error(const std::string& name, const std::string& text) {
  const auto p = temp_file(name, text);
  try {
    read_axis_trace_csv(p);
  } catch (const core::Error& e) {
    std::filesystem::remove(p);
    return e.what();
  }
  std::filesystem::remove(p);
  return "";
}

}  // namespace

TEST(Identify, ReadsTraceCsv) {
  std::vector<std::string> ignored;
  const auto p = temp_file("ok.csv",
                           "# axis X\n t_s , position_deg,current_A,setpoint\n0.001,1.0,0.5,9\n0.002,2.0,0.6,9\r\n"
                           "\n0.003,3.0,0.7,9\n");
  const AxisTrace tr = read_axis_trace_csv(p, &ignored);
  std::filesystem::remove(p);
  ASSERT_EQ(tr.t_s.size(), 3);
  EXPECT_TRUE(tr.rotary);
  EXPECT_EQ(tr.velocity.size(), 0);
  EXPECT_NEAR(tr.position[1], 2.0 * kPi / 180, 1e-15);
  EXPECT_DOUBLE_EQ(tr.current_A[2], 0.7);
  ASSERT_EQ(ignored.size(), 1u);
  EXPECT_EQ(ignored[0], "setpoint");

  const std::string bad_number =
      read_error("n.csv", "t_s,velocity_mm_per_s,current_A\n0.001,1,0.5\n0.002,x1,0.5\n0.003,1,1\n");
  EXPECT_NE(bad_number.find("n.csv:3: column 2 'velocity_mm_per_s': 'x1' is not a finite number"), std::string::npos)
      << bad_number;
  const std::string fields = read_error("f.csv", "t_s,velocity_mm_per_s,current_A\n0.001,1,0.5\n0.002,1\n");
  EXPECT_NE(fields.find("f.csv:3: 2 cells, the header (line 1) names 3 columns"), std::string::npos) << fields;
  const std::string time =
      read_error("t.csv", "t_s,velocity_mm_per_s,current_A\n0.002,1,0.5\n0.002,1,0.5\n0.003,1,1\n");
  EXPECT_NE(time.find("t.csv:3: column 1 't_s': 0.002 does not increase"), std::string::npos) << time;
  const std::string both = read_error("b.csv", "t_s,position_mm,velocity_mm_per_s,current_A\n");
  EXPECT_NE(both.find("b.csv:1: columns 'position_mm' and 'velocity_mm_per_s' both give the motion"), std::string::npos)
      << both;
  const std::string none = read_error("m.csv", "t_s,current_A,speed\n");
  EXPECT_NE(none.find("m.csv:1: the header has no position_mm"), std::string::npos) << none;
  const std::string nan = read_error("nan.csv", "t_s,position_mm,current_A\n0.001,1,nan\n");
  EXPECT_NE(nan.find("nan.csv:2: column 3 'current_A': 'nan' is not a finite number"), std::string::npos) << nan;
  EXPECT_NE(read_error("e.csv", "").find("no header row"), std::string::npos);
}
