// vmsim compensate end to end on the five-axis blade (parts/blade, the predictive-compensation paper section 5) and the
// compensated program a user would send to the machine. References: the machine model itself (the compensated program
// read back, re-timed by vmsim's interpolator and run on the Mikron's cascades must cut a smaller contour error against
// the ORIGINAL plan than the original program does; measured by core/contour, not by the compensation's own search);
// the original program's cycle time through `vmsim interp` (a separate process) for the re-timing; the machine file's
// axis limits. The predictive-compensation paper's -31.43 % on its blade is printed for comparison, not asserted.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/app/cli_util.hpp"

namespace fs = std::filesystem;
using vmsim_test::CliRun;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace {

double cycle_time(const std::string& interp_stdout) {
  const auto at = interp_stdout.find("cycle time: ");
  if (at == std::string::npos) return -1.0;
  return std::stod(interp_stdout.substr(at + 12));
}

const std::string kBlade = std::string(VMSIM_SOURCE_DIR) + "/parts/blade";

// The compensated program cuts at least as well as the original on the machine model, max and mean (and the tool
// axis' orientation error where there is one), within the 1 nm (1e-6 deg) sim::compensate_job counts as equal; it is
// then written as compensated.<ext>. Reference: the original program re-timed and run on the same chain.
void expect_not_worse(const nlohmann::json& rep, const char* part) {
  const auto& m = rep["contour_error"]["compensated_program_on_machine"];
  const double b_max = m["before"]["max_mm"].get<double>(), a_max = m["after"]["max_mm"].get<double>();
  const double b_mean = m["before"]["mean_mm"].get<double>(), a_mean = m["after"]["mean_mm"].get<double>();
  std::printf("%s, compensated program on the machine: max %.4f -> %.4f um, mean %.4f -> %.4f um\n", part, b_max * 1e3,
              a_max * 1e3, b_mean * 1e3, a_mean * 1e3);
  EXPECT_LE(a_max, b_max + 1e-6) << part;
  EXPECT_LE(a_mean, b_mean + 1e-6) << part;
  if (m["before"].contains("orientation_max_deg")) {
    EXPECT_LE(m["after"]["orientation_max_deg"].get<double>(), m["before"]["orientation_max_deg"].get<double>() + 1e-6);
    EXPECT_LE(m["after"]["orientation_mean_deg"].get<double>(),
              m["before"]["orientation_mean_deg"].get<double>() + 1e-6);
  }
  const auto& cp = rep["compensated_program"];
  EXPECT_EQ(cp["file"].get<std::string>().rfind("compensated.", 0), 0u) << cp.dump();
  EXPECT_EQ(cp["verdict"].get<std::string>().rfind("not worse", 0), 0u) << cp.dump();
}

// Every G2/G3 block of a G-code text (absolute X Y, incremental I J, G17) checked against LinuxCNC's rule for a
// centre-format arc (interp_internal.hh, mm: the radii to the start and to the end differ by at most 0.0283 mm and
// 0.1 % of the larger); the test's own arithmetic, not vmsim's reader. Returns the number of arcs.
int expect_linuxcnc_arcs(const std::string& ngc) {
  std::istringstream text(ngc);
  double x = 0, y = 0;
  int arcs = 0;
  for (std::string line; std::getline(text, line);) {
    if (line.empty() || line[0] == '(') continue;
    std::istringstream words(line);
    bool arc = false;
    double nx = x, ny = y, i = 0, j = 0;
    for (std::string w; words >> w;) {
      if (w == "G2" || w == "G3") arc = true;
      if (w.size() < 2) continue;
      const double v = std::atof(w.c_str() + 1);
      if (w[0] == 'X') nx = v;
      if (w[0] == 'Y') ny = v;
      if (w[0] == 'I') i = v;
      if (w[0] == 'J') j = v;
    }
    if (arc) {
      ++arcs;
      const double cx = x + i, cy = y + j;
      const double r1 = std::hypot(x - cx, y - cy), r2 = std::hypot(nx - cx, ny - cy);
      EXPECT_LE(std::abs(r1 - r2), 2 * 0.01 * std::sqrt(2.0)) << line;
      EXPECT_LE(std::abs(r1 - r2), 0.001 * std::max(r1, r2)) << line;
    }
    x = nx, y = ny;
  }
  return arcs;
}

}  // namespace

