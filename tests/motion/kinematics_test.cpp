// Kinematic chains: forward for any chain, the closed-form inverse of the five-axis families, continuity of the rotary
// axes, singular poses, travel limits, and tool paths in axis space. References: the round trip forward(inverse(pose))
// = pose (a property, not a second implementation), LinuxCNC's xyzac-trt formulas (src/emc/kinematics/trtfuncs.c,
// written out below from the math of its 5-axis kinematics documentation), finite differences for the tip velocity,
// and the 3-axis "xyz" machine the Mikron reproduces exactly with its tables at zero.
#include "core/error.hpp"
#include "program/gcode.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "core/machine.hpp"
#include "program/program.hpp"
#include "core/units.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "tests/test_paths.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

namespace vmsim::motion {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector3d;
using Eigen::VectorXd;
using vmsim::core::units::kDegToRad;
using vmsim::core::units::kPi;

const fs::path kMachines = fs::path(VMSIM_SOURCE_DIR) / "parts" / "machines";
const fs::path kGcodeData = fs::path(VMSIM_SHARED_DIR) / "data" / "gcode";

fs::path test_dir() { return vmsim::test::test_scratch_dir("vmsim_kinematics_test"); }
fs::path write(const std::string& name, const std::string& text) {
  return vmsim::test::write_test_file("vmsim_kinematics_test", name, text);
}

double angle(const Vector3d& a, const Vector3d& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

// ---- Machines built in code: one per family, with offsets everywhere so that no term hides behind a zero ----------

core::MachineAxis linear(const char* name, double lo, double hi) {
  core::MachineAxis a;
  a.name = name;
  a.program_axis = std::string("XYZ").find(name[0]);
  a.kind = core::AxisKind::Linear;
  a.travel_min = lo;
  a.travel_max = hi;
  a.max_velocity = 500;
  a.max_acceleration = 2000;
  a.max_jerk = 20000;
  return a;
}

// Rotary axis with travel in degrees; lo > hi means continuous.
core::MachineAxis rotary(const char* name, double lo_deg, double hi_deg) {
  core::MachineAxis a;
  a.name = name;
  a.program_axis = 3 + static_cast<int>(std::string("ABC").find(name[0]));
  a.kind = core::AxisKind::Rotary;
  a.continuous = lo_deg > hi_deg;
  a.travel_min = a.continuous ? -1e300 : lo_deg * kDegToRad;
  a.travel_max = a.continuous ? 1e300 : hi_deg * kDegToRad;
  a.max_velocity = 2;
  a.max_acceleration = 5;
  a.max_jerk = 50;
  return a;
}

core::ChainJoint joint(const char* axis, Vector3d dir, Vector3d point = Vector3d::Zero()) {
  core::ChainJoint j;
  j.program_axis = static_cast<int>(std::string("XYZABC").find(axis[0]));
  j.kind = j.program_axis < 3 ? core::AxisKind::Linear : core::AxisKind::Rotary;
  j.direction = dir.normalized();
  j.point_mm = point;
  j.where = std::string("test joint ") + axis;
  return j;
}

core::Machine chain_machine(const std::string& name, std::vector<core::MachineAxis> axes,
                            std::vector<core::ChainJoint> workpiece, std::vector<core::ChainJoint> tool,
                            Vector3d origin, Vector3d gauge, Vector3d tool_dir) {
  core::Machine m;
  m.name = name;
  m.source_file = name + ".toml";
  m.kinematics = "chain";
  m.axes = std::move(axes);
  core::KinematicChain ch;
  ch.workpiece = std::move(workpiece);
  ch.tool = std::move(tool);
  ch.workpiece_origin_mm = origin;
  ch.gauge_point_mm = gauge;
  ch.tool_direction = tool_dir.normalized();
  m.chain = ch;
  return m;
}

// B tilting table (about Y, off every axis) carrying a C rotary table; Y rides on the table side (negative direction:
// the table moves, the tool goes the other way relative to it).
core::Machine bc_table() {
  return chain_machine("bc-table",
                       {linear("X", -600, 600), linear("Y", -600, 600), linear("Z", -600, 600), rotary("B", -110, 110),
                        rotary("C", 1, -1)},
                       {joint("Y", {0, -1, 0}), joint("B", {0, 1, 0}, {12, -7, -80}), joint("C", {0, 0, 1}, {3, 4, 0})},
                       {joint("X", {1, 0, 0}), joint("Z", {0, 0, 1})}, {5, -2, 1}, {0.5, 0.25, 40}, {0, 0, 1});
}

// C rotary table carrying an X slide (the X direction turns with C), B tilting head (pivot above the spindle nose).
core::Machine head_table() {
  return chain_machine("head-table",
                       {linear("X", -900, 900), linear("Y", -900, 900), linear("Z", -900, 900), rotary("B", -100, 100),
                        rotary("C", 1, -1)},
                       {joint("C", {0, 0, 1}, {10, -5, 0}), joint("X", {-1, 0, 0})},
                       {joint("Y", {0, 1, 0}), joint("Z", {0, 0, 1}), joint("B", {0, 1, 0}, {1, 2, 300})}, {-3, 2, 7},
                       {0, 0, 200}, {0, 0, 1});
}

// Fork head: C about Z carrying A about X, pivots above the spindle nose.
core::Machine head_head() {
  return chain_machine("head-head",
                       {linear("X", -900, 900), linear("Y", -900, 900), linear("Z", -900, 900), rotary("A", -110, 110),
                        rotary("C", 1, -1)},
                       {},
                       {joint("X", {1, 0, 0}), joint("Y", {0, 1, 0}), joint("Z", {0, 0, 1}),
                        joint("C", {0, 0, 1}, {2, 1, 400}), joint("A", {1, 0, 0}, {0, 3, 350})},
                       {1, 1, 1}, {0, 0, 250}, {0, 0, 1});
}

// Nutating head: C about Z carrying B about an axis 45 deg from Z: the two rotary axes are not perpendicular (the
// general case of the solution, with an unreachable region: the tool tilts at most 90 deg).
core::Machine nutating_head() {
  return chain_machine(
      "nutating",
      {linear("X", -900, 900), linear("Y", -900, 900), linear("Z", -900, 900), rotary("B", 1, -1), rotary("C", 1, -1)},
      {},
      {joint("X", {1, 0, 0}), joint("Y", {0, 1, 0}), joint("Z", {0, 0, 1}), joint("C", {0, 0, 1}, {0, 0, 400}),
       joint("B", {0, 1, 1}, {0, -20, 330})},
      {0, 0, 0}, {0, 0, 250}, {0, 0, 1});
}

// No rotary joint: a gantry whose table moves in X and Y.
core::Machine cartesian_chain() {
  return chain_machine("cartesian", {linear("X", -900, 900), linear("Y", -900, 900), linear("Z", -900, 900)},
                       {joint("X", {-1, 0, 0}), joint("Y", {0, -1, 0})}, {joint("Z", {0, 0, 1})}, {100, 50, 0},
                       {0, 0, 120}, {0, 0, 1});
}

core::Machine xyzac() { return core::load_machine(kMachines / "xyzac_trt.toml"); }
core::Machine mikron_machine() { return core::load_machine(kMachines / "mikron_ucp710.toml"); }

// Random axis positions within travel (continuous axes: three turns either way).
VectorXd random_axes(const core::Machine& m, std::mt19937_64& rng) {
  VectorXd q(static_cast<Eigen::Index>(m.axes.size()));
  for (std::size_t i = 0; i < m.axes.size(); ++i) {
    const core::MachineAxis& a = m.axes[i];
    double lo = a.travel_min, hi = a.travel_max;
    if (a.continuous) lo = -3 * kPi, hi = 3 * kPi;
    if (a.kind == core::AxisKind::Linear)
      lo *= 0.3, hi *= 0.3;  // the tip stays where the other solution reaches it too
    q[static_cast<Eigen::Index>(i)] = std::uniform_real_distribution<double>(lo, hi)(rng);
  }
  return q;
}

bool within_travel(const core::Machine& m, const VectorXd& q) {
  for (std::size_t i = 0; i < m.axes.size(); ++i) {
    const core::MachineAxis& a = m.axes[i];
    const double v = q[static_cast<Eigen::Index>(i)];
    if (!a.continuous && (v < a.travel_min - 1e-9 || v > a.travel_max + 1e-9)) return false;
  }
  return true;
}

// ---- Machine files --------------------------------------------------------------------------------------------

TEST(KinematicsFiles, MikronAndXyzacTrtLoadWithTheirChains) {
  const core::Machine mk = mikron_machine();
  EXPECT_EQ(mk.kinematics, "chain");
  ASSERT_TRUE(mk.chain);
  ASSERT_EQ(mk.chain->workpiece.size(), 2u);
  EXPECT_EQ(mk.chain->workpiece[0].program_axis, core::kA);
  EXPECT_EQ(mk.chain->workpiece[1].program_axis, core::kC);
  EXPECT_EQ(mk.chain->workpiece[0].point_mm, Vector3d(0, 0, -100));
  EXPECT_EQ(make_kinematics(mk)->family(), KinematicFamily::TableTable);

  const core::Machine tr = xyzac();
  ASSERT_TRUE(tr.chain);
  EXPECT_EQ(tr.chain->workpiece[0].point_mm, Vector3d(0, 20, 10));  // LinuxCNC sim: y-offset 20, z-offset 10
  EXPECT_EQ(make_kinematics(tr)->family(), KinematicFamily::TableTable);
  const core::MachineAxis& a = tr.axes[static_cast<std::size_t>(tr.axis_index(core::kA))];
  EXPECT_NEAR(a.travel_min, -100 * kDegToRad, 1e-15);
  EXPECT_NEAR(a.travel_max, 50 * kDegToRad, 1e-15);
  EXPECT_TRUE(tr.axes[static_cast<std::size_t>(tr.axis_index(core::kC))].continuous);
  for (const core::MachineAxis& ax : tr.axes) EXPECT_TRUE(ax.drive) << ax.name;

  EXPECT_EQ(make_kinematics(bc_table())->family(), KinematicFamily::TableTable);
  EXPECT_EQ(make_kinematics(head_table())->family(), KinematicFamily::HeadTable);
  EXPECT_EQ(make_kinematics(head_head())->family(), KinematicFamily::HeadHead);
  EXPECT_EQ(make_kinematics(nutating_head())->family(), KinematicFamily::HeadHead);
  EXPECT_EQ(make_kinematics(cartesian_chain())->family(), KinematicFamily::Cartesian);
}

// A valid chain machine; tests replace one line to break it. Line numbers are commented for the assertions.
const char* kChainMachine =
    "[machine]\n"                                                                              // 1
    "name = \"trt\"\n"                                                                         // 2
    "kinematics = \"chain\"\n"                                                                 // 3
    "[kinematics]\n"                                                                           // 4
    "workpiece = [\n"                                                                          // 5
    "  { axis = \"A\", type = \"rotary\", direction = [1, 0, 0], point_mm = [0, 0, -50] },\n"  // 6
    "  { axis = \"C\", type = \"rotary\", direction = [0, 0, 1], point_mm = [0, 0, 0] },\n"    // 7
    "]\n"                                                                                      // 8
    "tool = [\n"                                                                               // 9
    "  { axis = \"X\", type = \"linear\", direction = [1, 0, 0] },\n"                          // 10
    "  { axis = \"Y\", type = \"linear\", direction = [0, 1, 0] },\n"                          // 11
    "  { axis = \"Z\", type = \"linear\", direction = [0, 0, 1] },\n"                          // 12
    "]\n"                                                                                      // 13
    "[[axes]]\nname = \"X\"\ntype = \"linear\"\ntravel_mm = [-100, 100]\nmax_velocity_m_per_min = 10\n"
    "max_acceleration_m_per_s2 = 1\nmax_jerk_m_per_s3 = 10\n"
    "[[axes]]\nname = \"Y\"\ntype = \"linear\"\ntravel_mm = [-100, 100]\nmax_velocity_m_per_min = 10\n"
    "max_acceleration_m_per_s2 = 1\nmax_jerk_m_per_s3 = 10\n"
    "[[axes]]\nname = \"Z\"\ntype = \"linear\"\ntravel_mm = [-100, 100]\nmax_velocity_m_per_min = 10\n"
    "max_acceleration_m_per_s2 = 1\nmax_jerk_m_per_s3 = 10\n"
    "[[axes]]\nname = \"A\"\ntype = \"rotary\"\ntravel_deg = [-90, 90]\nmax_velocity_deg_per_s = 10\n"
    "max_acceleration_deg_per_s2 = 10\nmax_jerk_deg_per_s3 = 100\n"
    "[[axes]]\nname = \"C\"\ntype = \"rotary\"\nmax_velocity_deg_per_s = 10\n"
    "max_acceleration_deg_per_s2 = 10\nmax_jerk_deg_per_s3 = 100\n";

std::string chain_with(int line, const std::string& text) {
  std::vector<std::string> lines;
  std::string cur;
  for (char c : std::string(kChainMachine)) {
    if (c == '\n') {
      lines.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  lines.at(static_cast<std::size_t>(line - 1)) = text;
  std::string out;
  for (const auto& l : lines) out += l + "\n";
  return out;
}

std::string load_error(const std::string& text) {
  const fs::path p = write("machine.toml", text);
  try {
    core::load_machine(p);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "(no error)";
}

void expect_error(const std::string& message, const fs::path& file, int line, const std::vector<std::string>& parts) {
  const std::string prefix = file.string() + ":" + std::to_string(line) + ":";
  EXPECT_EQ(message.rfind(prefix, 0), 0u)
      << "expected the message to start with " << prefix << "\nmessage: " << message;
  for (const auto& part : parts)
    EXPECT_NE(message.find(part), std::string::npos) << "missing \"" << part << "\" in: " << message;
}

TEST(KinematicsFiles, BadChainsAreErrorsNamingFileLineAndKey) {
  const fs::path file = test_dir() / "machine.toml";
  ASSERT_EQ(load_error(kChainMachine), "(no error)");
  // An axis used twice.
  expect_error(load_error(chain_with(7,
                                     "  { axis = \"A\", type = \"rotary\", direction = [0, 0, 1], point_mm = [0, 0, "
                                     "0] },")),
               file, 7, {"key 'kinematics.workpiece[1].axis'", "axis A is already the joint kinematics.workpiece[0]"});
  // A chain axis the machine lacks.
  expect_error(load_error(chain_with(7,
                                     "  { axis = \"B\", type = \"rotary\", direction = [0, 0, 1], point_mm = [0, 0, "
                                     "0] },")),
               file, 7, {"key 'kinematics.workpiece[1].axis'", "the machine has no axis B"});
  // A zero direction.
  expect_error(load_error(chain_with(11, "  { axis = \"Y\", type = \"linear\", direction = [0, 0, 0] },")), file, 11,
               {"key 'kinematics.tool[1].direction'", "not all zero"});
  // A type that is not the axis' type.
  expect_error(load_error(chain_with(10,
                                     "  { axis = \"X\", type = \"rotary\", direction = [1, 0, 0], point_mm = [0, 0, "
                                     "0] },")),
               file, 10, {"key 'kinematics.tool[0].type'", "axis X is a linear axis"});
  // A rotary joint without its axis point, a linear joint with one.
  expect_error(load_error(chain_with(7, "  { axis = \"C\", type = \"rotary\", direction = [0, 0, 1] },")), file, 7,
               {"key 'kinematics.workpiece[1].point_mm'", "missing"});
  expect_error(load_error(chain_with(10,
                                     "  { axis = \"X\", type = \"linear\", direction = [1, 0, 0], point_mm = [0, 0, "
                                     "0] },")),
               file, 10, {"key 'kinematics.tool[0].point_mm'", "for rotary joints"});
  // An axis in neither chain.
  expect_error(load_error(chain_with(12, "")), file, 5, {"axis Z is in neither chain"});
  // Linear joints that do not span space.
  expect_error(load_error(chain_with(12, "  { axis = \"Z\", type = \"linear\", direction = [1, 1, 0] },")), file, 9,
               {"key 'kinematics.tool'", "span space"});
  // An unknown key in a joint.
  expect_error(load_error(chain_with(10, "  { axis = \"X\", type = \"linear\", direction = [1, 0, 0], offset = 1 },")),
               file, 10, {"unknown key 'kinematics.tool[0].offset'"});
  // kinematics = "chain" without [kinematics]; [kinematics] on an "xyz" machine.
  std::string no_table = kChainMachine;
  no_table.replace(no_table.find("[kinematics]"), no_table.find("[[axes]]") - no_table.find("[kinematics]"), "");
  expect_error(load_error(no_table), file, 1, {"needs a [kinematics] table"});
  expect_error(load_error(chain_with(3, "kinematics = \"xyz\"")), file, 4,
               {"key 'kinematics'", "needs kinematics = \"chain\""});
}

TEST(KinematicsFiles, JobTcpOption) {
  const fs::path machine = kMachines / "xyzac_trt.toml";
  write("p.ngc", "G1 X1 F100\nM2\n");
  const fs::path job =
      write("job.toml", "[job]\nmachine = \"" + machine.string() + "\"\nprogram = \"p.ngc\"\ntcp = true\n");
  EXPECT_TRUE(core::load_job(job).tcp);
  const fs::path plain = write("plain.toml", "[job]\nmachine = \"" + machine.string() + "\"\nprogram = \"p.ngc\"\n");
  EXPECT_FALSE(core::load_job(plain).tcp);
}

// ---- Forward and inverse --------------------------------------------------------------------------------------

struct Family {
  const char* name;
  core::Machine machine;
};

std::vector<Family> families() {
  return {{"xyzac-trt", xyzac()},
          {"mikron", mikron_machine()},
          {"bc-table", bc_table()},
          {"head-table", head_table()},
          {"head-head", head_head()},
          {"nutating", nutating_head()},
          {"cartesian-chain", cartesian_chain()}};
}

// forward(inverse(pose)) = pose on random reachable poses (the poses of random axis positions within travel), from a
// random `near` (which picks the solution) and from near = the axes themselves (which must give them back).
TEST(Kinematics, ForwardOfInverseIsThePoseForEveryFamily) {
  for (const Family& f : families()) {
    SCOPED_TRACE(f.name);
    const auto kin = make_kinematics(f.machine);
    std::mt19937_64 rng(7);
    double worst_tip = 0, worst_axis = 0, worst_back = 0;
    for (int n = 0; n < 3000; ++n) {
      const VectorXd q = random_axes(f.machine, rng);
      const double tlo = std::uniform_real_distribution<double>(0, 150)(rng);
      const ToolPose pose = kin->forward(q, tlo);
      ASSERT_NEAR(pose.axis.norm(), 1.0, 1e-14);
      const VectorXd near = random_axes(f.machine, rng);
      const VectorXd sol = kin->inverse(pose, tlo, near);
      ASSERT_TRUE(within_travel(f.machine, sol));
      const ToolPose back = kin->forward(sol, tlo);
      worst_tip = std::max(worst_tip, (back.tip_mm - pose.tip_mm).norm());
      worst_axis = std::max(worst_axis, angle(back.axis, pose.axis));
      // near = q: the same axes (the inverse adds no turn of 2 pi and does not switch solutions).
      const VectorXd same = kin->inverse(pose, tlo, q);
      worst_back = std::max(worst_back, (same - q).cwiseAbs().maxCoeff());
    }
    EXPECT_LE(worst_tip, 1e-9);
    EXPECT_LE(worst_axis, 1e-9);
    EXPECT_LE(worst_back, 1e-9);
  }
}

TEST(Kinematics, CartesianXyzRoundTrip) {
  core::Machine m = cartesian_chain();
  m.kinematics = "xyz";
  m.chain.reset();
  const auto kin = make_kinematics(m);
  EXPECT_EQ(kin->family(), KinematicFamily::Cartesian);
  const VectorXd q = (VectorXd(3) << 12.5, -3.25, 40).finished();
  const ToolPose p = kin->forward(q, 30);
  EXPECT_EQ(p.tip_mm, Vector3d(12.5, -3.25, 10));
  EXPECT_EQ(kin->inverse(p, 30, VectorXd::Zero(3)), q);
}

// The inverse of the chain without rotary joints refuses a tilted tool, names the machine.
TEST(Kinematics, CartesianChainCannotTilt) {
  const auto kin = make_kinematics(cartesian_chain());
  try {
    kin->inverse(ToolPose{Vector3d(1, 2, 3), Vector3d(0, 0.1, 1).normalized()}, 0, VectorXd::Zero(3));
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot tilt the tool"), std::string::npos) << e.what();
  }
}

// LinuxCNC's xyzac-trt, with the sim's offsets (y-offset 20, z-offset 10, rot-points 0): trtfuncs.c takes the
// position with the tool offset added along Z (pos = tip + t Z) and the tool offset t, and gives the joints
//   X = cos C px - sin C py
//   Y = sin C cos A px + cos C cos A py - sin A pz - cos A dy + sin A (dz + t) + dy
//   Z = sin C sin A px + cos C sin A py + cos A pz - sin A dy - cos A (dz + t) + dz + t
// (its xyzacKinematicsInverse); the tool stays vertical in the machine, so in the work frame it is
// Rz(-C) Rx(-A) Z.
TEST(Kinematics, XyzacTrtMatchesLinuxCncFormulas) {
  const core::Machine m = xyzac();
  const auto kin = make_kinematics(m);
  const int ix = m.axis_index(core::kX), iy = m.axis_index(core::kY), iz = m.axis_index(core::kZ),
            ia = m.axis_index(core::kA), ic = m.axis_index(core::kC);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  double worst = 0, worst_axis = 0, worst_fwd = 0;
  for (int n = 0; n < 1000; ++n) {
    const Vector3d tip(60 * u(rng), 40 * u(rng), 30 * u(rng));
    const double a = (-25 + 75 * u(rng)) * kDegToRad, c = 400 * u(rng) * kDegToRad, t = 50 + 50 * u(rng);
    const double dy = 20, dz = 10 + t;
    const Vector3d pos = tip + Vector3d(0, 0, t);
    const double ca = std::cos(a), sa = std::sin(a), cc = std::cos(c), sc = std::sin(c);
    const Vector3d lcnc(cc * pos.x() - sc * pos.y(),
                        sc * ca * pos.x() + cc * ca * pos.y() - sa * pos.z() - ca * dy + sa * dz + dy,
                        sc * sa * pos.x() + cc * sa * pos.y() + ca * pos.z() - sa * dy - ca * dz + dz);
    VectorXd q = VectorXd::Zero(5);
    q[ia] = a;
    q[ic] = c;
    const VectorXd ours = kin->place_tip(tip, t, q);
    worst = std::max(worst, (Vector3d(ours[ix], ours[iy], ours[iz]) - lcnc).norm());
    const ToolPose p = kin->forward(ours, t);
    worst_fwd = std::max(worst_fwd, (p.tip_mm - tip).norm());
    const Vector3d axis =
        Eigen::AngleAxisd(-c, Vector3d::UnitZ()) * (Eigen::AngleAxisd(-a, Vector3d::UnitX()) * Vector3d::UnitZ());
    worst_axis = std::max(worst_axis, angle(p.axis, axis));
  }
  EXPECT_LE(worst, 1e-10);
  EXPECT_LE(worst_fwd, 1e-10);
  EXPECT_LE(worst_axis, 1e-14);
}

// With its tables at zero the Mikron is the 3-axis machine it was before its chain, bit for bit.
TEST(Kinematics, MikronAtZeroIsTheCartesianMachine) {
  const core::Machine chain = mikron_machine();
  core::Machine flat = chain;
  flat.kinematics = "xyz";
  flat.chain.reset();
  const auto kc = make_kinematics(chain), kf = make_kinematics(flat);
  std::mt19937_64 rng(3);
  for (int n = 0; n < 1000; ++n) {
    VectorXd q = random_axes(chain, rng);
    q[chain.axis_index(core::kA)] = 0;
    q[chain.axis_index(core::kC)] = 0;
    const double tlo = 37.25 * (n % 3);
    const ToolPose a = kc->forward(q, tlo), b = kf->forward(q, tlo);
    ASSERT_EQ(a.tip_mm, b.tip_mm);
    ASSERT_EQ(a.axis, b.axis);
  }
  program::ProgramOptions po;
  po.tool_table = fs::path(VMSIM_SOURCE_DIR) / "parts/plane_cylinder/tools.tbl";
  const core::ToolPath tp =
      program::read_program(fs::path(VMSIM_SOURCE_DIR) / "parts/plane_cylinder/plane_cylinder_fast.ngc", po);
  const core::ToolPath ac = toolpath_in_axis_space(tp, chain), af = toolpath_in_axis_space(tp, flat);
  ASSERT_EQ(ac.moves.size(), af.moves.size());
  EXPECT_EQ(ac.initial_position, af.initial_position);
  for (std::size_t i = 0; i < ac.moves.size(); ++i) {
    ASSERT_EQ(ac.moves[i].start, af.moves[i].start);
    ASSERT_EQ(ac.moves[i].end, af.moves[i].end);
    ASSERT_EQ(ac.moves[i].centre_mm, af.moves[i].centre_mm);
  }
}

// The Mikron turns its tables the ISO 841 way: +C turns the table clockwise seen from above, so the tool goes
// counter-clockwise around the workpiece (the tool, at machine +X, is over the workpiece's +Y at C = +90 deg).
TEST(Kinematics, MikronRotaryDirections) {
  const core::Machine m = mikron_machine();
  const auto kin = make_kinematics(m);
  VectorXd q = VectorXd::Zero(5);
  q[m.axis_index(core::kC)] = 90 * kDegToRad;
  q[m.axis_index(core::kX)] = 50;
  // The gauge at X = 50 (machine) sits over the workpiece point at +Y: the workpiece turned by -90 deg about Z.
  EXPECT_LT((kin->forward(q, 0).tip_mm - Vector3d(0, 50, 0)).norm(), 1e-12);
  // +A turns the table about -X: the tool leans towards -Y in the workpiece frame, about the pivot 100 mm down.
  q.setZero();
  q[m.axis_index(core::kA)] = 90 * kDegToRad;
  const ToolPose p = kin->forward(q, 0);
  EXPECT_LT((p.axis - Vector3d(0, -1, 0)).norm(), 1e-12);
  EXPECT_LT((p.tip_mm - Vector3d(0, -100, -100)).norm(), 1e-12);
}

TEST(Kinematics, TipVelocityIsTheDerivativeOfForward) {
  for (const Family& f : families()) {
    SCOPED_TRACE(f.name);
    const auto kin = make_kinematics(f.machine);
    std::mt19937_64 rng(5);
    for (int n = 0; n < 200; ++n) {
      const VectorXd q = random_axes(f.machine, rng);
      VectorXd qd(q.size());
      for (Eigen::Index i = 0; i < qd.size(); ++i) qd[i] = std::uniform_real_distribution<double>(-1, 1)(rng);
      const double tlo = 42, h = 1e-6;
      const Vector3d fd = (kin->forward(q + h * qd, tlo).tip_mm - kin->forward(q - h * qd, tlo).tip_mm) / (2 * h);
      const Vector3d v = kin->tip_velocity(q, qd, tlo);
      ASSERT_LT((v - fd).norm(), 1e-6 * std::max(1.0, v.norm())) << v.transpose() << " vs " << fd.transpose();
    }
  }
}

TEST(Kinematics, ForwardOnlyChainsSayWhy) {
  // Three rotary joints.
  core::Machine three = head_head();
  three.axes.push_back(rotary("B", 1, -1));
  three.chain->workpiece.push_back(joint("B", {0, 1, 0}));
  const auto k3 = make_kinematics(three);
  EXPECT_EQ(k3->family(), KinematicFamily::ForwardOnly);
  const VectorXd q = VectorXd::Zero(6);
  const ToolPose p = k3->forward(q, 0);  // forward works
  try {
    k3->inverse(p, 0, q);
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("forward only"), std::string::npos) << e.what();
  }
  // The TCP inverse (rotary axes given) exists for every chain.
  const VectorXd placed = k3->place_tip(Vector3d(10, 20, 30), 5, q);
  EXPECT_LT((k3->forward(placed, 5).tip_mm - Vector3d(10, 20, 30)).norm(), 1e-10);
  // Parallel rotary axes.
  core::Machine par = head_head();
  par.chain->tool[4] = joint("A", {0, 0, 1}, {0, 3, 350});
  const auto kp = make_kinematics(par);
  EXPECT_EQ(kp->family(), KinematicFamily::ForwardOnly);
  try {
    kp->inverse(p, 0, VectorXd::Zero(5));
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("parallel"), std::string::npos) << e.what();
  }
}

// ---- Continuity, singular poses, travel ---------------------------------------------------------------------------

// Tool axis at polar angle theta from Z and azimuth phi (workpiece frame).
Vector3d polar(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

struct Track {
  std::vector<double> a, c;
};

Track track(const core::Machine& m, const std::vector<Vector3d>& axes, const Vector3d& tip, VectorXd near) {
  const auto kin = make_kinematics(m);
  Track t;
  for (const Vector3d& v : axes) {
    near = kin->inverse(ToolPose{tip, v}, 10, near);
    const ToolPose back = kin->forward(near, 10);
    EXPECT_LT((back.tip_mm - tip).norm(), 1e-9);
    EXPECT_LT(angle(back.axis, v), 1e-9);
    t.a.push_back(near[m.axis_index(core::kA)]);
    t.c.push_back(near[m.axis_index(core::kC)]);
  }
  return t;
}

double max_step(const std::vector<double>& v) {
  double s = 0;
  for (std::size_t i = 1; i < v.size(); ++i) s = std::max(s, std::abs(v[i] - v[i - 1]));
  return s;
}

// Sweeping the tool axis three times around the C axis, 2 deg from it: C follows continuously through +-180 deg and
// on (three whole turns, never wrapped back by 2 pi), A keeps its sign.
TEST(KinematicsContinuity, ConeAroundTheSingularityTurnsCContinuously) {
  const core::Machine m = xyzac();
  std::vector<Vector3d> axes;
  for (int k = 0; k <= 1080; ++k) axes.push_back(polar(2 * kDegToRad, k * kDegToRad));
  const Track t = track(m, axes, Vector3d(10, 5, 0), VectorXd::Zero(5));
  EXPECT_LT(max_step(t.c), 1.01 * kDegToRad);
  EXPECT_NEAR(std::abs(t.c.back() - t.c.front()), 6 * kPi, 1e-9);
  for (double a : t.a) EXPECT_NEAR(std::abs(a), 2 * kDegToRad, 1e-12);
  for (double a : t.a) EXPECT_EQ(std::signbit(a), std::signbit(t.a.front()));
}

// Through C = 180 deg from a near C of 170 deg: 190 deg, not -170 deg.
TEST(KinematicsContinuity, CPassesHalfATurnWithoutJumping) {
  const core::Machine m = xyzac();
  const auto kin = make_kinematics(m);
  const int ia = m.axis_index(core::kA), ic = m.axis_index(core::kC);
  VectorXd near = VectorXd::Zero(5);
  near[ia] = -30 * kDegToRad;
  near[ic] = 170 * kDegToRad;
  // The pose of (A -30, C 190), asked from near (A -30, C 170).
  VectorXd q = near;
  q[ic] = 190 * kDegToRad;
  const ToolPose p = kin->forward(q, 0);
  const VectorXd sol = kin->inverse(p, 0, near);
  EXPECT_NEAR(sol[ic], 190 * kDegToRad, 1e-12);
  EXPECT_NEAR(sol[ia], -30 * kDegToRad, 1e-12);
  // And from C = 170 deg + 3 turns: the same turn count.
  near[ic] += 6 * kPi;
  EXPECT_NEAR(kin->inverse(p, 0, near)[ic], 190 * kDegToRad + 6 * kPi, 1e-12);
}

// Straight through the singular pose (the tool axis tilting in the YZ plane from -5 to +5 deg, exactly vertical
// in the middle): C holds still, A passes through zero at an even pace: no flip of the solution.
TEST(KinematicsContinuity, ThroughTheSingularPoseCHoldsStill) {
  const core::Machine m = xyzac();
  std::vector<Vector3d> axes;
  for (int k = -50; k <= 50; ++k)
    axes.push_back(Vector3d(0, std::sin(k * 0.1 * kDegToRad), std::cos(k * 0.1 * kDegToRad)));
  ASSERT_EQ(axes[50], Vector3d(0, 0, 1));
  VectorXd near = VectorXd::Zero(5);
  near[m.axis_index(core::kC)] = 0.3;  // C of the previous pose: kept through the pose where C is free
  const Track t = track(m, axes, Vector3d(-20, 15, 2), near);
  // The first pose (tilted) fixes C at 0 (of 0 and pi, the closer to near's 0.3), and C never moves after it.
  for (double c : t.c) EXPECT_EQ(c, t.c.front());
  EXPECT_NEAR(max_step(t.a), 0.1 * kDegToRad, 1e-12);
  EXPECT_EQ(t.a[50], 0.0);
  EXPECT_NE(std::signbit(t.a.front()), std::signbit(t.a.back()));
}

// At the singular pose itself C is free: the inverse keeps near's C (any value, any turn count).
TEST(KinematicsContinuity, SingularPoseKeepsNearC) {
  const core::Machine m = xyzac();
  const auto kin = make_kinematics(m);
  for (const double c : {0.0, 1.234, -7.5, 40.0}) {
    VectorXd near = VectorXd::Zero(5);
    near[m.axis_index(core::kC)] = c;
    const VectorXd q = kin->inverse(ToolPose{Vector3d(3, 4, 5), Vector3d::UnitZ()}, 20, near);
    EXPECT_EQ(q[m.axis_index(core::kC)], c);
    EXPECT_EQ(q[m.axis_index(core::kA)], 0.0);
    EXPECT_LT((kin->forward(q, 20).tip_mm - Vector3d(3, 4, 5)).norm(), 1e-12);
  }
}

// Passing 0.06 deg from the singular pose: C has to turn half a turn in a few steps (the machine's physics: the
// closer the path passes, the faster C must turn), but it turns continuously and A keeps its sign.
TEST(KinematicsContinuity, NearTheSingularPoseCTurnsFastButContinuously) {
  const core::Machine m = xyzac();
  std::vector<Vector3d> axes;
  const double eps = 1e-3;
  for (int k = -500; k <= 500; ++k) axes.push_back(Vector3d(eps, k * 1e-4, 1).normalized());
  const Track t = track(m, axes, Vector3d(0, 0, 0), VectorXd::Zero(5));
  EXPECT_NEAR(std::abs(t.c.back() - t.c.front()), kPi - 2 * std::atan(eps / 0.05), 1e-9);
  // The fastest step is about (step / eps) rad: 0.1 rad per 1e-4 of tool axis change.
  EXPECT_NEAR(max_step(t.c), 0.1, 0.005);
  for (double a : t.a) EXPECT_EQ(std::signbit(a), std::signbit(t.a.front()));
}

// A limited tilting axis: of the two solutions the one within travel; none within travel is an error naming the axis.
TEST(KinematicsTravel, LimitsChooseTheSolutionOrReportTheAxis) {
  const core::Machine m = xyzac();  // A -100..50 deg
  const auto kin = make_kinematics(m);
  const int ia = m.axis_index(core::kA);
  // 60 deg tilt from near A = +40: A = +60 is out of travel, so A = -60 (with C half a turn away).
  VectorXd near = VectorXd::Zero(5);
  near[ia] = 40 * kDegToRad;
  const ToolPose p{Vector3d(5, -5, 3), polar(60 * kDegToRad, 0.7)};
  const VectorXd q = kin->inverse(p, 0, near);
  EXPECT_NEAR(q[ia], -60 * kDegToRad, 1e-12);
  EXPECT_LT(angle(kin->forward(q, 0).axis, p.axis), 1e-12);
  // 120 deg tilt: both +-120 deg are outside -100..50.
  try {
    kin->inverse(ToolPose{Vector3d(0, 0, 0), polar(120 * kDegToRad, 0.3)}, 0, VectorXd::Zero(5));
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("xyzac_trt.toml"), std::string::npos) << msg;
    EXPECT_NE(msg.find("A = "), std::string::npos) << msg;
    EXPECT_NE(msg.find("outside its travel [-100.0000, 50.0000] deg"), std::string::npos) << msg;
  }
  // A tip beyond the X travel.
  try {
    kin->inverse(ToolPose{Vector3d(500, 0, 0), Vector3d::UnitZ()}, 0, VectorXd::Zero(5));
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("X = 500.0000 mm is outside its travel"), std::string::npos) << e.what();
  }
  // A limited C (-200..200 deg): the 2 pi equivalent inside the travel.
  core::Machine lim = m;
  core::MachineAxis& c = lim.axes[static_cast<std::size_t>(lim.axis_index(core::kC))];
  c.continuous = false;
  c.travel_min = -200 * kDegToRad;
  c.travel_max = 200 * kDegToRad;
  const auto kl = make_kinematics(lim);
  VectorXd qc = VectorXd::Zero(5);
  qc[ia] = -30 * kDegToRad;
  qc[lim.axis_index(core::kC)] = -170 * kDegToRad;
  VectorXd nc = qc;
  nc[lim.axis_index(core::kC)] = 180 * kDegToRad;  // the closest equivalent, 190 deg, is inside
  const VectorXd sc = kl->inverse(kl->forward(qc, 0), 0, nc);
  EXPECT_NEAR(sc[lim.axis_index(core::kC)], 190 * kDegToRad, 1e-12);
  nc[lim.axis_index(core::kC)] = 195 * kDegToRad + 2 * kPi;  // near is far out; the equivalents inside are -170 and 190
  const VectorXd sc2 = kl->inverse(kl->forward(qc, 0), 0, nc);
  EXPECT_NEAR(sc2[lim.axis_index(core::kC)], 190 * kDegToRad, 1e-12);
}

// The nutating head cannot tilt the tool beyond 90 deg: an error that says so.
TEST(KinematicsTravel, UnreachableOrientationIsAnError) {
  const auto kin = make_kinematics(nutating_head());
  try {
    kin->inverse(ToolPose{Vector3d(0, 0, 0), polar(120 * kDegToRad, 0)}, 0, VectorXd::Zero(5));
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("outside the orientations"), std::string::npos) << e.what();
  }
}

// ---- Tool paths in axis space ---------------------------------------------------------------------------------

core::ToolPath read_tcp(const std::string& text) {
  const fs::path p = write("tcp.ngc", text);
  core::ToolPath tp = program::read_gcode(p);
  for (core::Move& m : tp.moves) m.tcp = true;
  return tp;
}

// The programmed tip of a workpiece-frame move at parameter s (lines and XY arcs, as the G-code below has them).
Vector3d programmed_tip(const core::Move& m, double s) {
  if (m.kind == core::MotionKind::Line) return m.start.head<3>() + s * (m.end.head<3>() - m.start.head<3>());
  const Vector3d c(m.centre_mm[0], m.centre_mm[1], 0);
  const double t0 = std::atan2(m.start.y() - c.y(), m.start.x() - c.x());
  double t1 = std::atan2(m.end.y() - c.y(), m.end.x() - c.x());
  if (m.rotation > 0 && t1 <= t0) t1 += 2 * kPi;
  if (m.rotation < 0 && t1 >= t0) t1 -= 2 * kPi;
  const double r = std::hypot(m.start.x() - c.x(), m.start.y() - c.y()), th = t0 + s * (t1 - t0);
  return {c.x() + r * std::cos(th), c.y() + r * std::sin(th), m.start.z() + s * (m.end.z() - m.start.z())};
}

VectorXd to_axes(const core::Machine& m, const core::Vec6& v) {
  VectorXd q(static_cast<Eigen::Index>(m.axes.size()));
  for (std::size_t i = 0; i < m.axes.size(); ++i) q[static_cast<Eigen::Index>(i)] = v[m.axes[i].program_axis];
  return q;
}

// Every axis-space point of the move (start, via, end) against the programmed tip, and the straight segments between
// them at 20 points each against the tolerance.
void check_move(const core::Machine& m, const Kinematics& kin, const core::Move& wp, const core::Move& ax, double tol,
                double* worst_point, double* worst_chord) {
  std::vector<std::pair<double, core::Vec6>> pts{{0.0, ax.start}};
  for (std::size_t i = 0; i < ax.via.size(); ++i) pts.emplace_back(ax.via_s[i], ax.via[i]);
  pts.emplace_back(1.0, ax.end);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vector3d tip = kin.forward(to_axes(m, pts[i].second), wp.tool_length_offset_mm).tip_mm;
    *worst_point = std::max(*worst_point, (tip - programmed_tip(wp, pts[i].first)).norm());
    if (i == 0) continue;
    for (int k = 1; k < 20; ++k) {
      const double f = k / 20.0, s = pts[i - 1].first + f * (pts[i].first - pts[i - 1].first);
      const core::Vec6 q = pts[i - 1].second + f * (pts[i].second - pts[i - 1].second);
      const Vector3d t = kin.forward(to_axes(m, q), wp.tool_length_offset_mm).tip_mm;
      *worst_chord = std::max(*worst_chord, (t - programmed_tip(wp, s)).norm());
    }
  }
  EXPECT_LE(*worst_chord, tol * 1.01);
}

