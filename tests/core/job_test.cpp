// Machine and job files. References: the Mikron UCP 710 limits of Duong et al. Table I (X 30 m/min, 2.5 m/s^2,
// 10 m/s^3; Z 30 m/min, 2.1 m/s^2, 100 m/s^3) converted by hand to mm/s, mm/s^2, mm/s^3, and the DESIGN.md rule
// that every error names the file, the line and the full key. Small files are written to a per-test temp dir.
#include "core/error.hpp"
#include "core/job.hpp"
#include "core/machine.hpp"
#include "core/toolpath.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include "tests/test_paths.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

namespace vmsim::core {
namespace {

namespace fs = std::filesystem;

fs::path test_dir() { return vmsim::test::test_scratch_dir("vmsim_job_test"); }
fs::path write(const std::string& name, const std::string& text) {
  return vmsim::test::write_test_file("vmsim_job_test", name, text);
}

// A valid machine file; tests replace one line to break it. Line numbers are commented for the assertions.
const char* kMachine =
    "[machine]\n"                            // 1
    "name = \"test mill\"\n"                 // 2
    "kinematics = \"xyz\"\n"                 // 3
    "\n"                                     // 4
    "[[axes]]\n"                             // 5
    "name = \"X\"\n"                         // 6
    "type = \"linear\"\n"                    // 7
    "travel_mm = [-100.0, 100.0]\n"          // 8
    "max_velocity_m_per_min = 30.0\n"        // 9
    "max_acceleration_m_per_s2 = 2.5\n"      // 10
    "max_jerk_m_per_s3 = 10.0\n"             // 11
    "\n"                                     // 12
    "[[axes]]\n"                             // 13
    "name = \"Y\"\n"                         // 14
    "type = \"linear\"\n"                    // 15
    "travel_mm = [-100.0, 100.0]\n"          // 16
    "max_velocity_m_per_min = 30\n"          // 17 (an integer is a number too)
    "max_acceleration_m_per_s2 = 2.5\n"      // 18
    "max_jerk_m_per_s3 = 10.0\n"             // 19
    "\n"                                     // 20
    "[[axes]]\n"                             // 21
    "name = \"Z\"\n"                         // 22
    "type = \"linear\"\n"                    // 23
    "travel_mm = [-50.0, 50.0]\n"            // 24
    "max_velocity_m_per_min = 30.0\n"        // 25
    "max_acceleration_m_per_s2 = 2.1\n"      // 26
    "max_jerk_m_per_s3 = 100.0\n"            // 27
    "\n"                                     // 28
    "[[axes]]\n"                             // 29
    "name = \"A\"\n"                         // 30
    "type = \"rotary\"\n"                    // 31
    "travel_deg = [-120.0, 120.0]\n"         // 32
    "max_velocity_deg_per_s = 90.0\n"        // 33
    "max_acceleration_deg_per_s2 = 200.0\n"  // 34
    "max_jerk_deg_per_s3 = 2000.0\n";        // 35

// kMachine with line `line` (1-based) replaced by `text` ("" deletes its content).
std::string machine_with(int line, const std::string& text) {
  std::vector<std::string> lines;
  std::string s = kMachine, cur;
  for (char c : s) {
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

std::string machine_error(const std::string& text) {
  const fs::path p = write("machine.toml", text);
  try {
    load_machine(p);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// Asserts that `message` starts with "<file>:<line>:" and contains every one of `parts`.
void expect_error(const std::string& message, const fs::path& file, int line, const std::vector<std::string>& parts) {
  const std::string prefix = file.string() + ":" + std::to_string(line) + ":";
  EXPECT_EQ(message.rfind(prefix, 0), 0u)
      << "expected the message to start with " << prefix << "\nmessage: " << message;
  for (const auto& part : parts)
    EXPECT_NE(message.find(part), std::string::npos) << "missing \"" << part << "\" in: " << message;
}

TEST(Machine, LoadsTheMikronUcp710WithUnitsConverted) {
  const fs::path file = fs::path(VMSIM_SOURCE_DIR) / "parts/machines/mikron_ucp710.toml";
  const Machine m = load_machine(file);
  EXPECT_EQ(m.name, "Mikron UCP 710 (Siemens 840D)");
  EXPECT_EQ(m.kinematics, "chain");  // its A/C table chain: tests/core/kinematics_test.cpp
  EXPECT_EQ(m.source_file, file.string());
  ASSERT_EQ(m.axes.size(), 5u);

  const MachineAxis& x = m.axes[static_cast<std::size_t>(m.axis_index(kX))];
  EXPECT_EQ(x.name, "X");
  EXPECT_EQ(x.kind, AxisKind::Linear);
  EXPECT_DOUBLE_EQ(x.max_velocity, 500.0);       // 30 m/min = 30000 mm / 60 s
  EXPECT_DOUBLE_EQ(x.max_acceleration, 2500.0);  // 2.5 m/s^2
  EXPECT_DOUBLE_EQ(x.max_jerk, 10000.0);         // 10 m/s^3
  EXPECT_DOUBLE_EQ(x.travel_min, -355.0);
  EXPECT_DOUBLE_EQ(x.travel_max, 355.0);
  EXPECT_FALSE(x.continuous);

  const MachineAxis& z = m.axes[static_cast<std::size_t>(m.axis_index(kZ))];
  EXPECT_DOUBLE_EQ(z.max_velocity, 500.0);
  EXPECT_DOUBLE_EQ(z.max_acceleration, 2100.0);  // 2.1 m/s^2
  EXPECT_DOUBLE_EQ(z.max_jerk, 100000.0);        // 100 m/s^3

  const MachineAxis& a = m.axes[static_cast<std::size_t>(m.axis_index(kA))];
  EXPECT_EQ(a.kind, AxisKind::Rotary);
  EXPECT_EQ(a.program_axis, kA);
  EXPECT_NEAR(a.travel_min, -120.0 * std::numbers::pi / 180.0, 1e-12);  // -2.0944 rad
  EXPECT_NEAR(a.travel_max, 2.0 * std::numbers::pi / 3.0, 1e-12);
  EXPECT_NEAR(a.max_velocity, std::numbers::pi / 2.0, 1e-12);  // 90 deg/s
  EXPECT_NEAR(a.max_acceleration, 200.0 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_NEAR(a.max_jerk, 2000.0 * std::numbers::pi / 180.0, 1e-12);

  const MachineAxis& c = m.axes[static_cast<std::size_t>(m.axis_index(kC))];
  EXPECT_TRUE(c.continuous);  // no travel_deg
  EXPECT_NEAR(c.max_velocity, 120.0 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_EQ(m.axis_index(kB), -1);
}

TEST(Machine, SmallValidFile) {
  const Machine m = load_machine(write("machine.toml", kMachine));
  ASSERT_EQ(m.axes.size(), 4u);
  EXPECT_DOUBLE_EQ(m.axes[1].max_velocity, 500.0);  // integer 30 read as a number
  EXPECT_DOUBLE_EQ(m.axes[2].travel_min, -50.0);
}

TEST(Machine, UnknownKeysAreErrorsWithTheirFullKey) {
  const fs::path file = test_dir() / "machine.toml";
  expect_error(machine_error(machine_with(3, "kinematic = \"xyz\"")), file, 3, {"unknown key 'machine.kinematic'"});
  expect_error(machine_error(machine_with(11, "max_jerk_m_per_s3 = 10.0\nmax_jerk = 3.0")), file, 12,
               {"unknown key 'axes[0].max_jerk'"});
  // A linear axis's travel is in mm; travel_deg there is a mistake, not something to ignore.
  expect_error(machine_error(machine_with(24, "travel_mm = [-50.0, 50.0]\ntravel_deg = [0, 1]")), file, 25,
               {"unknown key 'axes[2].travel_deg'"});
  expect_error(machine_error(std::string(kMachine) + "[spindle]\nmax_rpm = 24000\n"), file, 36,
               {"unknown key 'spindle'"});
}

TEST(Machine, WrongTypesNameTheKey) {
  const fs::path file = test_dir() / "machine.toml";
  expect_error(machine_error(machine_with(9, "max_velocity_m_per_min = \"fast\"")), file, 9,
               {"key 'axes[0].max_velocity_m_per_min'", "expected a number, found a string"});
  expect_error(machine_error(machine_with(2, "name = 42")), file, 2,
               {"key 'machine.name'", "expected a string, found an integer"});
  expect_error(machine_error(machine_with(16, "travel_mm = [-100.0, \"a\"]")), file, 16,
               {"key 'axes[1].travel_mm'", "finite numbers"});
  expect_error(machine_error(machine_with(16, "travel_mm = [-100.0, 0.0, 100.0]")), file, 16,
               {"key 'axes[1].travel_mm'", "expected 2 numbers, found 3"});
  expect_error(machine_error(machine_with(16, "travel_mm = -100.0")), file, 16,
               {"key 'axes[1].travel_mm'", "expected an array of numbers, found a number"});
  expect_error(machine_error(machine_with(26, "max_acceleration_m_per_s2 = nan")), file, 26,
               {"key 'axes[2].max_acceleration_m_per_s2'", "finite"});
  expect_error(machine_error(machine_with(26, "max_acceleration_m_per_s2 = -2.1")), file, 26,
               {"key 'axes[2].max_acceleration_m_per_s2'", "expected a number > 0, found -2.1"});
  expect_error(machine_error(machine_with(1, "machine = 3")), file, 1,
               {"key 'machine'", "expected a table, found an integer"});
}

TEST(Machine, MissingRequiredKeysNameTheTableLine) {
  const fs::path file = test_dir() / "machine.toml";
  // A missing key has no line of its own: the message points at the table that should hold it.
  expect_error(machine_error(machine_with(11, "")), file, 5, {"key 'axes[0].max_jerk_m_per_s3'", "missing"});
  expect_error(machine_error(machine_with(33, "")), file, 29, {"key 'axes[3].max_velocity_deg_per_s'", "missing"});
  expect_error(machine_error(machine_with(2, "")), file, 1, {"key 'machine.name'", "missing (expected a string)"});
  // Without travel_deg a rotary axis is continuous, not an error.
  EXPECT_TRUE(load_machine(write("machine.toml", machine_with(32, ""))).axes[3].continuous);
}

TEST(Machine, MissingTablesNameTheFile) {
  const fs::path file = test_dir() / "machine.toml";
  // No [machine] table: the root table has no line of its own, so the message names line 1.
  const std::string no_machine = machine_error(std::string(kMachine).substr(std::string(kMachine).find("[[axes]]")));
  expect_error(no_machine, file, 1, {"key 'machine'", "missing table [machine]"});
  const std::string no_axes = machine_error("[machine]\nname = \"m\"\n");
  expect_error(no_axes, file, 1, {"key 'axes'", "expected at least one [[axes]] table"});
  // Only X and Y: Z is required by the "xyz" kinematics.
  const std::string no_z =
      machine_error(std::string(kMachine).substr(0, std::string(kMachine).find("[[axes]]\nname = \"Z\"")));
  expect_error(no_z, file, 5, {"key 'axes'", "needs an axis named Z"});  // the first [[axes]]
}

TEST(Machine, BadChoicesAndImpossibleValues) {
  const fs::path file = test_dir() / "machine.toml";
  expect_error(machine_error(machine_with(6, "name = \"Q\"")), file, 6,
               {"key 'axes[0].name'", "\"Q\" is not one of \"X\", \"Y\", \"Z\", \"A\", \"B\", \"C\""});
  expect_error(machine_error(machine_with(31, "type = \"angular\"")), file, 31,
               {"key 'axes[3].type'", "\"angular\" is not one of \"linear\", \"rotary\""});
  expect_error(machine_error(machine_with(31, "type = \"linear\"")), file, 31,
               {"key 'axes[3].type'", "axis A must be rotary"});
  expect_error(machine_error(machine_with(3, "kinematics = \"ac-table\"")), file, 3, {"key 'machine.kinematics'"});
  expect_error(machine_error(machine_with(8, "travel_mm = [100.0, 100.0]")), file, 8,
               {"key 'axes[0].travel_mm'", "min < max"});
  expect_error(machine_error(machine_with(8, "travel_mm = [100.0, -100.0]")), file, 8,
               {"key 'axes[0].travel_mm'", "min < max"});
  expect_error(machine_error(machine_with(32, "travel_deg = [10, -10]")), file, 32,
               {"key 'axes[3].travel_deg'", "min < max"});
  expect_error(machine_error(machine_with(14, "name = \"X\"")), file, 14,
               {"key 'axes[1].name'", "axis X is defined twice"});
  expect_error(machine_error(machine_with(22, "name = \"B\"")), file, 23,
               {"key 'axes[2].type'", "axis B must be rotary"});
}

// Regressions: a limit that overflows in the unit conversion used to load as an infinite limit; a nan in an array
// was reported as "an element that is a number"; a directory read as an empty file ("missing table").
TEST(Machine, OverflowNanAndDirectory) {
  const fs::path file = test_dir() / "machine.toml";
  expect_error(machine_error(machine_with(9, "max_velocity_m_per_min = 1e308")), file, 9,
               {"key 'axes[0].max_velocity_m_per_min'", "finite limit"});
  expect_error(machine_error(machine_with(8, "travel_mm = [nan, 100.0]")), file, 8,
               {"key 'axes[0].travel_mm'", "found nan or inf"});
  try {
    load_machine(test_dir());
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(test_dir().string() + ": cannot open file", 0), 0u) << e.what();
  }
}

TEST(Machine, MissingFileAndSyntaxErrors) {
  const fs::path missing = test_dir() / "nope.toml";
  try {
    load_machine(missing);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(missing.string() + ": cannot open", 0), 0u) << e.what();
  }
  const fs::path file = test_dir() / "machine.toml";
  expect_error(machine_error(machine_with(10, "max_acceleration_m_per_s2 = ")), file, 10, {"TOML syntax error"});
  expect_error(machine_error(machine_with(13, "[[axes]")), file, 13, {"TOML syntax error"});
}

// ---- job files ----

struct JobFiles {
  fs::path dir, job, machine, program;
};

// A job directory with a machine file, a program and a job file whose text is `job_text`.
JobFiles job_files(const std::string& job_text) {
  JobFiles f;
  f.dir = test_dir();
  f.machine = write("machine.toml", kMachine);
  f.program = write("part.apt", "GOTO/0,0,0\n");
  f.job = write("job.toml", job_text);
  return f;
}

const char* kJob =
    "[job]\n"                        // 1
    "name = \"plane\"\n"             // 2
    "machine = \"machine.toml\"\n"   // 3 (relative to the job file)
    "program = \"part.apt\"\n"       // 4
    "\n"                             // 5
    "[tool]\n"                       // 6
    "type = \"bullnose\"\n"          // 7
    "diameter_mm = 10.0\n"           // 8
    "corner_radius_mm = 1.0\n"       // 9
    "flute_length_mm = 25.0\n"       // 10
    "\n"                             // 11
    "[stock]\n"                      // 12
    "type = \"box\"\n"               // 13
    "min_mm = [0, 0, -20]\n"         // 14
    "max_mm = [100.0, 50.0, 0.0]\n"  // 15
    "\n"                             // 16
    "[interpolation]\n"              // 17
    "period_ms = 1\n"                // 18
    "tolerance_mm = 0.02\n";         // 19

std::string job_with(int line, const std::string& text) {
  std::vector<std::string> lines;
  std::string cur;
  for (char c : std::string(kJob)) {
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

std::string job_error(const JobFiles& f) {
  try {
    load_job(f.job);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Job, LoadsAValidJob) {
  const JobFiles f = job_files(kJob);
  const Job job = load_job(f.job);
  EXPECT_EQ(job.name, "plane");
  EXPECT_EQ(job.file, f.job);
  EXPECT_TRUE(fs::equivalent(job.machine_file, f.machine));
  EXPECT_TRUE(fs::equivalent(job.program_file, f.program));
  EXPECT_FALSE(job.tool_table_file.has_value());
  EXPECT_EQ(job.machine.name, "test mill");
  EXPECT_EQ(job.tool.shape, ToolShape::BullNose);
  EXPECT_DOUBLE_EQ(job.tool.diameter_mm, 10.0);
  EXPECT_DOUBLE_EQ(job.tool.corner_radius_mm, 1.0);
  EXPECT_DOUBLE_EQ(job.tool.flute_length_mm, 25.0);
  EXPECT_DOUBLE_EQ(job.tool.length_mm, 50.0);
  EXPECT_EQ(job.stock.kind, StockSpec::Kind::Box);
  EXPECT_TRUE(job.stock.min_mm.isApprox(Eigen::Vector3d(0, 0, -20)));
  EXPECT_TRUE(job.stock.max_mm.isApprox(Eigen::Vector3d(100, 50, 0)));
  EXPECT_DOUBLE_EQ(job.interp.period_s, 1e-3);
  EXPECT_DOUBLE_EQ(job.interp.tolerance_mm, 0.02);
}

// [[tools]] (issue 24): one per T number (or 840D name), in the job's order; each with the [tool] keys.
TEST(Job, ToolsTableGivesOneToolPerNumber) {
  const JobFiles f = job_files(
      "[job]\nmachine = \"machine.toml\"\nprogram = \"part.apt\"\n"
      "[[tools]]\nnumber = 2\ntype = \"flat\"\ndiameter_mm = 6.35\nflute_length_mm = 19.0\nlength_mm = 60.0\n"
      "[[tools]]\nnumber = 1\ntype = \"bull\"\ndiameter_mm = 10.0\ncorner_radius_mm = 2.0\n"
      "[[tools]]\nname = \"ENTFRAESER_D8\"\ntype = \"ball\"\ndiameter_mm = 8.0\n");
  const Job job = load_job(f.job);
  EXPECT_FALSE(job.tool_given);
  ASSERT_EQ(job.tools.size(), 3u);
  EXPECT_EQ(job.tools[0].number, 2);
  EXPECT_EQ(job.tools[0].shape, ToolShape::Flat);
  EXPECT_DOUBLE_EQ(job.tools[0].diameter_mm, 6.35);
  EXPECT_DOUBLE_EQ(job.tools[0].corner_radius_mm, 0.0);
  EXPECT_DOUBLE_EQ(job.tools[0].flute_length_mm, 19.0);
  EXPECT_DOUBLE_EQ(job.tools[0].length_mm, 60.0);
  EXPECT_EQ(job.tools[1].number, 1);
  EXPECT_EQ(job.tools[1].shape, ToolShape::BullNose);  // "bull" is "bullnose"
  EXPECT_DOUBLE_EQ(job.tools[1].corner_radius_mm, 2.0);
  EXPECT_DOUBLE_EQ(job.tools[1].flute_length_mm, 20.0);  // default 2 x diameter
  EXPECT_EQ(job.tools[2].number, -1);                    // by name only
  EXPECT_EQ(job.tools[2].name, "ENTFRAESER_D8");
  EXPECT_DOUBLE_EQ(job.tools[2].corner_radius_mm, 4.0);
}

TEST(Job, ToolsErrorsNameTheKeys) {
  const std::string head = "[job]\nmachine = \"machine.toml\"\nprogram = \"part.apt\"\n";
  const struct {
    std::string body;
    std::vector<std::string> expected;
  } cases[] = {
      // Both: the error names both tables.
      {"[tool]\ntype = \"ball\"\ndiameter_mm = 6.0\n[[tools]]\nnumber = 1\ntype = \"ball\"\ndiameter_mm = 6.0\n",
       {"job.toml:", "key 'tools'", "both [tool] and [[tools]]"}},
      {"[[tools]]\ntype = \"ball\"\ndiameter_mm = 6.0\n", {"key 'tools[0].number'", "missing", "T number"}},
      {"[[tools]]\nnumber = 1\ntype = \"ball\"\ndiameter_mm = 6.0\n[[tools]]\nnumber = 1\ntype = \"flat\"\n"
       "diameter_mm = 3.0\n",
       {"key 'tools[1].number'", "T1 is described twice"}},
      {"[[tools]]\nnumber = -3\ntype = \"ball\"\ndiameter_mm = 6.0\n", {"key 'tools[0].number'", "found -3"}},
      {"[[tools]]\nnumber = 1\ntype = \"ball\"\ndiameter_mm = 6.0\nall_tools = true\n",
       {"unknown key 'tools[0].all_tools'"}},
      {"[[tools]]\nnumber = 1\ntype = \"cone\"\ndiameter_mm = 6.0\n", {"key 'tools[0].type'"}},
  };
  for (const auto& c : cases) {
    const std::string err = job_error(job_files(head + c.body));
    for (const std::string& e : c.expected) EXPECT_NE(err.find(e), std::string::npos) << c.body << "\n -> " << err;
  }
  // [tool] all_tools = true: accepted there.
  const Job job = load_job(job_files(head + "[tool]\ntype = \"flat\"\ndiameter_mm = 3.0\nall_tools = true\n").job);
  EXPECT_TRUE(job.tool_all_numbers);
  EXPECT_TRUE(job.tools.empty());
}

TEST(Job, OptionalTablesTakeTheirDefaults) {
  const JobFiles f = job_files("[job]\nmachine = \"machine.toml\"\nprogram = \"part.apt\"\n");
  const Job job = load_job(f.job);
  EXPECT_EQ(job.name, "job");  // the file's stem
  EXPECT_EQ(job.stock.kind, StockSpec::Kind::None);
  EXPECT_EQ(job.tool.shape, ToolShape::Ball);
  EXPECT_DOUBLE_EQ(job.interp.period_s, 1e-3);
}

TEST(Job, ErrorsNameTheFileLineAndFullKey) {
  const struct {
    int line;
    const char* replacement;
    int error_line;
    std::vector<std::string> parts;
  } cases[] = {
      {2, "nmae = \"plane\"", 2, {"unknown key 'job.nmae'"}},
      {10, "flute_lenght_mm = 25.0", 10, {"unknown key 'tool.flute_lenght_mm'"}},
      {8, "diameter_mm = \"10\"", 8, {"key 'tool.diameter_mm'", "expected a number, found a string"}},
      {8, "diameter_mm = 0", 8, {"key 'tool.diameter_mm'", "expected a number > 0"}},
      {7, "type = \"conical\"", 7, {"key 'tool.type'", "\"conical\" is not one of \"ball\", \"flat\", \"bullnose\""}},
      {9, "corner_radius_mm = 5.0", 9, {"key 'tool.corner_radius_mm'", "less than the radius 5 mm"}},
      {10, "flute_length_mm = 80.0\nlength_mm = 60", 11, {"key 'tool.length_mm'", "at least flute_length_mm"}},
      {13, "type = \"sphere\"", 13, {"key 'stock.type'", "\"sphere\" is not one of \"box\", \"stl\""}},
      {15, "max_mm = [100.0, 50.0, -20.0]", 15, {"key 'stock.max_mm'", "max_mm > min_mm on every axis"}},
      {14, "min_mm = [0, 0]", 14, {"key 'stock.min_mm'", "expected 3 numbers, found 2"}},
      {13, "type = \"stl\"\nfile = \"stock.stl\"", 14, {"key 'stock.file'", "does not exist"}},
      {18, "period_ms = 250", 18, {"key 'interpolation.period_ms'", "expected <= 100"}},
      {19, "tolerance_mm = -0.02", 19, {"key 'interpolation.tolerance_mm'", "expected a number > 0"}},
      {3, "machine = \"no_such_machine.toml\"", 3, {"key 'job.machine'", "no_such_machine.toml", "does not exist"}},
      {4, "program = \"no_such_program.ngc\"", 4, {"key 'job.program'", "no_such_program.ngc", "does not exist"}},
      {4, "program = 7", 4, {"key 'job.program'", "expected a string, found an integer"}},
      {4, "program = \"part.apt\"\ntool_table = \"tools.tbl\"", 5, {"key 'job.tool_table'", "does not exist"}},
      {4, "program = \"part.apt\"\nfeed_plan = \"plan.csv\"", 5, {"key 'job.feed_plan'", "plan.csv", "does not exist"}},
      {4, "program = \"part.apt\"\nfeed_plan = 3", 5, {"key 'job.feed_plan'", "expected a string, found an integer"}},
      {3, "", 1, {"key 'job.machine'", "missing (expected a file path)"}},
      {17, "[interpolaton]", 17, {"unknown key 'interpolaton'"}},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.replacement);
    const JobFiles f = job_files(job_with(c.line, c.replacement));
    expect_error(job_error(f), f.job, c.error_line, c.parts);
  }
}

// [job] feed_plan (vmsim plan-feed's feed_plan.csv): a path relative to the job file, read only when it exists; its
// content is checked where the chain follows it (sim::Chain, methods/feedplan_file).
TEST(Job, FeedPlanIsAFileBesideTheJob) {
  const JobFiles f = job_files(job_with(4, "program = \"part.apt\"\nfeed_plan = \"plans/plan.csv\""));
  fs::create_directories(f.dir / "plans");
  const fs::path plan = write("plans/plan.csv", "# vmsim feed plan 1\n");
  const Job job = load_job(f.job);
  ASSERT_TRUE(job.feed_plan_file.has_value());
  EXPECT_TRUE(fs::equivalent(*job.feed_plan_file, plan));
  EXPECT_FALSE(load_job(job_files(kJob).job).feed_plan_file.has_value());
}

TEST(Job, MissingJobTableAndFiles) {
  {
    const JobFiles f = job_files("[tool]\ntype = \"ball\"\ndiameter_mm = 6\n");
    const std::string msg = job_error(f);
    EXPECT_EQ(msg.rfind(f.job.string() + ":", 0), 0u) << msg;
    EXPECT_NE(msg.find("missing table [job]"), std::string::npos) << msg;
  }
  {
    const fs::path missing = test_dir() / "missing_job.toml";
    try {
      load_job(missing);
      FAIL();
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind(missing.string() + ": cannot open", 0), 0u) << e.what();
    }
  }
}

TEST(Job, MachineFileErrorsNameTheMachineFile) {
  JobFiles f = job_files(kJob);
  write("machine.toml", machine_with(27, "max_jerk_m_per_s3 = \"high\""));
  expect_error(job_error(f), f.machine, 27, {"key 'axes[2].max_jerk_m_per_s3'", "expected a number"});
}

}  // namespace
}  // namespace vmsim::core

namespace vmsim::core {
namespace {

// [outputs] (parts/README.md): every key read, its defaults, and its errors naming the key.
TEST(Job, OutputsKeysDefaultsAndErrors) {
  const std::string head = "[job]\nmachine = \"machine.toml\"\nprogram = \"part.apt\"\n";
  const Job plain = load_job(job_files(head).job);
  EXPECT_EQ(plain.outputs.part_mesh, OutputsSpec::Mesh::Auto);
  EXPECT_EQ(plain.outputs.csv, OutputsSpec::Csv::Auto);
  EXPECT_TRUE(plain.outputs.npy);
  EXPECT_TRUE(plain.outputs.x3p);
  EXPECT_DOUBLE_EQ(plain.outputs.large_grid_nodes, 4e6);
  EXPECT_DOUBLE_EQ(plain.outputs.mesh_tolerance_mm, 1e-4);
  EXPECT_EQ(plain.outputs.vtp_compression_level, 1);
  const Job job =
      load_job(job_files(head + "[outputs]\npart_mesh = \"simplified\"\ncsv = \"never\"\nnpy = false\nx3p = false\n"
                                "large_grid_nodes = 1000\nmesh_tolerance_mm = 0.002\nvtp_compression_level = 6\n")
                   .job);
  EXPECT_EQ(job.outputs.part_mesh, OutputsSpec::Mesh::Simplified);
  EXPECT_EQ(job.outputs.csv, OutputsSpec::Csv::Never);
  EXPECT_FALSE(job.outputs.npy);
  EXPECT_FALSE(job.outputs.x3p);
  EXPECT_DOUBLE_EQ(job.outputs.large_grid_nodes, 1000);
  EXPECT_DOUBLE_EQ(job.outputs.mesh_tolerance_mm, 0.002);
  EXPECT_EQ(job.outputs.vtp_compression_level, 6);
  EXPECT_EQ(load_job(job_files(head + "[outputs]\npart_mesh = \"none\"\ncsv = \"always\"\n").job).outputs.part_mesh,
            OutputsSpec::Mesh::None);
  const struct {
    std::string body;
    std::vector<std::string> expected;
  } cases[] = {
      {"[outputs]\npart_mesh_max = 3\n", {"job.toml:", "unknown key 'outputs.part_mesh_max'"}},
      {"[outputs]\npart_mesh = \"coarse\"\n", {"key 'outputs.part_mesh'", "\"coarse\" is not one of"}},
      {"[outputs]\ncsv = true\n", {"key 'outputs.csv'"}},
      {"[outputs]\nnpy = \"yes\"\n", {"key 'outputs.npy'"}},
      {"[outputs]\nlarge_grid_nodes = 0\n", {"key 'outputs.large_grid_nodes'", ">= 1"}},
      {"[outputs]\nmesh_tolerance_mm = -1\n", {"key 'outputs.mesh_tolerance_mm'"}},
      {"[outputs]\nvtp_compression_level = 0\n", {"key 'outputs.vtp_compression_level'", "1..9"}},
      {"[outputs]\nvtp_compression_level = 10\n", {"key 'outputs.vtp_compression_level'", "found 10"}},
  };
  for (const auto& c : cases) {
    const std::string err = job_error(job_files(head + c.body));
    for (const std::string& e : c.expected) EXPECT_NE(err.find(e), std::string::npos) << c.body << "\n -> " << err;
  }
}

}  // namespace
}  // namespace vmsim::core