TEST(CompensateCli, FiveAxisBladeTipAndOrientationErrorsFallAndTheCompensatedProgramCutsBetter) {
  TempDir d("vmsim_compensate_cli_");
  const fs::path p = d.path();
  CliRun r = run_vmsim("compensate '" + kBlade + "/job.toml' --out '" + (p / "c").string() + "'", d);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("compensated program cuts worse"), std::string::npos) << r.err;
  std::printf("%s", r.out.c_str());
  const nlohmann::json rep = nlohmann::json::parse(slurp(p / "c" / "report.json"));
  // The prediction (the cascades themselves here): tip and tool axis both fall, the maximum does not grow.
  const auto& pr = rep["contour_error"]["predicted"];
  EXPECT_LT(pr["after"]["mean_mm"].get<double>(), pr["before"]["mean_mm"].get<double>());
  EXPECT_LE(pr["after"]["max_mm"].get<double>(), pr["before"]["max_mm"].get<double>());
  ASSERT_TRUE(pr["before"].contains("orientation_mean_deg"));
  EXPECT_LT(pr["after"]["orientation_mean_deg"].get<double>(), pr["before"]["orientation_mean_deg"].get<double>());
  EXPECT_TRUE(rep["limits"]["compensated_within_limits"].get<bool>());
  vmsim_test::expect_report_html(p / "c", "--pictures yes");
  std::printf("blade, mean tip contour error %+.1f %% (the predictive-compensation paper on its blade: -31.43 %%)\n",
              pr["change_percent"]["mean"].get<double>());

  // The compensated program: the original's moves as CL (tip and tool axis), plus the G-code form with A and C.
  const auto& cp = rep["compensated_program"];
  EXPECT_EQ(cp["file"], "compensated.cl");
  EXPECT_EQ(cp["blocks"].get<int>(), cp["original_moves"].get<int>());
  ASSERT_TRUE(fs::exists(p / "c" / "compensated.cl"));
  ASSERT_TRUE(fs::exists(p / "c" / "compensated_tcp.ngc"));
  EXPECT_NE(slurp(p / "c" / "compensated_tcp.ngc").find(" A"), std::string::npos);
  // End to end on the machine model: the program re-timed and run cuts closer to the original plan.
  const auto& em = rep["contour_error"]["compensated_program_on_machine"];
  EXPECT_LT(em["after"]["mean_mm"].get<double>(), em["before"]["mean_mm"].get<double>());
  EXPECT_LT(em["after"]["orientation_mean_deg"].get<double>(), em["before"]["orientation_mean_deg"].get<double>());
  expect_not_worse(rep, "blade");
  EXPECT_TRUE(cp["within_limits"].get<bool>());

  // Re-timing, through a separate `vmsim interp` of each program: within 1 % (the programs differ by micrometres).
  r = run_vmsim("interp '" + kBlade + "/job.toml' --summary-only", d);
  ASSERT_EQ(r.code, 0) << r.err;
  const double t_orig = cycle_time(r.out);
  std::ofstream(p / "c" / "job.toml") << "[job]\nname = \"blade_compensated\"\nmachine = \"" << kBlade
                                      << "/../machines/mikron_ucp710.toml\"\nprogram = \"compensated.cl\"\n"
                                         "[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n";
  r = run_vmsim("interp '" + (p / "c" / "job.toml").string() + "' --summary-only", d);
  ASSERT_EQ(r.code, 0) << r.err;
  const double t_comp = cycle_time(r.out);
  std::printf("blade cycle time: original %.3f s, compensated program %.3f s\n", t_orig, t_comp);
  ASSERT_GT(t_orig, 0.0);
  EXPECT_NEAR(t_comp, t_orig, 0.01 * t_orig);
  EXPECT_NEAR(cp["cycle_time_compensated_program_s"].get<double>(), t_comp, 1e-9);
  // The G-code form with the A and C words (tool-centre-point, [job] tcp) against the original in the same form.
  ASSERT_TRUE(cp["tcp_form"].is_object());
  const double t_tcp0 = cp["tcp_form"]["cycle_time_original_s"].get<double>();
  const double t_tcp1 = cp["tcp_form"]["cycle_time_compensated_s"].get<double>();
  std::printf("blade, tool-centre-point G-code: original %.3f s, compensated %.3f s\n", t_tcp0, t_tcp1);
  EXPECT_NEAR(t_tcp1, t_tcp0, 0.01 * t_tcp0);
}