// Tool-centre-point programming: the table turns (A and C) while the tip stays at one point of the workpiece; the
// axis-space image of every move, pushed through forward, keeps the tip there.
TEST(KinematicsToolpath, TcpProgramKeepsTheTipFixedThroughTheChain) {
  const core::Machine m = xyzac();
  const core::ToolPath wp = read_tcp(
      "G21 G90 G94\n"
      "G0 X10 Y5 Z2 A0 C0\n"  // 2
      "G1 F600 A-30 C90\n"    // 3: the tip stays at (10, 5, 2)
      "G1 A-60 C200\n"        // 4
      "G1 A-10 C-100\n"       // 5
      "G0 A0 C0\n"            // 6
      "M2\n");
  ASSERT_EQ(wp.moves.size(), 5u);
  const core::ToolPath ax = toolpath_in_axis_space(wp, m);
  const auto kin = make_kinematics(m);
  ASSERT_EQ(ax.moves.size(), wp.moves.size());
  EXPECT_EQ(ax.initial_position, ax.moves[0].start);
  for (std::size_t i = 1; i < ax.moves.size(); ++i) {
    SCOPED_TRACE(i);
    const core::Move& mv = ax.moves[i];
    EXPECT_FALSE(mv.via.empty());
    EXPECT_EQ(mv.start, ax.moves[i - 1].end);
    // The rotary words are the rotary axes.
    EXPECT_EQ(mv.end[core::kA], wp.moves[i].end[core::kA]);
    EXPECT_EQ(mv.end[core::kC], wp.moves[i].end[core::kC]);
    double worst_point = 0, worst_chord = 0;
    check_move(m, *kin, wp.moves[i], mv, 1e-3, &worst_point, &worst_chord);
    EXPECT_LE(worst_point, 1e-9);
    for (const core::Vec6& v : mv.via)
      EXPECT_LT((kin->forward(to_axes(m, v), 0).tip_mm - Vector3d(10, 5, 2)).norm(), 1e-9);
  }
  // F600 with the tip still: the rotary words' angle over F (RS274/NGC), as an inverse-time feed.
  const double deg = std::hypot(30.0, 90.0);
  EXPECT_EQ(ax.moves[1].feed_mode, core::FeedMode::InverseTime);
  EXPECT_NEAR(ax.moves[1].inverse_time_per_min, 600.0 / deg, 1e-12);
  EXPECT_TRUE(ax.moves[4].rapid);
  // The interpolator takes the axis-space path (its moves join end to start, within the machine's travels).
  const InterpResult r = interpolate(ax, m, InterpOptions{});
  EXPECT_GT(r.setpoints.samples(), 100);
}

