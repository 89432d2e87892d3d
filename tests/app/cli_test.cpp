// The vmsim command line, end to end, as a user runs it: exit codes, messages, and the files it writes.
// References: the plane-cylinder program itself (its first and last programmed points), and the error
// conventions of DESIGN.md (file:line:key, non-zero exit, no half-written output).
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_util.hpp"
#include "tests/test_paths.hpp"

using vmsim_test::CliRun;
using vmsim_test::json_number_after;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;
using vmsim_test::write_file;

namespace fs = std::filesystem;

namespace {

std::vector<double> row(const std::string& line) {
  std::vector<double> v;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) v.push_back(std::stod(cell));
  return v;
}

using vmsim::test::kSourceDir;

}  // namespace

TEST(Cli, VersionAndHelp) {
  TempDir tmp;
  CliRun v = run_vmsim("--version", tmp);
  EXPECT_EQ(v.code, 0);
  EXPECT_NE(v.out.find("vmsim 0."), std::string::npos) << v.out;
  CliRun h = run_vmsim("--help", tmp);
  EXPECT_EQ(h.code, 0);
  for (const char* sub : {"canon", "interp"}) EXPECT_NE(h.out.find(sub), std::string::npos) << h.out;
  CliRun hi = run_vmsim("interp --help", tmp);
  EXPECT_EQ(hi.code, 0);
  EXPECT_NE(hi.out.find("--summary-only"), std::string::npos) << hi.out;
  CliRun none = run_vmsim("", tmp);
  EXPECT_NE(none.code, 0);
}

TEST(Cli, InterpWritesSetpointsFromStartToProgramEnd) {
  TempDir tmp;
  const std::string job = kSourceDir + "/parts/plane_cylinder/job_fast.toml";
  CliRun r = run_vmsim("interp '" + job + "' --out '" + (tmp.path() / "out").string() + "'", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("cycle time:"), std::string::npos);
  EXPECT_NE(r.out.find("reached up to 10000 mm/min"), std::string::npos) << r.out;
  std::ifstream csv(tmp.path() / "out" / "setpoints.csv");
  std::string header, line, first, last;
  std::getline(csv, header);
  EXPECT_EQ(header, "t_s,X_mm,Y_mm,Z_mm,A_deg,C_deg,path_speed_mm_per_s");
  std::size_t n = 0;
  while (std::getline(csv, line)) {
    if (n == 0) first = line;
    last = line;
    const std::vector<double> v = row(line);
    ASSERT_EQ(v.size(), 7u) << line;
    ASSERT_NEAR(v[0], n * 1e-3, 1e-9) << "sample " << n;  // Te = 1 ms
    ++n;
  }
  ASSERT_GT(n, 1000u);
  // The job starts the tool tip at (-8, 5, 40) (start_mm); the program ends with G0 Z40 at X134.461524 Y5 under
  // G43 with a 50 mm tool: the Z axis starts and ends at 40 + 50.
  const std::vector<double> a = row(first), b = row(last);
  EXPECT_EQ(a[1], -8.0);
  EXPECT_EQ(a[2], 5.0);
  EXPECT_EQ(a[3], 90.0);
  EXPECT_NEAR(b[1], 134.461524, 1e-9);
  EXPECT_NEAR(b[2], 5.0, 1e-9);
  EXPECT_NEAR(b[3], 90.0, 1e-9);
}

TEST(Cli, UnknownJobKeyIsAnErrorNamingFileLineAndKey) {
  TempDir tmp;
  const fs::path job = tmp.path() / "job.toml";
  write_file(
      job,
      "[job]\nmachine = \"" + kSourceDir + "/parts/machines/mikron_ucp710.toml\"\nprogram = \"" + kSourceDir +
          "/parts/plane_cylinder/plane_cylinder_fast.ngc\"\n[interpolation]\nperiod_ms = 1\ntolerence_mm = 0.01\n");
  CliRun r = run_vmsim("interp '" + job.string() + "' --summary-only", tmp);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find(job.string() + ":6:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("interpolation.tolerence_mm"), std::string::npos) << r.err;
}

TEST(Cli, ProgramErrorNamesTheLineAndWritesNothing) {
  TempDir tmp;
  const fs::path prog = tmp.path() / "bad.ngc";
  write_file(prog, "G21 G90\nG1 X10 F100\nG1 X20 Q7 F100\nM2\n");  // Q is not a word of G1
  const fs::path job = tmp.path() / "job.toml";
  write_file(job, "[job]\nmachine = \"" + kSourceDir + "/parts/machines/mikron_ucp710.toml\"\nprogram = \"bad.ngc\"\n");
  const fs::path out = tmp.path() / "out";
  CliRun r = run_vmsim("interp '" + job.string() + "' --out '" + out.string() + "'", tmp);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("bad.ngc:3"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out / "setpoints.csv"));
}

