// vmsim plan-feed end to end, as a user runs it on Chen et al.'s case (parts/feedplan/job_butterfly.toml): the files,
// `vmsim run` following the plan it wrote ([job] feed_plan: the same cycle time and contour-error peak),
// the report's figures against Chen et al. 2016 section 4 (without the contour-error constraint the simulated contour
// error exceeds the 20 um tolerance, Chen et al. 2016: 31.6 um; with it every sample is within 20 um), and bad input
// (exit 2 with a message naming the file and key, no report written).
#include <gtest/gtest.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "tests/app/cli_util.hpp"

using vmsim_test::CliRun;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace fs = std::filesystem;

namespace {

const fs::path kFeedplanPart = fs::path(VMSIM_SOURCE_DIR) / "parts" / "feedplan";

std::string replace(std::string s, const std::string& a, const std::string& b) {
  const auto i = s.find(a);
  if (i != std::string::npos) s.replace(i, a.size(), b);
  return s;
}

std::string quoted(const fs::path& p) { return fmt::format("\"{}\"", p.string()); }

// The butterfly job with absolute paths, its control points from `points` (default: the part's own).
std::string butterfly_job(const fs::path& points = kFeedplanPart / "butterfly_nurbs_control_points.csv") {
  std::string text = slurp(kFeedplanPart / "job_butterfly.toml");
  text = replace(text, "\"butterfly_nurbs_control_points.csv\"", quoted(points));
  text = replace(text, "\"butterfly_nurbs_knots.csv\"", quoted(kFeedplanPart / "butterfly_nurbs_knots.csv"));
  return replace(text, "\"chen2016_machine.toml\"", quoted(kFeedplanPart / "chen2016_machine.toml"));
}

// [job] feed_plan: `vmsim run` of the butterfly job (a stock added to cut) with the plan plan-feed wrote in `out`
// plays the same cycle and reaches the same contour-error peak (the same chain: the curve, the plan's ceiling, Chen et
// al.'s PID servo); the same plan on the curve moved by 1 mm is refused, naming the plan.
void expect_run_follows_the_plan(const TempDir& tmp, const fs::path& out, const nlohmann::json& rep) {
  const fs::path plan = out / "feed_plan.csv";
  ASSERT_TRUE(fs::exists(plan));
  EXPECT_EQ(slurp(plan).rfind("# vmsim feed plan 1", 0), 0u);
  const std::string cut =
      "\n[stock]\ntype = \"box\"\nmin_mm = [0.0, 0.0, -5.0]\nmax_mm = [110.0, 110.0, 1.0]\n"
      "\n[removal]\nspacing_mm = 0.5\n\n[reference]\nkind = \"none\"\n";
  const std::string with_plan =
      "machine = \"" + (kFeedplanPart / "chen2016_machine.toml").string() + "\"\nfeed_plan = \"" + plan.string() + "\"";
  const std::string machine_line = "machine = \"" + (kFeedplanPart / "chen2016_machine.toml").string() + "\"";
  const fs::path job = tmp.path() / "run_with_plan.toml";
  std::ofstream(job) << replace(butterfly_job(), machine_line, with_plan) << cut;
  const CliRun r =
      run_vmsim("run '" + job.string() + "' --out '" + (tmp.path() / "run").string() + "' --no-render", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json run = nlohmann::json::parse(slurp(tmp.path() / "run" / "report.json"));
  const auto& played = rep.at("runs").at("plan");
  EXPECT_EQ(run.at("interpolation").at("cycle_time_s").get<double>(), played.at("cycle_time_s").get<double>());
  EXPECT_EQ(run.at("interpolation").at("setpoints").get<long>(), played.at("setpoints").get<long>());
  EXPECT_NEAR(run.at("contour_error").at("all_moves").at("max_abs_mm").get<double>() * 1e3,
              played.at("simulated_contour_error_max_um").get<double>(), 1e-9);
  EXPECT_EQ(run.at("inputs").at("feed_plan").at("sha256").get<std::string>().size(), 64u);

  // The same curve 1 mm further along X: the same length, another path.
  std::string points = slurp(kFeedplanPart / "butterfly_nurbs_control_points.csv"), moved;
  std::istringstream in(points);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && std::isdigit(static_cast<unsigned char>(line[0]))) {
      const auto c1 = line.find(','), c2 = line.find(',', c1 + 1);
      std::ostringstream l;
      l << line.substr(0, c1 + 1) << std::stod(line.substr(c1 + 1, c2 - c1 - 1)) + 1.0 << line.substr(c2);
      line = l.str();
    }
    moved.append(line).append("\n");
  }
  const fs::path moved_points = tmp.path() / "moved_points.csv";
  std::ofstream(moved_points) << moved;
  const fs::path other = tmp.path() / "other_path.toml";
  std::ofstream(other) << replace(butterfly_job(moved_points), machine_line, with_plan) << cut;
  const CliRun o = run_vmsim("run '" + other.string() + "' --out '" + (tmp.path() / "other").string() + "'", tmp);
  EXPECT_EQ(o.code, 2) << o.err;
  EXPECT_NE(o.err.find(plan.string()), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("another path"), std::string::npos) << o.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "other" / "report.json"));
}

}  // namespace