// Lines and arcs with the table still stay lines and arcs in axis space (arcs when their plane maps onto a plane of
// the axes: C alone keeps XY arcs in XY); with the table tilted an XY arc is a via polyline; the tip is the
// programmed one at every axis-space point.
TEST(KinematicsToolpath, TcpLinesAndArcs) {
  const core::Machine m = xyzac();
  const core::ToolPath wp = read_tcp(
      "G21 G90 G94 G17\n"
      "G0 X10 Y5 Z2 A0 C0\n"   // 2
      "G1 X20 F300\n"          // 3 line, table at zero
      "G2 X30 Y5 I5 J0\n"      // 4 arc, table at zero
      "G0 C35\n"               // 5 C turns: the tip stays
      "G3 X20 Y5 I-5 J0 Z1\n"  // 6 helix with C = 35: XY arc in axis space, centre turned
      "G0 A-20\n"              // 7 tilt
      "G1 X25 Y0 F300\n"       // 8 line on the tilted table: a line
      "G2 X20 Y-5 I-5 J0\n"    // 9 arc on the tilted table: via points
      "M2\n");
  ASSERT_EQ(wp.moves.size(), 8u);
  const core::ToolPath ax = toolpath_in_axis_space(wp, m);
  const auto kin = make_kinematics(m);
  EXPECT_EQ(ax.moves[1].kind, core::MotionKind::Line);
  EXPECT_TRUE(ax.moves[1].via.empty());
  EXPECT_EQ(ax.moves[1].feed_mode, core::FeedMode::UnitsPerMinute);  // a tip feed is the axes' feed here
  EXPECT_EQ(ax.moves[2].kind, core::MotionKind::Arc);
  EXPECT_EQ(ax.moves[2].plane, core::ArcPlane::XY);
  EXPECT_EQ(ax.moves[4].kind, core::MotionKind::Arc);
  EXPECT_EQ(ax.moves[4].plane, core::ArcPlane::XY);
  EXPECT_TRUE(ax.moves[4].via.empty());
  EXPECT_EQ(ax.moves[4].rotation, wp.moves[4].rotation);
  // The centre (25, 5) turned with the table by +35 deg about Z (LinuxCNC's direction).
  const Vector3d c = Eigen::AngleAxisd(35 * kDegToRad, Vector3d::UnitZ()) * Vector3d(25, 5, 0);
  EXPECT_LT((Eigen::Vector2d(ax.moves[4].centre_mm) - c.head<2>()).norm(), 1e-12);
  EXPECT_EQ(ax.moves[6].kind, core::MotionKind::Line);
  EXPECT_TRUE(ax.moves[6].via.empty());
  EXPECT_EQ(ax.moves[7].kind, core::MotionKind::Line);
  EXPECT_GT(ax.moves[7].via.size(), 10u);
  EXPECT_EQ(ax.moves[7].feed_mode, core::FeedMode::UnitsPerMinute);  // rotary axes still, orthonormal: the same speed
  for (std::size_t i = 0; i < wp.moves.size(); ++i) {
    SCOPED_TRACE(i);
    double worst_point = 0, worst_chord = 0;
    if (ax.moves[i].kind == core::MotionKind::Arc) {
      // An axis-space arc: its end points (the interpolator draws the arc between them).
      for (const auto& [v, s] : {std::pair{ax.moves[i].start, 0.0}, std::pair{ax.moves[i].end, 1.0}})
        worst_point =
            std::max(worst_point, (kin->forward(to_axes(m, v), 0).tip_mm - programmed_tip(wp.moves[i], s)).norm());
    } else {
      check_move(m, *kin, wp.moves[i], ax.moves[i], 1e-3, &worst_point, &worst_chord);
    }
    EXPECT_LE(worst_point, 1e-9);
  }
}