TEST(Cli, TravelErrorLeavesNoOutputFile) {
  TempDir tmp;
  const fs::path prog = tmp.path() / "far.ngc";
  write_file(prog, "G21 G90\nG1 X100 F1000\nG1 X500\nM2\n");  // X travel of the Mikron is +-355 mm
  const fs::path job = tmp.path() / "job.toml";
  write_file(job, "[job]\nmachine = \"" + kSourceDir + "/parts/machines/mikron_ucp710.toml\"\nprogram = \"far.ngc\"\n");
  const fs::path out = tmp.path() / "out";
  fs::create_directories(out);
  CliRun r = run_vmsim("interp '" + job.string() + "' --out '" + out.string() + "'", tmp);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("far.ngc:3"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("travel"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_empty(out));  // neither setpoints.csv nor a temporary file
}

TEST(Cli, CanonPrintsLinuxCncCalls) {
  TempDir tmp;
  const fs::path prog = tmp.path() / "arc.ngc";
  write_file(prog, "G21 G90 F300\nG1 X10\nG2 X20 Y0 I5 J0\nM2\n");
  CliRun r = run_vmsim("canon '" + prog.string() + "'", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("STRAIGHT_FEED(10.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)"), std::string::npos) << r.out;
  // LinuxCNC's ARC_FEED(first_end, second_end, first_axis, second_axis, rotation, axis_end, a, b, c): clockwise.
  EXPECT_NE(r.out.find("ARC_FEED(20.0000, 0.0000, 15.0000, 0.0000, -1, 0.0000, 0.0000, 0.0000, 0.0000)"),
            std::string::npos)
      << r.out;
}

// The whole chain on the plane-cylinder part (the feed-drive simulation paper section 4, Fig. 6), the figure the seed
// reports: at 10 m/min the pass leaves a mark of about 0.02 mm at the fillet against the same pass at 0.1 m/min. The
// issue asks for the order of magnitude with the one machine file: 0.01 to 0.04 mm.
TEST(Cli, RunPlaneCylinderFastPassLeavesAMarkOfTheSeedsOrder) {
  TempDir tmp;
  const std::string job = kSourceDir + "/parts/plane_cylinder/job_fast.toml";
  CliRun r = run_vmsim("run '" + job + "' --quiet --out '" + (tmp.path() / "out").string() + "'", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string rep = slurp(tmp.path() / "out" / "report.json");
  ASSERT_NE(rep.find("\"marks\""), std::string::npos) << rep;
  const double depth = json_number_after(rep, "depth_mm", rep.find("\"marks\""));
  EXPECT_GE(depth, 0.010) << rep;
  EXPECT_LE(depth, 0.040) << rep;
  EXPECT_EQ(rep.find("\"sha256\": \"\""), std::string::npos);
  for (const char* f : {"surface.csv", "deviation.csv", "part.stl", "part.vtp", "report.json"})
    EXPECT_TRUE(fs::exists(tmp.path() / "out" / f)) << f;
}

// At 0.1 m/min over the whole surface the marks against the program cut exactly stay below 0.003 mm (the feed-drive
// simulation paper: negligible).
TEST(Cli, RunPlaneCylinderLowFeedMarksAreNegligible) {
  TempDir tmp;
  const std::string job = kSourceDir + "/parts/plane_cylinder/job_reference.toml";
  CliRun r = run_vmsim("run '" + job + "' --quiet --out '" + (tmp.path() / "out").string() + "'", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string rep = slurp(tmp.path() / "out" / "report.json");
  const double lo = json_number_after(rep, "deviation_min_mm"), hi = json_number_after(rep, "deviation_max_mm");
  EXPECT_GT(lo, -0.003) << rep;
  EXPECT_LT(hi, 0.003) << rep;
}
