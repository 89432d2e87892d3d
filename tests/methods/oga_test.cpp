// Offline gain adjustment (Duong et al.): the gain function (eq. 3-4), the curvature windows (section III.E), the
// admissible sets and the best fixed pair against an exhaustive search through simulate_axes, the state-at-the-
// window-start evaluation against Duong et al.'s re-simulation from the start, thread-count independence, the
// verification against the search, the schedule file, and the OGA case of parts/oga_profile.
#include "tests/app/cli_util.hpp"
#include "methods/oga.hpp"
#include "methods/oga_schedule.hpp"

#include "motion/contour.hpp"
#include "core/error.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"
#include "core/units.hpp"
#include "tests/drives/drive_test_support.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

namespace vmsim::methods {
namespace {

namespace fs = std::filesystem;
constexpr double kKv = core::units::kKvMPerMinPerMmToPerS;

using vmsim_test::TempDir;  // tests/app/cli_util.hpp

// A program's setpoints on the Mikron, the tool tip starting at `start` (as vmsim's jobs with start_mm).
core::Setpoints setpoints_of(const fs::path& program, const core::Machine& m, const Eigen::Vector3d& start,
                             const std::optional<fs::path>& tools = std::nullopt) {
  program::ProgramOptions po;
  po.tool_table = tools;
  po.start_mm = std::array<double, 3>{start.x(), start.y(), start.z()};
  core::ToolPath tp = program::read_program(program, po);
  core::Move& first = tp.moves.front();
  first.start.head<3>() = start;
  tp.initial_position = first.start;
  tp.initial_position[core::kZ] += first.tool_length_offset_mm;
  return motion::interpolate(motion::toolpath_in_axis_space(tp, m), m, motion::InterpOptions{}).setpoints;
}

// A short XZ profile at 3 m/min (1.1 s): 8 mm straight, concave R30 over 35 deg, convex R20 over 70 deg (Z
// reverses), 6 mm straight.
core::Setpoints short_profile(const core::Machine& m) {
  TempDir tmp;
  const fs::path p = tmp.path() / "short.ngc";
  std::ofstream(p) << "G21 G90 G94 G18\nG1 X-12.000000 Z0.000000 F3000\n"
                      "G2 X5.207293 Z5.425439 I0.000000 K30.000000\n"
                      "G3 X28.150351 Z5.425439 I11.471529 K-16.383041\n"
                      "G1 X33.065263 Z1.983980\nM30\n";
  return setpoints_of(p, m, Eigen::Vector3d(-20, 0, 0));
}

// The OGA test part as its job runs it.
core::Setpoints case_profile(const core::Machine& m) {
  const fs::path dir = fs::path(VMSIM_SOURCE_DIR) / "parts/oga_profile";
  const core::Job job = core::load_job(dir / "job.toml");
  return setpoints_of(job.program_file, m, *job.start_mm, job.tool_table_file);
}

Eigen::MatrixXd xyz_command(const core::Setpoints& sp, const core::Machine& m, Eigen::Index rows) {
  Eigen::MatrixXd c(rows, 3);
  for (Eigen::Index k = 0; k < rows; ++k)
    for (int j = 0; j < 3; ++j) c(k, j) = sp.position(std::min(k, sp.samples() - 1), m.axis_index(j));
  return c;
}

// ---- eq. 3-4
// ----------------------------------------------------------------------------------------------------------

// Reference: Duong et al. eq. 3 in closed form, K(k+i) = K(k-1) + (K_final - K(k-1)) (1 - cos(pi i / (p-1))) / 2
// (-A sin(pi/2 + x) + A = A (1 - cos x)), then eq. 4.
TEST(OgaGainFunction, HalfSinusoidThenHold) {
  EXPECT_EQ(sinusoid_samples(10.0, 1e-3), 50);  // Duong et al.: f = 10 Hz, Te = 1 ms
  const int p = 50;
  std::vector<double> k(80);
  gain_function(6.0, 6.5, p, 80, k.data());
  EXPECT_EQ(k[0], 6.0);  // the first gain of the window is the last of the one before, exactly
  for (int i = 0; i < p; ++i)
    EXPECT_NEAR(k[static_cast<std::size_t>(i)], 6.0 + 0.5 * (1 - std::cos(std::numbers::pi * i / (p - 1))) / 2, 1e-12);
  for (int i = p - 1; i < 80; ++i) EXPECT_EQ(k[static_cast<std::size_t>(i)], 6.5);
  for (int i = 1; i < 80; ++i) EXPECT_GE(k[static_cast<std::size_t>(i)], k[static_cast<std::size_t>(i) - 1]);
  // Downwards, and a window shorter than p stops part-way on the same curve.
  std::vector<double> full(50), cut(20);
  gain_function(6.0, 5.0, p, 50, full.data());
  gain_function(6.0, 5.0, p, 20, cut.data());
  for (int i = 0; i < 20; ++i) EXPECT_EQ(cut[static_cast<std::size_t>(i)], full[static_cast<std::size_t>(i)]);
  EXPECT_GT(cut.back(), 5.0);
  // Holding (A = 0) is flat.
  gain_function(5.7, 5.7, p, 20, cut.data());
  for (double v : cut) EXPECT_EQ(v, 5.7);
  EXPECT_THROW(sinusoid_samples(400.0, 1e-3), core::Error);  // p = 1.25 < 2
  EXPECT_THROW(sinusoid_samples(0.0, 1e-3), core::Error);
}

// ---- windows (section III.E)
// ------------------------------------------------------------------------------------------

// Reference: a sampled path of known geometry in XZ (0.05 mm steps): 5 mm straight, an arc of radius 10 turning
// towards -Z (convex about +Y), 5 mm straight, an arc of radius 20 turning towards +Z (concave). The curvature from
// three points on a circle is exactly 1/R.
TEST(OgaWindows, CutWhereTheCurvatureChangesKind) {
  std::vector<Eigen::Vector3d> pts;
  Eigen::Vector3d p(0, 0, 0);
  double h = 0.0;
  const double ds = 0.05;
  auto line = [&](double len) {
    for (int i = 0; i < static_cast<int>(std::lround(len / ds)); ++i) {
      p += ds * Eigen::Vector3d(std::cos(h), 0, std::sin(h));
      pts.push_back(p);
    }
  };
  auto arc = [&](double r, double turn) {
    const int n = static_cast<int>(std::lround(std::abs(turn) * r / ds));
    const double side = turn > 0 ? 1 : -1;
    const Eigen::Vector3d c = p + side * r * Eigen::Vector3d(-std::sin(h), 0, std::cos(h));
    for (int i = 1; i <= n; ++i) {
      const double hh = h + turn * i / n;
      pts.push_back(c + side * r * Eigen::Vector3d(std::sin(hh), 0, -std::cos(hh)));
    }
    p = pts.back();
    h += turn;
  };
  pts.push_back(p);
  line(5);
  const Eigen::Index a0 = static_cast<Eigen::Index>(pts.size());
  arc(10, -0.6);
  const Eigen::Index a1 = static_cast<Eigen::Index>(pts.size());
  line(5);
  const Eigen::Index a2 = static_cast<Eigen::Index>(pts.size());
  arc(20, 0.5);
  Eigen::MatrixXd xyz(static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t i = 0; i < pts.size(); ++i) xyz.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();

  const Eigen::ArrayXd kappa = setpoint_curvature(xyz, Eigen::Vector3d::UnitY());
  EXPECT_NEAR(kappa[(a0 + a1) / 2], 0.1, 1e-9);            // convex R10: +1/R about +Y
  EXPECT_NEAR(kappa[(a2 + xyz.rows()) / 2], -0.05, 1e-9);  // concave R20
  EXPECT_NEAR(kappa[a0 / 2], 0.0, 1e-9);

  // The plateaus in order; where the curvature jumps (no blend in this synthetic path) a transition of the three
  // rows whose curvature mixes both sides.
  const std::vector<Window> w = curvature_windows(xyz, Eigen::Vector3d::UnitY());
  const WindowKind kinds[4] = {WindowKind::Straight, WindowKind::Convex, WindowKind::Straight, WindowKind::Concave};
  const Eigen::Index cuts[3] = {a0, a1, a2};
  std::size_t plateau = 0, transition = 0;
  for (std::size_t i = 0; i < w.size(); ++i) {
    if (i > 0) {
      EXPECT_EQ(w[i].begin, w[i - 1].end);
    }
    if (w[i].kind == WindowKind::Transition) {
      ASSERT_LT(transition, 3u);
      EXPECT_LE(w[i].end - w[i].begin, 4);
      EXPECT_LE(std::abs(w[i].begin - cuts[transition]), 2) << i;
      ++transition;
    } else {
      ASSERT_LT(plateau, 4u);
      EXPECT_EQ(w[i].kind, kinds[plateau]) << i;
      ++plateau;
    }
  }
  EXPECT_EQ(plateau, 4u);
  EXPECT_EQ(transition, 3u);
  EXPECT_EQ(w.front().begin, 0);
  EXPECT_EQ(w.back().end, xyz.rows());
}

// Reference: the OGA part's geometry (parts/oga_profile/README.md): straight, concave, straight, convex, straight,
// concave, convex, straight, concave, straight, with a transition where the interpolator's blends make the
// curvature ramp between them.
TEST(OgaWindows, TheOgaProfile) {
  const core::Machine m = drives::test::mikron();
  const core::Setpoints sp = case_profile(m);
  const std::vector<Window> w = curvature_windows(xyz_command(sp, m, sp.samples()), Eigen::Vector3d::UnitY());
  std::vector<WindowKind> plateaus;
  for (const Window& x : w)
    if (x.kind != WindowKind::Transition) plateaus.push_back(x.kind);
  using K = WindowKind;
  const std::vector<K> expect = {K::Straight, K::Concave, K::Straight, K::Convex,  K::Straight,
                                 K::Concave,  K::Convex,  K::Straight, K::Concave, K::Straight};
  EXPECT_EQ(plateaus, expect);
  for (std::size_t i = 0; i + 1 < w.size(); ++i) {
    EXPECT_EQ(w[i].end, w[i + 1].begin);
    EXPECT_NE(w[i].kind, w[i + 1].kind);
  }
}

// ---- admissible sets and the best fixed pair against an exhaustive search -------------------------------------------

// The limits as the header states them, computed here independently: backward differences of the frictionless
// drive's positions from simulate_axes, the full model's period-peak current.
bool admissible_by_brute_force(const drives::AxisResponse& twin, const drives::AxisResponse& model, int a,
                               const core::MachineAxis& ax) {
  const double te = twin.period_s;
  double px = twin.position(0, a), pv = 0, pa = 0, v_max = 0, a_max = 0, j_max = 0;
  for (Eigen::Index k = 0; k < twin.samples(); ++k) {
    const double v = (twin.position(k, a) - px) / te, acc = (v - pv) / te, j = (acc - pa) / te;
    px = twin.position(k, a), pv = v, pa = acc;
    v_max = std::max(v_max, std::abs(v)), a_max = std::max(a_max, std::abs(acc)), j_max = std::max(j_max, std::abs(j));
  }
  const double i_max = model.current_peak_A.col(a).maxCoeff();
  return v_max <= ax.max_velocity && a_max <= ax.max_acceleration && j_max <= ax.max_jerk &&
         i_max < ax.drive->current_limit_A;
}

// Reference: every (X configuration, Z configuration) pair through drives::simulate_axes on machine copies whose
// drives carry the pair's gains, MSE(CE) by motion::contour_error, the limits by the function above.
TEST(OgaSearch, AdmissibleSetsAndBestPairMatchAnExhaustiveSearch) {
  const core::Machine m = drives::test::mikron();
  const core::Setpoints sp = short_profile(m);
  OgaOptions o;
  o.kp_grid = {3.0, 6.0, 9.0};
  o.kf_grid = {0.0, 0.5, 0.9};
  o.range = {{"X", {5.5, 6.5}}, {"Z", {5.5, 6.5}}};
  o.gain_step = 0.5;
  o.reference = OgaOptions::Reference::Machine;  // C1 = the machine's (6, 0.1); the best pair is searched anyway
  const OgaResult r = offline_gain_adjustment(sp, m, o);
  ASSERT_EQ(r.axis_names, (std::vector<std::string>{"X", "Z"}));

  const int ix = m.axis_index(0), iz = m.axis_index(2);
  const Eigen::Index rows = sp.samples() + 200;
  const Eigen::MatrixXd cmd = xyz_command(sp, m, rows);
  std::vector<drives::AxisResponse> px, pz;  // per configuration: the X (or Z) column is the one that matters
  std::vector<bool> ok[2];
  int admissible[2] = {0, 0};
  for (double kp : o.kp_grid)
    for (double kf : o.kf_grid) {
      core::Machine mm = m, tw = m;
      for (int a : {ix, iz}) {
        core::DriveParams& d = *mm.axes[static_cast<std::size_t>(a)].drive;
        d.kv_per_s = kp * kKv;
        d.kf = kf;
        core::DriveParams& t = *tw.axes[static_cast<std::size_t>(a)].drive;
        t = d;
        t.coulomb_Nm = 0;
        t.stribeck_static_Nm = 0;
      }
      drives::AxisResponse model = drives::simulate_axes(sp, mm), twin = drives::simulate_axes(sp, tw);
      for (int q = 0; q < 2; ++q) {
        const int a = q == 0 ? ix : iz;
        ok[q].push_back(admissible_by_brute_force(twin, model, a, m.axes[static_cast<std::size_t>(a)]));
        admissible[q] += ok[q].back();
      }
      px.push_back(model);
      pz.push_back(std::move(model));
    }
  // Both kinds exist on X (the jerk of KF 0.9): the comparison means something.
  EXPECT_GT(admissible[0], 0);
  EXPECT_LT(admissible[0], 9);
  for (int q = 0; q < 2; ++q)
    for (std::size_t c = 0; c < 9; ++c)
      EXPECT_EQ(r.sweep[static_cast<std::size_t>(q)][c].admissible, ok[q][c])
          << r.axis_names[static_cast<std::size_t>(q)] << " config " << c << ": "
          << r.sweep[static_cast<std::size_t>(q)][c].violation;

  motion::ContourOptions co;
  co.plane_normal = Eigen::Vector3d::UnitY();
  co.window_samples = 65536;
  double best = INFINITY;
  std::size_t bx = 0, bz = 0;
  for (std::size_t i = 0; i < 9; ++i)
    for (std::size_t j = 0; j < 9; ++j) {
      if (!ok[0][i] || !ok[1][j]) continue;
      Eigen::MatrixXd act = cmd;
      act.col(0) = px[i].position.col(ix);
      act.col(2) = pz[j].position.col(iz);
      const double mse = motion::contour_error(cmd, act, co).mse_um2;
      if (mse < best) best = mse, bx = i, bz = j;
    }
  ASSERT_EQ(r.best.size(), 2u);
  EXPECT_EQ(r.best[0].kp, o.kp_grid[bx / 3]);
  EXPECT_EQ(r.best[0].kf, o.kf_grid[bx % 3]);
  EXPECT_EQ(r.best[1].kp, o.kp_grid[bz / 3]);
  EXPECT_EQ(r.best[1].kf, o.kf_grid[bz % 3]);
  EXPECT_NEAR(r.best_mse_um2, best, 1e-9 * best);
  EXPECT_EQ(r.pairs_evaluated, admissible[0] * admissible[1]);
}

// ---- the receding windows
// ----------------------------------------------------------------------------------------------

OgaOptions quick_options() {
  OgaOptions o;
  o.kp_grid = {6.0};
  o.kf_grid = {0.1};
  o.reference = OgaOptions::Reference::Machine;
  o.search_best_pair = false;
  o.range = {{"X", {5.5, 6.5}}, {"Z", {5.5, 6.5}}};
  o.gain_step = 0.25;
  return o;
}

void expect_same_schedule(const OgaResult& a, const OgaResult& b) {
  ASSERT_EQ(a.windows.size(), b.windows.size());
  EXPECT_TRUE((a.table.kv_1000_per_min.array() == b.table.kv_1000_per_min.array()).all());
  const auto ka = a.schedule.kv_per_s.array(), kb = b.schedule.kv_per_s.array();
  EXPECT_TRUE(((ka == kb) || (ka.isNaN() && kb.isNaN())).all());
  for (std::size_t w = 0; w < a.windows.size(); ++w) {
    EXPECT_EQ(a.windows[w].final_kp, b.windows[w].final_kp) << w;
    EXPECT_EQ(a.windows[w].mse_um2, b.windows[w].mse_um2) << w;
  }
  EXPECT_EQ(a.c2_mse_um2, b.c2_mse_um2);
}

// Reference: Duong et al.'s Task 2, every candidate re-simulated from the first instant of the path with the gains
// chosen so far. The state at the window start (clone) must give the same positions bit for bit, hence the same
// choices.
TEST(OgaSearch, StateAtWindowStartChoosesAsReSimulatingFromTheStart) {
  const core::Machine m = drives::test::mikron();
  const core::Setpoints sp = short_profile(m);
  OgaOptions o = quick_options();
  const OgaResult incremental = offline_gain_adjustment(sp, m, o);
  o.from_start = true;
  const OgaResult from_start = offline_gain_adjustment(sp, m, o);
  ASSERT_GE(incremental.windows.size(), 3u);
  expect_same_schedule(incremental, from_start);
  // The gains did move (the test is not about a schedule that never changes).
  EXPECT_GT(incremental.table.kv_1000_per_min.maxCoeff() - incremental.table.kv_1000_per_min.minCoeff(), 0.2);
}

// Reference: DESIGN.md, results do not depend on the thread count.
TEST(OgaSearch, SameResultWithOneAndTwoThreads) {
  const core::Machine m = drives::test::mikron();
  const core::Setpoints sp = short_profile(m);
  OgaOptions o = quick_options();
  o.kp_grid = {4.0, 6.0, 8.0};
  o.kf_grid = {0.1, 0.6};
  o.search_best_pair = true;
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const OgaResult one = offline_gain_adjustment(sp, m, o);
  omp_set_num_threads(2);
  const OgaResult two = offline_gain_adjustment(sp, m, o);
  omp_set_num_threads(saved);
  expect_same_schedule(one, two);
  for (int q = 0; q < 2; ++q)
    for (std::size_t c = 0; c < one.sweep[static_cast<std::size_t>(q)].size(); ++c) {
      EXPECT_EQ(one.sweep[static_cast<std::size_t>(q)][c].admissible,
                two.sweep[static_cast<std::size_t>(q)][c].admissible);
      EXPECT_EQ(one.sweep[static_cast<std::size_t>(q)][c].twin.jerk.value,
                two.sweep[static_cast<std::size_t>(q)][c].twin.jerk.value);
    }
  EXPECT_EQ(one.best_mse_um2, two.best_mse_um2);
}

// Reference: drives::simulate_axes (every axis, the schedule as vmsim run applies it) and motion::contour_error on the
// whole path. The search sums the contour error window by window from the state it kept; the whole-path figures must
// be the same (the windows' lead-in lets the foot-point search converge before each window).
TEST(OgaSearch, VerificationReproducesTheSearch) {
  const core::Machine m = drives::test::mikron();
  const core::Setpoints sp = short_profile(m);
  const OgaOptions o = quick_options();
  const OgaResult r = offline_gain_adjustment(sp, m, o);
  const OgaVerification v = verify_oga(sp, m, r, o);
  EXPECT_NEAR(v.mse_c2_um2, r.c2_mse_um2, 1e-9 * r.c2_mse_um2);
  EXPECT_NEAR(v.mse_c1_um2, r.c1_mse_um2, 1e-9 * r.c1_mse_um2);
  EXPECT_TRUE(v.limits_held) << (v.advice.empty() ? "" : v.advice.front());
  ASSERT_EQ(v.axes.size(), 2u);
  EXPECT_EQ(v.axes[0].axis, "X");
  EXPECT_TRUE(v.axes[0].violation_c2.empty());
}

// ---- the schedule file
// -------------------------------------------------------------------------------------------------

TEST(OgaSchedule, FileRoundTripIsExactAndChecksItsPath) {
  const core::Machine m = drives::test::mikron();
  const core::Setpoints sp = short_profile(m);
  const OgaOptions o = quick_options();
  const OgaResult r = offline_gain_adjustment(sp, m, o);
  TempDir tmp;
  const fs::path f = tmp.path() / "gain_schedule.csv";
  write_gain_schedule(f, r.table, sp, m, "short", {"a comment"});
  const GainTable t = read_gain_table(f, sp, m);
  EXPECT_EQ(t.axis_names, r.table.axis_names);
  EXPECT_TRUE((t.kv_1000_per_min.array() == r.table.kv_1000_per_min.array()).all());
  EXPECT_TRUE((t.kf.array() == r.table.kf.array()).all());
  // Applied through simulate_axes: the same motion as the schedule in memory, bit for bit.
  const drives::GainSchedule g = read_gain_schedule(f, sp, m);
  drives::SimulateOptions so;
  so.gains = &g;
  const drives::AxisResponse from_file = drives::simulate_axes(sp, m, so);
  so.gains = &r.schedule;
  const drives::AxisResponse in_memory = drives::simulate_axes(sp, m, so);
  EXPECT_TRUE((from_file.position.array() == in_memory.position.array()).all());

  // Another path (the same program at another feed) is refused, naming the file.
  core::Setpoints other = sp;
  other.position.conservativeResize(sp.samples() - 1, Eigen::NoChange);
  try {
    read_gain_table(f, other, m);
    ADD_FAILURE() << "a schedule for another path was accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("gain_schedule.csv"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("run vmsim oga"), std::string::npos) << e.what();
  }
  other = sp;
  other.position(100, m.axis_index(0)) += 1e-3;
  EXPECT_THROW(read_gain_table(f, other, m), core::Error);
  // Tampered files.
  std::ifstream in(f);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto tamper = [&](const std::string& from, const std::string& to) {
    std::string s = text;
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    s.replace(at, from.size(), to);
    const fs::path g2 = tmp.path() / "tampered.csv";
    std::ofstream(g2) << s;
    try {
      read_gain_table(g2, sp, m);
      return std::string("accepted");
    } catch (const core::Error& e) {
      return std::string(e.what());
    }
  };
  EXPECT_NE(tamper("X_kv_1000_per_min", "Q_kv_1000_per_min").find("column"), std::string::npos);
  EXPECT_NE(tamper("# vmsim gain schedule 1", "# something else").find("not a vmsim gain schedule"), std::string::npos);
  const std::string line1 = "\n1,0.001000,";
  const auto at = text.find(line1);
  ASSERT_NE(at, std::string::npos);
  const auto eol = text.find('\n', at + 1);
  std::string bad = text.substr(at + 1, eol - at - 1);
  const auto c3 = bad.find(',', bad.find(',', bad.find(',') + 1) + 1);  // after row, t_s, X setpoint
  const auto c4 = bad.find(',', c3 + 1);
  std::string gain_bad = bad;
  gain_bad.replace(c3 + 1, c4 - c3 - 1, "-3");
  const std::string msg = tamper(bad, gain_bad);
  EXPECT_NE(msg.find("tampered.csv:8:"), std::string::npos) << msg;  // the file and its line (row 1)
  EXPECT_NE(msg.find("not a gain"), std::string::npos) << msg;
}

// ---- the OGA case (parts/oga_profile, Duong et al. section IV)
// ------------------------------------------------------------

void expect_schedule_respects_range_and_continuity(const OgaResult& r) {
  for (int q = 0; q < 2; ++q) {
    const auto col = r.table.kv_1000_per_min.col(q).array();
    EXPECT_GE(col.minCoeff(), r.range[static_cast<std::size_t>(q)].first - 1e-12);
    EXPECT_LE(col.maxCoeff(), r.range[static_cast<std::size_t>(q)].second + 1e-12);
    EXPECT_EQ(col[0], r.c1[static_cast<std::size_t>(q)].kp);  // the first window starts from C1
    EXPECT_TRUE((r.table.kf.col(q).array() == r.c1[static_cast<std::size_t>(q)].kf).all());  // KF fixed (case C2)
    for (std::size_t w = 1; w < r.windows.size(); ++w) {
      const Eigen::Index b = r.windows[w].window.begin;
      // Eq. 3: the first gain of a window equals the last of the previous one, exactly.
      EXPECT_EQ(col[b], col[b - 1]) << "window " << w;
      EXPECT_EQ(col[b - 1], r.windows[w - 1].last_kp[static_cast<std::size_t>(q)]);
      EXPECT_GE(r.windows[w].window.end - r.windows[w].window.begin, r.sinusoid_samples);
    }
  }
}

// Reference: Duong et al. Table II's claim, OGA against the best fixed gains on its case: never worse, gains within the
// range, continuous from window to window, every limit kept. Two settings: vmsim's own C1 (the best admissible
// pair of the search) with the range placed around it as Duong et al. placed [5, 6.5] around 6; and Duong et al.'s
// setting literally (C1 = the machine file's Kv 6, KF 0.1 = Duong et al.'s C1; range [5, 6.5]).
TEST(OgaCase, NeverWorseThanTheBestFixedGainsAndKeepsTheLimits) {
  const core::Machine m = drives::test::mikron();
  const core::Setpoints sp = case_profile(m);
  {
    OgaOptions o;  // Duong et al.'s grids, dK 0.03, f 10 Hz
    const OgaResult r = offline_gain_adjustment(sp, m, o);
    ASSERT_EQ(r.c1.size(), 2u);
    EXPECT_EQ(r.c1[0].kp, r.best[0].kp);
    EXPECT_LE(r.c2_mse_um2, r.c1_mse_um2);
    expect_schedule_respects_range_and_continuity(r);
    const OgaVerification v = verify_oga(sp, m, r, o);
    EXPECT_TRUE(v.limits_held) << (v.advice.empty() ? "" : v.advice.front());
    EXPECT_LE(v.mse_c2_um2, v.mse_c1_um2);
    EXPECT_NEAR(v.mse_c2_um2, r.c2_mse_um2, 1e-9 * r.c2_mse_um2);
  }
  {
    OgaOptions o;
    o.reference = OgaOptions::Reference::Machine;
    o.search_best_pair = false;
    o.range = {{"X", {5.0, 6.5}}, {"Z", {5.0, 6.5}}};
    const OgaResult r = offline_gain_adjustment(sp, m, o);
    EXPECT_EQ(r.c1[0].kp, 6.0);
    EXPECT_EQ(r.c1[1].kf, 0.1);
    EXPECT_LE(r.c2_mse_um2, r.c1_mse_um2);
    expect_schedule_respects_range_and_continuity(r);
    const OgaVerification v = verify_oga(sp, m, r, o);
    EXPECT_TRUE(v.limits_held) << (v.advice.empty() ? "" : v.advice.front());
    EXPECT_LE(v.mse_c2_um2, v.mse_c1_um2);
  }
}

TEST(OgaErrors, ProfilesAndOptionsOgaDoesNotHandle) {
  const core::Machine m = drives::test::mikron();
  const core::Setpoints sp = short_profile(m);
  OgaOptions o = quick_options();
  o.range = {{"X", {6.5, 7.0}}};  // C1's Kp = 6 is outside
  EXPECT_THROW(offline_gain_adjustment(sp, m, o), core::Error);
  o = quick_options();
  o.range = {{"Y", {5.0, 6.0}}};  // Y does not move
  EXPECT_THROW(offline_gain_adjustment(sp, m, o), core::Error);
  o = quick_options();
  o.frequency_hz = 400;  // p < 2
  EXPECT_THROW(offline_gain_adjustment(sp, m, o), core::Error);
  // Three moving axes: not a biaxial profile.
  core::Setpoints three = sp;
  for (Eigen::Index k = 0; k < three.samples(); ++k) three.position(k, m.axis_index(1)) += 1e-3 * k;
  try {
    offline_gain_adjustment(three, m, quick_options());
    ADD_FAILURE();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("biaxial"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vmsim::methods