// APT CL moves go through the inverse: the tool axis turns along its great circle while the tip moves, and the
// rotary axes continue from the previous move.
TEST(KinematicsToolpath, ClMovesThroughTheInverse) {
  const core::Machine m = mikron_machine();
  const fs::path p = write("five.apt",
                           "FEDRAT/1000.0\n"
                           "FROM/0.0,0.0,50.0,0.0,0.0,1.0\n"
                           "GOTO/10.0,0.0,5.0,0.0,0.0,1.0\n"
                           "GOTO/20.0,5.0,5.0,0.3,0.0,0.9539392\n"
                           "GOTO/20.0,25.0,0.0,0.0,0.4,0.9165151\n"
                           "GOTO/0.0,25.0,0.0,-0.2,-0.2,0.9591663\n"
                           "FINI\n");
  const core::ToolPath wp = program::read_program(p);
  ASSERT_EQ(wp.moves.size(), 4u);
  ASSERT_TRUE(wp.moves[1].tool_axis_end);
  const core::ToolPath ax = toolpath_in_axis_space(wp, m);
  const auto kin = make_kinematics(m);
  for (std::size_t i = 0; i < ax.moves.size(); ++i) {
    SCOPED_TRACE(i);
    const core::Move& a = ax.moves[i];
    const core::Move& w = wp.moves[i];
    if (i > 0) {
      EXPECT_EQ(a.start, ax.moves[i - 1].end);
    }
    const ToolPose e = kin->forward(to_axes(m, a.end), 0);
    EXPECT_LT((e.tip_mm - w.end.head<3>()).norm(), 1e-9);
    EXPECT_LT(angle(e.axis, w.tool_axis_end->normalized()), 1e-9);
    for (std::size_t k = 0; k < a.via.size(); ++k) {
      const ToolPose v = kin->forward(to_axes(m, a.via[k]), 0);
      EXPECT_LT((v.tip_mm - programmed_tip(w, a.via_s[k])).norm(), 1e-9);
    }
    if (i > 0) {
      EXPECT_FALSE(a.via.empty());
      EXPECT_EQ(a.feed_mode, core::FeedMode::InverseTime);
      EXPECT_NEAR(a.inverse_time_per_min, 1000.0 / (w.end.head<3>() - w.start.head<3>()).norm(), 1e-9);
    }
  }
  // The first move keeps a vertical tool: C stays at its start (zero), A at zero: a straight line.
  EXPECT_TRUE(ax.moves[0].via.empty());
  // The second leaves the vertical (singular) pose towards +X: C turns first on the spot (via points at s = 0, the
  // tip and tool axis held), then A tilts.
  ASSERT_FALSE(ax.moves[1].via_s.empty());
  EXPECT_EQ(ax.moves[1].via_s.front(), 0.0);
  EXPECT_GT(std::abs(ax.moves[1].end[core::kC]), 80 * kDegToRad);
  EXPECT_EQ(ax.moves[0].end[core::kA], 0.0);
  EXPECT_EQ(ax.moves[0].end[core::kC], 0.0);
}

