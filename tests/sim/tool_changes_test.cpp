// Tool changes (issue 24 section 1): every sweep is cut by the tool in the spindle at its move.
// References, written elsewhere than the code under test:
// - the tools' own geometry (analytic): a flat end mill of diameter D leaves a flat floor at the programmed depth, a
//   groove exactly D wide; a ball of radius R moving straight along y leaves the circular profile
//   z = z_tip + R - sqrt(R^2 - (x - x_c)^2);
// - single-tool runs of each half of the program: a two-tool run must equal their union (the cell-by-cell minimum of
//   the two z-maps), since removal is a union of swept volumes;
// - the same run on one and on two threads (results never depend on the thread count);
// - the error cases the issue asks for, by the file, line, key and T number their messages must name.
#include "core/error.hpp"
#include "core/job.hpp"
#include "sim/job_program.hpp"
#include "sim/run.hpp"
#include "sim/tools.hpp"
#include "tests/test_machines.hpp"

#include <gtest/gtest.h>

#include "tests/test_paths.hpp"
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace vmsim::sim {
namespace {

namespace fs = std::filesystem;

fs::path write_tool_job_file(const std::string& name, const std::string& text) {
  return vmsim::test::write_test_file("vmsim_tool_changes_test", name, text);
}

using vmsim::test::kXyzTestMill;

// T1 (flat D6) cuts a groove along x at y = -5, 1 mm deep; T2 (ball D4) one along y at x = 5, 2 mm deep.
const char* kFirstHalf =
    "G0 Z5\n"
    "G0 X-15 Y-5\n"
    "G1 Z-1 F600\n"
    "G1 X15\n"
    "G0 Z5\n";
const char* kSecondHalf =
    "G0 X5 Y-15\n"
    "G1 Z-2 F600\n"
    "G1 Y15\n"
    "G0 Z5\n";
std::string two_tool_program() {
  return std::string("G21 G90 G17\nT1 M6\n") + kFirstHalf + "T2 M6\n" + kSecondHalf + "M2\n";
}

const char* kT1 = "[[tools]]\nnumber = 1\ntype = \"flat\"\ndiameter_mm = 6.0\nflute_length_mm = 10.0\n";
const char* kT2 = "[[tools]]\nnumber = 2\ntype = \"ball\"\ndiameter_mm = 4.0\nflute_length_mm = 10.0\n";

std::string job_text(const std::string& program, const std::string& tools, const std::string& motion,
                     const std::string& start = "[0.0, 0.0, 10.0]") {
  return "[job]\nmachine = \"machine.toml\"\nprogram = \"" + program + "\"\nstart_mm = " + start + "\n" + tools +
         "[stock]\ntype = \"box\"\nmin_mm = [-20.0, -20.0, -5.0]\nmax_mm = [20.0, 20.0, 0.0]\n"
         "[interpolation]\nperiod_ms = 1\ntolerance_mm = 0.005\n"
         "[removal]\nfield = \"zmap\"\nspacing_mm = 0.1\nmotion = \"" +
         motion + "\"\n[reference]\nkind = \"none\"\n";
}

core::Job two_tool_job(const std::string& motion) {
  write_tool_job_file("machine.toml", kXyzTestMill);
  write_tool_job_file("two.ngc", two_tool_program());
  return core::load_job(write_tool_job_file("two.toml", job_text("two.ngc", std::string(kT1) + kT2, motion)));
}

double height_at(const core::HeightGrid& s, double x, double y) {
  const auto i = static_cast<Eigen::Index>(std::lround((x - s.x0_mm) / s.dx_mm));
  const auto j = static_cast<Eigen::Index>(std::lround((y - s.y0_mm) / s.dy_mm));
  return s.z_mm(j, i);
}

std::string tool_change_error_of(const core::Job& job) {
  try {
    (void)run_job(job);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "no error";
}

// Each groove has its own tool's shape: T1's flat floor 6 mm wide, T2's circular profile of radius 2 (a ball's),
// where the other tool never reaches; where they cross, the deeper one. Within 0.1 um: the setpoints leave the
// programmed lines by a few hundredths of a micrometre here (34 nm measured; the interpolation tolerance is 5 um),
// while the other tool's shape would be off by up to 2 mm.
TEST(ToolChanges, EachToolCutsItsOwnShapeOnTheSetpoints) {
  const RunResult r = run_job(two_tool_job("setpoints"));
  ASSERT_TRUE(r.surface);
  const core::HeightGrid& s = *r.surface;
  // T1 alone (x = -10): floor at -1 for |y + 5| < 3, the stock top outside.
  double worst_flat = 0;
  int width_nodes = 0;
  for (Eigen::Index j = 0; j < s.ny(); ++j) {
    const double y = s.y(j), z = height_at(s, -10.0, y);
    if (std::abs(y + 5) < 3 - 1e-6) worst_flat = std::max(worst_flat, std::abs(z + 1.0));
    if (std::abs(y + 5) > 3 + 1e-6) worst_flat = std::max(worst_flat, std::abs(z));
    width_nodes += z < -0.5 ? 1 : 0;
  }
  EXPECT_LT(worst_flat, 1e-4) << "T1's groove is not a flat D6 groove 1 mm deep";
  // Nodes every 0.1 mm strictly inside |y + 5| < 3: 59 (the two edge nodes lie on the tool's rim).
  EXPECT_NEAR(width_nodes * s.dy_mm, 6.0, 2 * s.dy_mm);
  // T2 alone (y = 10): the ball's profile, z = -2 + 2 - sqrt(4 - (x - 5)^2) inside |x - 5| < 2.
  double worst_ball = 0;
  for (Eigen::Index i = 0; i < s.nx(); ++i) {
    const double x = s.x(i), dx = x - 5, z = height_at(s, x, 10.0);
    const double expected = std::abs(dx) < 2 ? std::min(0.0, -std::sqrt(4 - dx * dx)) : 0.0;
    worst_ball = std::max(worst_ball, std::abs(z - expected));
  }
  EXPECT_LT(worst_ball, 1e-4) << "T2's groove is not a ball R2's";
  // The crossing: T2's ball bottom at -2 under T1's floor.
  EXPECT_NEAR(height_at(s, 5.0, -5.0), -2.0, 1e-4);
  // report.json's tools: moves, feed moves, sweeps and time per tool; the times add up to the cycle time.
  const nlohmann::json& tools = r.report.at("tools");
  EXPECT_EQ(tools.at("source"), "job [[tools]]");
  ASSERT_EQ(tools.at("list").size(), 2u);
  const nlohmann::json &t1 = tools["list"][0], &t2 = tools["list"][1];
  EXPECT_EQ(t1.at("tool"), "T1");
  EXPECT_EQ(t1.at("type"), "flat");
  EXPECT_EQ(t1.at("moves"), 5);
  EXPECT_EQ(t1.at("feed_moves"), 2);
  EXPECT_EQ(t2.at("tool"), "T2");
  EXPECT_EQ(t2.at("type"), "ball");
  EXPECT_EQ(t2.at("moves"), 4);
  EXPECT_EQ(t2.at("feed_moves"), 2);
  EXPECT_GT(t1.at("sweeps").get<int>(), 0);
  EXPECT_GT(t2.at("sweeps").get<int>(), 0);
  const double cycle = r.report.at("interpolation").at("cycle_time_s").get<double>();
  EXPECT_NEAR(t1.at("time_s").get<double>() + t2.at("time_s").get<double>(), cycle, 1e-9);
  // T1's feed moves are 6 + 30 mm at 600 mm/min (3.6 s), T2's 7 + 30 mm (3.7 s); each tool's time holds at least its
  // feed moves' time.
  EXPECT_GT(t1.at("time_s").get<double>(), 3.6);
  EXPECT_GT(t2.at("time_s").get<double>(), 3.7);
  std::printf(
      "[ TOOLS    ] flat floor off by %.2e mm, groove %d nodes wide; ball profile off by %.2e mm; "
      "T1 %.3f s, T2 %.3f s of %.3f s\n",
      worst_flat, width_nodes, worst_ball, t1["time_s"].get<double>(), t2["time_s"].get<double>(), cycle);

  // The marks' tool, from the sweep that made the surface at each point (sim::mark_tools), on points whose cutter
  // is known from the program: T1's floor, T2's groove, the crossing (T2 deeper) and uncut stock.
  std::vector<metrology::Mark> marks(4);
  marks[0].x_mm = -10, marks[0].y_mm = -5;
  marks[1].x_mm = 5, marks[1].y_mm = 10;
  marks[2].x_mm = 5, marks[2].y_mm = -5;
  marks[3].x_mm = -15, marks[3].y_mm = 15;
  const std::vector<int> tagged = mark_tools(r.cut, marks, s, 1e-4);
  EXPECT_EQ(tagged, (std::vector<int>{0, 1, 1, -1}));
}

// Removal is a union of swept volumes: the two-tool run equals, cell for cell, the minimum of two single-tool runs of
// each half of the program (the programmed path, so the tracks are the same moves exactly).
TEST(ToolChanges, TwoToolRunIsTheUnionOfSingleToolRuns) {
  const RunResult both = run_job(two_tool_job("program"));
  write_tool_job_file("first.ngc", std::string("G21 G90 G17\n") + kFirstHalf + "M2\n");
  write_tool_job_file("second.ngc", std::string("G21 G90 G17\n") + kSecondHalf + "M2\n");
  const std::string t1 = "[tool]\ntype = \"flat\"\ndiameter_mm = 6.0\nflute_length_mm = 10.0\n";
  const std::string t2 = "[tool]\ntype = \"ball\"\ndiameter_mm = 4.0\nflute_length_mm = 10.0\n";
  const RunResult a = run_job(core::load_job(write_tool_job_file("first.toml", job_text("first.ngc", t1, "program"))));
  // T2's run in the two-tool program starts where T1 left the tool (x 15, y -5, z 5).
  const RunResult b = run_job(
      core::load_job(write_tool_job_file("second.toml", job_text("second.ngc", t2, "program", "[15.0, -5.0, 5.0]"))));
  ASSERT_TRUE(both.surface && a.surface && b.surface);
  const core::HeightArray& z = both.surface->z_mm;
  const core::HeightArray& za = a.surface->z_mm;
  const core::HeightArray& zb = b.surface->z_mm;
  ASSERT_EQ(z.rows(), za.rows());
  ASSERT_EQ(z.cols(), zb.cols());
  std::size_t differ = 0, cut_by_a = 0, cut_by_b = 0;
  double worst = 0;
  for (Eigen::Index j = 0; j < z.rows(); ++j)
    for (Eigen::Index i = 0; i < z.cols(); ++i) {
      const double u = std::min(za(j, i), zb(j, i));
      differ += z(j, i) != u ? 1 : 0;
      worst = std::max(worst, std::abs(double(z(j, i)) - u));
      cut_by_a += za(j, i) < zb(j, i) ? 1 : 0;
      cut_by_b += zb(j, i) < za(j, i) ? 1 : 0;
    }
  EXPECT_EQ(differ, 0u) << "largest difference " << worst << " mm";
  EXPECT_GT(cut_by_a, 1000u);  // both halves cut something the other does not
  EXPECT_GT(cut_by_b, 1000u);
  std::printf("[ TOOLS    ] two-tool run vs union of single-tool runs: %zu of %lld cells differ (largest %.2e mm)\n",
              differ, static_cast<long long>(z.size()), worst);
}

TEST(ToolChanges, SameResultOnOneAndTwoThreads) {
  const core::Job job = two_tool_job("setpoints");
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  const RunResult one = run_job(job);
  omp_set_num_threads(2);
  const RunResult two = run_job(job);
  omp_set_num_threads(before);
  ASSERT_TRUE(one.surface && two.surface);
  EXPECT_TRUE((one.surface->z_mm == two.surface->z_mm).all());
}

TEST(ToolChanges, ToolTheJobDoesNotDescribeIsAnErrorNamingFileLineAndNumber) {
  write_tool_job_file("machine.toml", kXyzTestMill);
  // Line 9 is the first move under T3 (T3 M6 is line 8).
  write_tool_job_file("three.ngc", std::string("G21 G90 G17\nT1 M6\n") + kFirstHalf + "T3 M6\n" + kSecondHalf + "M2\n");
  const core::Job job =
      core::load_job(write_tool_job_file("three.toml", job_text("three.ngc", std::string(kT1) + kT2, "program")));
  const std::string err = tool_change_error_of(job);
  EXPECT_NE(err.find("three.ngc:9:"), std::string::npos) << err;
  EXPECT_NE(err.find("T3"), std::string::npos) << err;
  EXPECT_NE(err.find("number = 3"), std::string::npos) << err;
  EXPECT_NE(err.find("T1, T2"), std::string::npos) << err;  // what the job does describe
}

TEST(ToolChanges, OneToolMeetingSeveralNumbersNeedsAllTools) {
  write_tool_job_file("machine.toml", kXyzTestMill);
  write_tool_job_file("two.ngc", two_tool_program());
  const std::string one = "[tool]\ntype = \"flat\"\ndiameter_mm = 6.0\n";
  const std::string err =
      tool_change_error_of(core::load_job(write_tool_job_file("one.toml", job_text("two.ngc", one, "program"))));
  for (const char* part : {"one.toml", "[tool] describes one tool", "T1 (line 3)", "T2 (line 9)", "all_tools = true"})
    EXPECT_NE(err.find(part), std::string::npos) << part << " not in: " << err;
  // With all_tools = true the one tool cuts everything: T2's groove is then 6 mm wide and flat.
  const RunResult r = run_job(
      core::load_job(write_tool_job_file("all.toml", job_text("two.ngc", one + "all_tools = true\n", "program"))));
  EXPECT_NEAR(height_at(*r.surface, 7.5, 10.0), -2.0, 1e-5);
  EXPECT_EQ(r.report["tools"]["list"].size(), 1u);
  EXPECT_EQ(r.report["tools"]["all_tools"], true);
}

TEST(ToolChanges, ToolsWithoutAToolChangeAreAnError) {
  write_tool_job_file("machine.toml", kXyzTestMill);
  write_tool_job_file("none.ngc", std::string("G21 G90\n") + kFirstHalf + "M2\n");
  const std::string err =
      tool_change_error_of(core::load_job(write_tool_job_file("none.toml", job_text("none.ngc", kT1, "program"))));
  EXPECT_NE(err.find("never changes tools"), std::string::npos) << err;
  EXPECT_NE(err.find("number = 0"), std::string::npos) << err;
}

// 840D programs call tools by name (T="name"); [[tools]] name maps them.
TEST(ToolChanges, SinumerikNamesMapThroughTheJob) {
  write_tool_job_file("machine.toml", kXyzTestMill);
  write_tool_job_file("named.mpf",
                      "N10 G90\nN20 T=\"FLAT_D6\"\nN30 M6\nN40 G0 X-15 Y-5 Z5\nN50 G1 Z-1 F600\nN60 X15\nN70 G0 Z5\n"
                      "N80 T=\"BALL_D4\"\nN90 M6\nN100 G0 X5 Y-15\nN110 G1 Z-2 F600\nN120 Y15\nN130 G0 Z5\nN140 M30\n");
  const std::string by_name =
      "[[tools]]\nname = \"BALL_D4\"\ntype = \"ball\"\ndiameter_mm = 4.0\n"
      "[[tools]]\nname = \"FLAT_D6\"\ntype = \"flat\"\ndiameter_mm = 6.0\n";
  const core::Job job = core::load_job(write_tool_job_file("named.toml", job_text("named.mpf", by_name, "program")));
  const core::ToolPath tp = read_job_program(job);
  const std::vector<int> per_move = move_tools(job, tp);
  ASSERT_EQ(per_move.size(), tp.moves.size());
  for (std::size_t k = 0; k < tp.moves.size(); ++k)
    EXPECT_EQ(per_move[k], tp.moves[k].source_line >= 9 ? 0 : 1) << "line " << tp.moves[k].source_line;
  const RunResult r = run_job(job);
  EXPECT_NEAR(height_at(*r.surface, 5.0, 10.0), -2.0, 1e-5);  // the ball's bottom
  EXPECT_NEAR(height_at(*r.surface, 6.5, 10.0), -std::sqrt(4 - 1.5 * 1.5), 1e-4);
  EXPECT_NEAR(height_at(*r.surface, -10.0, -7.5), -1.0, 1e-5);  // the flat's floor
  EXPECT_EQ(r.report["tools"]["list"][0]["tool"], "T=\"BALL_D4\"");
  // A name the job does not give.
  const core::Job missing = core::load_job(write_tool_job_file(
      "missing.toml",
      job_text("named.mpf", "[[tools]]\nname = \"FLAT_D6\"\ntype = \"flat\"\ndiameter_mm = 6.0\n", "program")));
  const std::string err = tool_change_error_of(missing);
  EXPECT_NE(err.find("named.mpf:10:"), std::string::npos) << err;
  EXPECT_NE(err.find("T=\"BALL_D4\""), std::string::npos) << err;
  EXPECT_NE(err.find("name = \"BALL_D4\""), std::string::npos) << err;
}

// CAMotics' botomata_bottom.nc (../shared/data/real/cam, skipped when absent) through parts/botomata/job.toml: three
// flat end mills, T1 1/4 in, T2 1/8 in, T3 1/16 in (the program's comments). Its "Profile: Layer 6" (T2, F300) runs
// G01 from Y-17 to Y-35.306 at Z-1.27, and nothing else reaches the groove's outer side: its outer wall lies
// at x = -38.29 - D2/2 = -39.8775 (T1 would put it at -41.465, T3 at -39.084) with a flat floor at -1.27. Checked on
// a 0.01 mm z-map of a window across the groove, cut along the programmed path (the run's per-move tool mapping).
TEST(ToolChanges, BotomataProfileGrooveHasTool2sWidth) {
  const fs::path data = fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "botomata_bottom.nc";
  if (!fs::exists(data)) GTEST_SKIP() << data << " is absent (the real CAM programs of ../shared)";
  core::Job job = core::load_job(fs::path(VMSIM_SOURCE_DIR) / "parts" / "botomata" / "job.toml");
  ASSERT_EQ(job.tools.size(), 3u);
  job.stock.min_mm = Eigen::Vector3d(-41.0, -30.0, -22.0);
  job.stock.max_mm = Eigen::Vector3d(-38.6, -22.0, 0.0);
  job.removal.spacing_mm = 0.01;
  job.removal.motion = core::RemovalSpec::Motion::Program;
  job.reference.kind = core::ReferenceSpec::Kind::None;
  const RunResult r = run_job(job);
  ASSERT_TRUE(r.surface);
  const core::HeightGrid& s = *r.surface;
  const double wall = -38.29 - job.tools[1].diameter_mm / 2;
  double worst_floor = 0, worst_top = 0, worst_wall = 0;
  for (Eigen::Index j = 0; j < s.ny(); ++j) {
    // The first node from the left whose surface lies below the stock top: the wall is between it and its neighbour.
    Eigen::Index first = -1;
    for (Eigen::Index i = 0; i < s.nx() && first < 0; ++i)
      if (s.z_mm(j, i) < -0.5) first = i;
    ASSERT_GT(first, 0) << "no groove at y " << s.y(j);
    worst_wall = std::max(worst_wall, std::abs(s.x(first) - s.dx_mm / 2 - wall));
    for (Eigen::Index i = 0; i < s.nx(); ++i) {
      const double x = s.x(i), z = s.z_mm(j, i);
      if (x < wall - 1e-6) worst_top = std::max(worst_top, std::abs(z));
      if (x > wall + 1e-6) worst_floor = std::max(worst_floor, std::abs(z + 1.27));
    }
  }
  EXPECT_LE(worst_wall, s.dx_mm / 2 + 1e-9) << "the groove's wall is not where T2's radius puts it";
  EXPECT_LT(worst_floor, 1e-5) << "the groove's floor is not T2's flat floor at -1.27";
  EXPECT_LT(worst_top, 1e-9) << "material was cut outside the groove";
  const nlohmann::json& tools = r.report.at("tools").at("list");
  ASSERT_EQ(tools.size(), 3u);
  std::size_t moves = 0;
  for (const auto& t : tools) {
    EXPECT_GT(t.at("moves").get<int>(), 100) << t.dump();
    moves += t.at("moves").get<std::size_t>();
  }
  EXPECT_EQ(moves, r.cut.motion.program.moves.size());
  std::printf(
      "[ BOTOMATA ] T2 groove wall within %.4f mm of x = %.4f (grid %.2f mm), floor within %.1e of -1.27; "
      "moves T1 %d, T2 %d, T3 %d\n",
      worst_wall, wall, s.dx_mm, worst_floor, tools[0]["moves"].get<int>(), tools[1]["moves"].get<int>(),
      tools[2]["moves"].get<int>());
}

}  // namespace
}  // namespace vmsim::sim