TEST(PlanFeedCli, ButterflyCaseOfChen2016) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const CliRun r = run_vmsim(
      "plan-feed '" + (kFeedplanPart / "job_butterfly.toml").string() + "' --out '" + out.string() + "' --no-render",
      tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* f : {"report.json", "feed_plan.csv", "feed_profile.csv", "motion.csv"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  const nlohmann::json rep = nlohmann::json::parse(slurp(out / "report.json"));
  const auto& runs = rep.at("runs");
  // Chen et al. 2016: without the constraint the error peaks at 31.6 um (58 % over 20 um); vmsim's servo simulation
  // must also exceed the tolerance there, and the plan with the constraint must keep it.
  EXPECT_GT(runs.at("plan_without_contour_error").at("simulated_contour_error_max_um").get<double>(), 20.0);
  EXPECT_LE(runs.at("plan").at("simulated_contour_error_max_um").get<double>(), 20.0);
  EXPECT_TRUE(runs.at("plan").at("within_tolerance").get<bool>());
  // Every constraint at every sample (recomputed from the feeds, not the LP) and the chord error of the setpoints.
  EXPECT_LE(runs.at("plan").at("check").at("worst").get<double>(), 1.0 + 1e-6);
  EXPECT_LE(runs.at("plan").at("chord_error_max_um").get<double>(), 0.5);
  // Keeping the contour error costs time, and never saves it.
  EXPECT_GT(rep.at("cycle_time_cost_of_contour_constraint").get<double>(), 0.0);
  // The profile has one row per sample after its comment and header lines.
  const std::string csv = slurp(out / "feed_profile.csv");
  std::size_t rows = 0;
  for (char c : csv) rows += c == '\n';
  EXPECT_EQ(rows, rep.at("path").at("samples").get<std::size_t>() + 2);
  vmsim_test::expect_report_html(out, "--pictures no --note 'run with --no-render'");
  expect_run_follows_the_plan(tmp, out, rep);
}

TEST(PlanFeedCli, BadInputNamesTheKey) {
  TempDir tmp;
  const fs::path job = tmp.path() / "job.toml";
  // A NURBS path without f_max, and a servo = "pid" without its axes: errors naming the key, exit 2, no report.
  std::string text = slurp(kFeedplanPart / "job_butterfly.toml");
  const std::string cp = (kFeedplanPart / "butterfly_nurbs_control_points.csv").string();
  const std::string kn = (kFeedplanPart / "butterfly_nurbs_knots.csv").string();
  const std::string mach = (kFeedplanPart / "chen2016_machine.toml").string();
  auto replace = [](std::string s, const std::string& a, const std::string& b) {
    const auto i = s.find(a);
    if (i != std::string::npos) s.replace(i, a.size(), b);
    return s;
  };
  text = replace(text, "\"butterfly_nurbs_control_points.csv\"", "\"" + cp + "\"");
  text = replace(text, "\"butterfly_nurbs_knots.csv\"", "\"" + kn + "\"");
  text = replace(text, "\"chen2016_machine.toml\"", "\"" + mach + "\"");
  {
    std::ofstream(job) << replace(text, "max_feed_mm_per_s = 50.0", "");
    const CliRun r = run_vmsim("plan-feed '" + job.string() + "' --out '" + (tmp.path() / "o1").string() + "'", tmp);
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("max_feed_mm_per_s"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(tmp.path() / "o1" / "report.json"));
  }
  {
    std::ofstream(job) << text.substr(0, text.find("[[feedplan.axis]]"));
    const CliRun r = run_vmsim("plan-feed '" + job.string() + "' --out '" + (tmp.path() / "o2").string() + "'", tmp);
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("axis"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(job.filename().string()), std::string::npos) << r.err;
  }
  {
    std::ofstream(job) << replace(text, "contour_error_um = 20.0", "contour_error_um = -20.0");
    const CliRun r = run_vmsim("plan-feed '" + job.string() + "' --out '" + (tmp.path() / "o3").string() + "'", tmp);
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("contour_error_um"), std::string::npos) << r.err;
  }
}
