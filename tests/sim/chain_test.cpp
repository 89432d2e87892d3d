// The job's chain (sim::Chain) and the feed plan it follows ([job] feed_plan): vmsim plan-feed's library call and a
// chain built from the job with the plan plan-feed wrote run the same setpoints and the same axes, bit for bit; a
// plan caps the interpolated feed at its ceiling; a plan for another path is refused naming the file; a job's
// [feedplan] transfer-function servo runs as methods::simulate_transfer_functions (the reference implementation of
// Chen et al.'s servo) does. References: the plan's own ceiling (a constant here), plan-feed's played plan, and the
// methods' simulation of the same transfer functions.
#include "tests/app/cli_util.hpp"
#include "core/error.hpp"
#include "core/job.hpp"
#include "methods/feedplan_file.hpp"
#include "methods/feedplan_servo.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"
#include "sim/plan_feed.hpp"
#include "tests/test_paths.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

using namespace vmsim;
namespace fs = std::filesystem;

namespace {

using vmsim::test::kPartsDir;

using vmsim_test::TempDir;  // tests/app/cli_util.hpp

// A small XY contour programmed at 6 m/min on the Mikron UCP 710 (its cascades): 20 mm lines and R 5 arcs, which its
// acceleration and jerk limits let it run at up to ~46 mm/s, where the contour error reaches ~19 um: a 5 um contour
// tolerance binds. A tool of 50 mm gauge length (G43): the axes are not the tool tip. `extra`: lines added to [job].
fs::path small_job(const TempDir& tmp, const std::string& extra = "", const std::string& name = "job.toml") {
  std::ofstream(tmp.path() / "p.ngc") << "G21 G90 G94 G17\nT1 M6\nG43 H1\nG1 X20 Y0 F6000\nG3 X20 Y10 I0 J5\n"
                                         "G1 X5 Y10\nG2 X5 Y20 I0 J5\nG1 X25 Y20\nM30\n";
  std::ofstream(tmp.path() / "tools.tbl") << "T1 P1 Z50 D10\n";
  const fs::path job = tmp.path() / name;
  std::ofstream(job) << "[job]\nname = \"small\"\nmachine = \"" << kPartsDir << "machines/mikron_ucp710.toml\"\n"
                     << "program = \"p.ngc\"\ntool_table = \"tools.tbl\"\nstart_mm = [0.0, 0.0, 0.0]\n"
                     << extra << "\n[feedplan]\ncontour_error_um = 5.0\nchord_error_um = 1.0\nservo = \"machine\"\n";
  return job;
}

}  // namespace

TEST(ChainFeedPlan, RunsWhatPlanFeedPlayed) {
  TempDir tmp;
  const core::Job job = core::load_job(small_job(tmp));
  const sim::PlanFeedResult r = sim::plan_feed(job);
  ASSERT_GT(r.free_played.max_abs_mm, 0.010);  // the plan binds: without the constraint the error exceeds 5 um
  ASSERT_GT(r.verified.played.interp.stats.cycle_time_s, r.free_played.interp.stats.cycle_time_s);  // it slows
  const fs::path plan = tmp.path() / "feed_plan.csv";
  methods::write_feed_plan(plan, r.ceiling, r.path, job.interp.period_s, job.name);

  const core::Job planned = core::load_job(small_job(tmp, "feed_plan = \"feed_plan.csv\"\n", "planned.toml"));
  sim::ChainOptions o;
  o.settle_s = 0.3;  // as long as plan-feed's verification simulates the settling
  const sim::Chain chain(planned, o);
  const motion::InterpResult ir = chain.interpolate(sim::read_job_program(planned));
  const methods::PlayedPlan& played = r.verified.played;
  EXPECT_EQ(ir.stats.cycle_time_s, played.interp.stats.cycle_time_s);
  ASSERT_EQ(ir.setpoints.samples(), played.interp.setpoints.samples());
  EXPECT_TRUE(ir.setpoints.position == played.interp.setpoints.position);
  const drives::AxisResponse resp = chain.simulate(ir.setpoints);
  EXPECT_TRUE(resp.position == played.actual);
  // ... and without the plan, the job's own feed: the setpoints of plan-feed's "no plan" run.
  sim::ChainOptions no;
  no.ignore_feed_plan = true;
  const sim::Chain free(planned, no);
  EXPECT_EQ(free.interpolate(sim::read_job_program(planned)).stats.cycle_time_s, r.no_plan.interp.stats.cycle_time_s);
}

// Issue 23 section 3: Chen et al.'s butterfly (parts/feedplan/job_butterfly.toml), its plan followed as a profile, is
// played within 5 % of the plan's own time (the plan's time: its samples' arc lengths over the mean of their feeds,
// methods::plan_feed), with the simulated contour error within the job's 20 um and every axis within the machine
// file's limits. The limits are recomputed here from the played setpoints by backward differences (velocity
// (x_k - x_{k-1}) / Te, acceleration and jerk the second and third differences over Te^2, Te^3, the axes at rest
// before the first and after the last setpoint), each within its limit to 1e-9 relative (round-off).
TEST(ChainFeedPlan, ButterflyPlanIsPlayedWithinFivePercentOfItsOwnTime) {
  const core::Job job = core::load_job(kPartsDir + "feedplan/job_butterfly.toml");
  const sim::PlanFeedResult r = sim::plan_feed(job);
  ASSERT_TRUE(r.played_as_profile);
  const methods::PlayedPlan& played = r.verified.played;
  const double ratio = played.interp.stats.cycle_time_s / r.verified.plan.time_s;
  EXPECT_LE(ratio, 1.05) << played.interp.stats.cycle_time_s << " s played, " << r.verified.plan.time_s << " s planned";
  EXPECT_GE(ratio, 0.999);
  EXPECT_TRUE(r.verified.holds);
  EXPECT_LE(played.max_abs_mm, 0.020);
  const core::Setpoints& sp = played.interp.setpoints;
  const Eigen::Index n = sp.samples();
  const double te = sp.period_s;
  double worst = 0.0;
  for (std::size_t a = 0; a < job.machine.axes.size(); ++a) {
    const core::MachineAxis& ax = job.machine.axes[a];
    auto x = [&](Eigen::Index k) { return sp.position(std::clamp<Eigen::Index>(k, 0, n - 1), (Eigen::Index)a); };
    for (Eigen::Index k = 1; k < n + 3; ++k) {
      worst = std::max(worst, std::abs(x(k) - x(k - 1)) / te / ax.max_velocity);
      worst = std::max(worst, std::abs(x(k) - 2 * x(k - 1) + x(k - 2)) / (te * te) / ax.max_acceleration);
      worst = std::max(worst, std::abs(x(k) - 3 * x(k - 1) + 3 * x(k - 2) - x(k - 3)) / (te * te * te) / ax.max_jerk);
    }
  }
  EXPECT_LE(worst, 1.0 + 1e-9);
}