// LinuxCNC's boat-xyzac.ngc demo on xyzac-trt in tool-centre-point mode (its M428): every axis-space point puts the
// tip where the program does, every axis stays within the sim machine's travels.
TEST(KinematicsToolpath, BoatXyzacOnXyzacTrt) {
  if (!fs::exists(kGcodeData))
    GTEST_SKIP() << "reference data not found at " << kGcodeData.string()
                 << " (../shared/data is written outside the project; a fresh clone does not have it)";
  const core::Machine m = xyzac();
  program::GcodeOptions go;
  go.tool_table = kGcodeData / "tooltables" / "xyzac-trt.tbl";
  go.no_motion_mcodes = {428, 429};
  core::ToolPath wp = program::read_gcode(kGcodeData / "programs" / "boat-xyzac.ngc", go);
  for (core::Move& mv : wp.moves) mv.tcp = true;
  const auto t0 = std::chrono::steady_clock::now();
  const core::ToolPath ax = toolpath_in_axis_space(wp, m);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto kin = make_kinematics(m);
  std::size_t curved = 0, vias = 0;
  double worst = 0, worst_chord = 0;
  for (std::size_t i = 0; i < ax.moves.size(); ++i) {
    const core::Move& a = ax.moves[i];
    if (!a.via.empty()) ++curved;
    vias += a.via.size();
    for (const core::Vec6* v : {&a.start, &a.end}) ASSERT_TRUE(within_travel(m, to_axes(m, *v))) << "move " << i;
    for (const core::Vec6& v : a.via) ASSERT_TRUE(within_travel(m, to_axes(m, v))) << "move " << i;
    if (a.kind == core::MotionKind::Line) {
      check_move(m, *kin, wp.moves[i], a, 1e-3, &worst, &worst_chord);
    } else {
      worst = std::max(worst, (kin->forward(to_axes(m, a.end), 0).tip_mm - wp.moves[i].end.head<3>()).norm());
    }
  }
  EXPECT_LE(worst, 1e-9);
  EXPECT_LE(worst_chord, 1e-3 * 1.01);
  EXPECT_GT(curved, 5u);  // the table turns at the safe height between passes
  std::printf("boat-xyzac: %zu moves, %zu with via points (%zu points), converted in %.3f s\n", ax.moves.size(), curved,
              vias, secs);
}