TEST(CompensateCli, CircleArcsFollowTheCorrectionAndAProgramThatCutsWorseIsNotWrittenAsCompensated) {
  // A G3 circle (R 20 mm at 3 m/min, twice round, a radial G1 lead-in) on the Mikron. The compensated program keeps the
  // arcs G3 about the programmed centre, in pieces that follow the correction along them, each within LinuxCNC's
  // radius rule (the test's own arithmetic). On the machine model (reference: the original program on the same chain)
  // the pieces bring the mean down (issue 23: quarter arcs to corrected ends cut 3.89 -> 3.94 um mean, 5.6 -> 26.7 um
  // max); the largest error, at the lead-in's corner which the interpolator rounds anew beside a short piece, stays
  // above the original's (parts/starfish/README.md, "Arcs"), so the program must not be written as compensated.ngc:
  // compensated_rejected.ngc, a warning, the verdict in report.json. Whichever way it comes out, the two go together.
  TempDir d("vmsim_compensate_cli_");
  const fs::path p = d.path();
  const std::string machine = std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml";
  std::ofstream(p / "circle.ngc") << "G21 G90 G17\nG1 X20 Y0 F3000\nG3 X20 Y0 I-20 J0\nG3 X20 Y0 I-20 J0\nM2\n";
  std::ofstream(p / "job.toml") << "[job]\nname = \"circle\"\nmachine = \"" << machine
                                << "\"\nprogram = \"circle.ngc\"\nstart_mm = [0.0, 0.0, 0.0]\n[interpolation]\n"
                                   "period_ms = 1.0\ntolerance_mm = 0.020\n";
  CliRun r = run_vmsim("compensate '" + (p / "job.toml").string() + "' --out '" + (p / "c").string() + "'", d);
  ASSERT_EQ(r.code, 0) << r.err;
  std::printf("%s", r.out.c_str());
  const nlohmann::json rep = nlohmann::json::parse(slurp(p / "c" / "report.json"));
  const auto& cp = rep["compensated_program"];
  const auto& m = rep["contour_error"]["compensated_program_on_machine"];
  const double b_max = m["before"]["max_mm"].get<double>(), a_max = m["after"]["max_mm"].get<double>();
  const double b_mean = m["before"]["mean_mm"].get<double>(), a_mean = m["after"]["mean_mm"].get<double>();
  std::printf("circle, compensated program on the machine: max %.4f -> %.4f um, mean %.4f -> %.4f um, %s\n",
              b_max * 1e3, a_max * 1e3, b_mean * 1e3, a_mean * 1e3, cp["file"].get<std::string>().c_str());
  EXPECT_LT(a_mean, 0.5 * b_mean);  // the correction along the arcs reaches the machine
  const bool worse = a_max > b_max + 1e-6 || a_mean > b_mean + 1e-6;
  const std::string file = worse ? "compensated_rejected.ngc" : "compensated.ngc";
  EXPECT_EQ(cp["file"].get<std::string>(), file);
  EXPECT_TRUE(fs::exists(p / "c" / file));
  EXPECT_FALSE(fs::exists(p / "c" / (worse ? "compensated.ngc" : "compensated_rejected.ngc")));
  EXPECT_EQ(r.err.find("compensated_program_worse") != std::string::npos, worse) << r.err;
  EXPECT_EQ(rep["verdict"].get<std::string>(), worse ? "warnings" : "ok");
  const std::string ngc = slurp(p / "c" / file);
  EXPECT_EQ(ngc.find("G1 X19"), std::string::npos) << "arcs written as chords";
  const int arcs = expect_linuxcnc_arcs(ngc);
  EXPECT_GT(arcs, 2 * 4);  // more pieces than quarter arcs
  EXPECT_EQ(cp["blocks"].get<int>(), 1 + arcs);
  EXPECT_TRUE(cp["within_limits"].get<bool>());
  // The cycle time of the program with the pieces, re-timed by a separate `vmsim interp`, as report.json has it.
  std::ofstream(p / "c" / "job.toml") << "[job]\nname = \"circle_c\"\nmachine = \"" << machine << "\"\nprogram = \""
                                      << file
                                      << "\"\nstart_mm = [0.0, 0.0, 0.0]\n"
                                         "[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n";
  r = run_vmsim("interp '" + (p / "c" / "job.toml").string() + "' --summary-only", d);
  ASSERT_EQ(r.code, 0) << r.err;
  const double t_comp = cycle_time(r.out);
  std::printf("circle cycle time: original %.3f s, compensated program %.3f s\n",
              cp["cycle_time_original_s"].get<double>(), t_comp);
  EXPECT_NEAR(cp["cycle_time_compensated_program_s"].get<double>(), t_comp, 1e-9);
}

TEST(CompensateCli, StarfishCompensatedProgramCutsNoWorseThanTheOriginal) {
  // parts/starfish (the predictive-compensation paper's starfish, 1250 G1 chords): the compensated program on the
  // machine model against the original program on the same chain (expect_not_worse).
  TempDir d("vmsim_compensate_cli_");
  const fs::path p = d.path();
  const CliRun r = run_vmsim("compensate '" + std::string(VMSIM_SOURCE_DIR) + "/parts/starfish/job.toml' --out '" +
                                 (p / "c").string() + "' --no-render",
                             d);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json rep = nlohmann::json::parse(slurp(p / "c" / "report.json"));
  expect_not_worse(rep, "starfish");
  EXPECT_TRUE(fs::exists(p / "c" / "compensated.ngc"));
  EXPECT_FALSE(fs::exists(p / "c" / "compensated_rejected.ngc"));
}