TEST(ChainFeedPlan, TheCeilingCapsTheFeedAndAPlanForAnotherPathIsRefused) {
  TempDir tmp;
  const core::Job job = core::load_job(small_job(tmp));
  const core::ToolPath program = sim::read_job_program(job);
  const sim::Chain plain(job);
  const motion::SmoothPath path = plain.smooth_path(program);
  motion::FeedCeiling c;
  c.s_mm = {0.0, path.length};
  c.feed_mm_per_s = {20.0, 20.0};
  methods::write_feed_plan(tmp.path() / "slow.csv", c, path, job.interp.period_s, job.name);
  EXPECT_GT(plain.interpolate(program).setpoints.path_speed_mm_per_s.maxCoeff(), 40.0);

  const core::Job slow = core::load_job(small_job(tmp, "feed_plan = \"slow.csv\"\n", "slow.toml"));
  const sim::Chain chain(slow);
  EXPECT_EQ(chain.feed_plan_file(), slow.feed_plan_file);
  const motion::InterpResult ir = chain.interpolate(program);
  EXPECT_LE(ir.setpoints.path_speed_mm_per_s.maxCoeff(), 20.0 * (1 + 1e-6));
  EXPECT_GT(ir.setpoints.path_speed_mm_per_s.maxCoeff(), 19.0);
  // The chain of plan-feed itself does not follow the job's plan.
  sim::ChainOptions o;
  o.ignore_feed_plan = true;
  EXPECT_GT(sim::Chain(slow, o).interpolate(program).setpoints.path_speed_mm_per_s.maxCoeff(), 40.0);

  // The same plan for another program: the job's path is 5 mm longer.
  std::ofstream(tmp.path() / "q.ngc") << "G21 G90 G94 G17\nT1 M6\nG43 H1\nG1 X20 Y0 F6000\nG3 X20 Y10 I0 J5\n"
                                         "G1 X5 Y10\nG2 X5 Y20 I0 J5\nG1 X30 Y20\nM30\n";
  std::string text;
  {
    std::ifstream in(tmp.path() / "slow.toml");
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  text.replace(text.find("\"p.ngc\""), 7, "\"q.ngc\"");
  std::ofstream(tmp.path() / "other.toml") << text;
  const core::Job other = core::load_job(tmp.path() / "other.toml");
  const sim::Chain oc(other);
  try {
    oc.interpolate(sim::read_job_program(other));
    FAIL() << "a plan for another path was followed";
  } catch (const core::Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("other.toml"), std::string::npos) << m;
    EXPECT_NE(m.find("feed_plan"), std::string::npos) << m;
    EXPECT_NE(m.find("slow.csv"), std::string::npos) << m;
  }
}

TEST(ChainServo, AJobsTransferFunctionServoRunsAsChenEtAlsServo) {
  const core::Job job = core::load_job(kPartsDir + "feedplan/job_butterfly.toml");
  const sim::Chain chain(job);
  ASSERT_NE(chain.curve(), nullptr);  // the path is the job's NURBS
  EXPECT_TRUE(chain.transfer_function_servo());
  const motion::InterpResult ir = chain.interpolate(sim::read_job_program(job));
  EXPECT_NEAR(ir.setpoints.path_length_mm[ir.setpoints.samples() - 1], chain.curve()->path.path.length, 1e-6);
  const drives::AxisResponse resp = chain.simulate(ir.setpoints);
  const std::vector<methods::TransferFunction> tfs = {methods::pid_servo_transfer_function(methods::chen2016_pid_x()),
                                                      methods::pid_servo_transfer_function(methods::chen2016_pid_y()),
                                                      methods::TransferFunction{{1.0}, {1.0}}};
  const Eigen::MatrixXd want = methods::simulate_transfer_functions(ir.setpoints, tfs, 0.2);
  ASSERT_EQ(resp.position.rows(), want.rows());
  EXPECT_TRUE(resp.position == want);
  // Identified axis models cannot replace the job's servo too: an error naming the job file and the key.
  TempDir tmp;
  const fs::path models = tmp.path() / "models.toml";
  std::ofstream(models) << "[model]\nperiod_ms = 4.0\n\n[[axes]]\nname = \"X\"\nstructure = \"oe\"\nnk = 1\n"
                           "b = [0.1]\na = [-0.9]\n";
  core::Job both = job;
  both.axis_models_file = models;
  try {
    const sim::Chain c(both);
    FAIL() << "two models of the same axes were taken";
  } catch (const core::Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("job_butterfly.toml"), std::string::npos) << m;
    EXPECT_NE(m.find("[feedplan] servo"), std::string::npos) << m;
  }
}