// ---- The interpolator in joint space ------------------------------------------------------------------------------

// The programmed tool pose of a workpiece-frame move at s: the tip along its line, the tool axis along the great
// circle of its end vectors (CL) or, for tool-centre-point moves, the axis the linearly moving rotary words give
// (through forward: it depends on the rotary axes only). Written here from the definitions, not from kinematics.cpp.
ToolPose programmed_pose(const core::Machine& m, const Kinematics& kin, const core::Move& w, double s) {
  ToolPose p;
  p.tip_mm = w.start.head<3>() + s * (w.end.head<3>() - w.start.head<3>());
  if (w.tool_axis_start) {
    const Vector3d a0 = w.tool_axis_start->normalized(), a1 = w.tool_axis_end->normalized();
    const double ang = angle(a0, a1);
    p.axis = ang < 1e-12 ? a0 : Vector3d((std::sin((1 - s) * ang) * a0 + std::sin(s * ang) * a1) / std::sin(ang));
  } else {
    p.axis = kin.forward(to_axes(m, w.start + s * (w.end - w.start)), 0).axis;
  }
  return p;
}

struct PoseDeviation {
  double tip_mm = 0, axis_rad = 0;
};

// The largest distance of the setpoints' tool poses (through forward) from the programmed poses: for each setpoint
// the programmed pose nearest in max(|tip - tip(s)|, 100 mm x angle(axis, axis(s))) over the setpoint's move and its
// neighbours (a grid of s, refined by golden sections), then the tip and axis parts of that pose's distance.
PoseDeviation pose_deviation(const core::Machine& m, const Kinematics& kin, const core::ToolPath& wp,
                             const core::Setpoints& sp) {
  constexpr int kGrid = 100;
  std::vector<std::vector<ToolPose>> grid(wp.moves.size());
  for (std::size_t i = 0; i < wp.moves.size(); ++i)
    for (int k = 0; k <= kGrid; ++k) grid[i].push_back(programmed_pose(m, kin, wp.moves[i], k / double(kGrid)));
  PoseDeviation worst;
  for (Eigen::Index r = 0; r < sp.samples(); ++r) {
    const ToolPose p = kin.forward(sp.position.row(r).transpose(), wp.moves.front().tool_length_offset_mm);
    auto dist = [&](const ToolPose& q) {
      return std::max((p.tip_mm - q.tip_mm).norm(), 100.0 * angle(p.axis, q.axis));
    };
    const int mi = sp.move_index[r];
    double best = 1e300;
    PoseDeviation best_parts;
    for (int j = std::max(0, mi - 1); j <= std::min<int>(static_cast<int>(wp.moves.size()) - 1, mi + 1); ++j) {
      const auto& g = grid[static_cast<std::size_t>(j)];
      int kb = 0;
      for (int k = 0; k <= kGrid; ++k)
        if (dist(g[static_cast<std::size_t>(k)]) < dist(g[static_cast<std::size_t>(kb)])) kb = k;
      double lo = std::max(0, kb - 1) / double(kGrid), hi = std::min(kGrid, kb + 1) / double(kGrid);
      const core::Move& w = wp.moves[static_cast<std::size_t>(j)];
      for (int it = 0; it < 60; ++it) {
        const double a = lo + 0.382 * (hi - lo), b = lo + 0.618 * (hi - lo);
        if (dist(programmed_pose(m, kin, w, a)) < dist(programmed_pose(m, kin, w, b)))
          hi = b;
        else
          lo = a;
      }
      const ToolPose q = programmed_pose(m, kin, w, 0.5 * (lo + hi));
      if (dist(q) < best) {
        best = dist(q);
        best_parts = {(p.tip_mm - q.tip_mm).norm(), angle(p.axis, q.axis)};
      }
    }
    worst.tip_mm = std::max(worst.tip_mm, best_parts.tip_mm);
    worst.axis_rad = std::max(worst.axis_rad, best_parts.axis_rad);
  }
  return worst;
}

// Largest |finite difference| / limit over every axis and order (the hard requirement: <= 1).
double kinematic_limit_ratio(const core::Machine& m, const core::Setpoints& sp) {
  const core::AxisPeaks pk = core::finite_difference_peaks(sp);
  double worst = 0;
  for (std::size_t i = 0; i < m.axes.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    worst = std::max({worst, pk.velocity[k] / m.axes[i].max_velocity, pk.acceleration[k] / m.axes[i].max_acceleration,
                      pk.jerk[k] / m.axes[i].max_jerk});
  }
  return worst;
}

core::Move cl_move(const Vector3d& p0, const Vector3d& p1, const Vector3d& a0, const Vector3d& a1, double feed,
                   int line) {
  core::Move mv;
  mv.start.head<3>() = p0;
  mv.end.head<3>() = p1;
  mv.tool_axis_start = a0;
  mv.tool_axis_end = a1;
  mv.feed_mm_per_min = feed;
  mv.source_line = line;
  return mv;
}

// Random five-axis CL paths (tips in a 60 x 60 x 20 mm box, tool axes tilted 15..60 deg at random azimuths, 1 m/min)
// and tool-centre-point paths (random tips, A in -60..0 deg, C turning up to half a turn per move) on xyzac-trt,
// through toolpath_in_axis_space and the interpolator at its 20 um tolerance: no axis exceeds its velocity,
// acceleration or jerk limit (finite differences of the setpoints, as the drives see them), and every setpoint's tool
// pose is within the tolerance of the programmed pose (tip, and the tool axis at 100 mm from the tip).
TEST(KinematicsInterp, RandomFiveAxisPathsKeepTheLimitsAndTheTolerance) {
  const core::Machine m = xyzac();
  const auto kin = make_kinematics(m);
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> u(-1, 1), u01(0, 1);
  InterpOptions io;
  io.tolerance_mm = 0.020;
  for (int trial = 0; trial < 4; ++trial) {
    SCOPED_TRACE(trial);
    const bool tcp = trial % 2 == 1;
    core::ToolPath wp;
    wp.source_path = "random.cl";
    Vector3d p0(30 * u(rng), 30 * u(rng), 10 * u(rng));
    Vector3d a0 = polar((15 + 45 * u01(rng)) * kDegToRad, kPi * u(rng));
    double ra = -60 * kDegToRad * u01(rng), rc = 2 * kPi * u(rng);
    for (int k = 0; k < 4; ++k) {
      const Vector3d p1(30 * u(rng), 30 * u(rng), 10 * u(rng));
      const Vector3d a1 = polar((15 + 45 * u01(rng)) * kDegToRad, kPi * u(rng));
      const double ra1 = -60 * kDegToRad * u01(rng), rc1 = rc + kPi * u(rng);
      core::Move mv = cl_move(p0, p1, a0, a1, 1000, k + 1);
      if (tcp) {
        mv.tool_axis_start.reset();
        mv.tool_axis_end.reset();
        mv.tcp = true;
        mv.start[core::kA] = ra, mv.end[core::kA] = ra1, mv.start[core::kC] = rc, mv.end[core::kC] = rc1;
      }
      wp.moves.push_back(mv);
      p0 = p1, a0 = a1, ra = ra1, rc = rc1;
    }
    wp.initial_position = wp.moves.front().start;
    const core::ToolPath ax = toolpath_in_axis_space(wp, m);
    const InterpResult r = interpolate(ax, m, io);
    // The interpolator keeps the limits in degrees; converted to rad here, the ratio may round to 1 + 1e-15.
    EXPECT_LE(kinematic_limit_ratio(m, r.setpoints), 1.0 + 1e-9);
    const PoseDeviation d = pose_deviation(m, *kin, wp, r.setpoints);
    EXPECT_LE(d.tip_mm, io.tolerance_mm);
    EXPECT_LE(100.0 * d.axis_rad, io.tolerance_mm);
    // The end is exact: the last setpoint is the last move's end.
    EXPECT_LT((r.setpoints.position.bottomRows(1).transpose() - to_axes(m, ax.moves.back().end)).norm(), 1e-9);
    std::printf("trial %d (%s): %.2f s, %d blends, tip %.2f um, axis %.2f urad, limits used %.4f\n", trial,
                tcp ? "tcp" : "cl", r.stats.cycle_time_s, r.stats.blends, d.tip_mm * 1e3, d.axis_rad * 1e6,
                kinematic_limit_ratio(m, r.setpoints));
  }
}

// Inverse-time moves keep their programmed duration in axis space: a TCP move turning C by 90 deg with the tip still
// at G93 F6 (10 s: RS274/NGC, an inverse-time move lasts 1/F minutes) takes 10 s when the axes can (C at 9 deg/s, far
// below its 30 deg/s), plus what starting and stopping cost: each at most v/a + 2 a/j = 0.23 s (300 deg/s^2,
// 3000 deg/s^3; the jerk ramps and the interpolator's FIR filter of length a/j, core/interp.cpp).
TEST(KinematicsInterp, InverseTimeDurationIsKept) {
  const core::Machine m = xyzac();
  const core::ToolPath wp = read_tcp(
      "G21 G90 G94\n"
      "G0 X10 Y5 Z2 A-20 C0\n"
      "G93 G1 C90 F6\n"
      "M2\n");
  const core::ToolPath ax = toolpath_in_axis_space(wp, m);
  ASSERT_EQ(ax.moves[1].feed_mode, core::FeedMode::InverseTime);
  const InterpResult r = interpolate(ax, m, InterpOptions{});
  double t1 = 0;
  for (Eigen::Index k = 0; k < r.setpoints.samples(); ++k)
    if (r.setpoints.move_index[k] == 1) t1 += r.setpoints.period_s;
  EXPECT_GT(t1, 10.0 - 1e-3);
  EXPECT_LT(t1, 10.0 + 2 * (9.0 / 300.0 + 2 * 300.0 / 3000.0));
  EXPECT_LE(kinematic_limit_ratio(m, r.setpoints), 1.0 + 1e-9);
}

}  // namespace
}  // namespace vmsim::motion
