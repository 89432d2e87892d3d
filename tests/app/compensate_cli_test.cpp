// vmsim compensate end to end on the five-axis blade (parts/blade, the predictive-compensation paper section 5) and the
// compensated program a user would send to the machine. References: the machine model itself (the compensated program
// read back, re-timed by vmsim's interpolator and run on the Mikron's cascades must cut a smaller contour error against
// the ORIGINAL plan than the original program does; measured by core/contour, not by the compensation's own search);
// the original program's cycle time through `vmsim interp` (a separate process) for the re-timing; the machine file's
// axis limits. The predictive-compensation paper's -31.43 % on its blade is printed for comparison, not asserted.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
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

TEST(CompensateCli, CircleArcsStayArcsInTheCompensatedProgramAndKeepTheTime) {
  // A G3 circle (R 20 mm at 3 m/min, twice round) on the Mikron. The compensated program keeps each arc a G3 about the
  // programmed centre, in pieces of at most 90 deg (a full circle's corrected end is not its corrected start), each
  // to its corrected end point, at the original feed; re-timed by `vmsim interp` within 5 % of the original (as G1
  // chords of 0.5 um sag the same circle took the interpolator twice as long: a blend at every chord). What the arcs'
  // end-point correction does to the contour error is printed, not asserted: at this commit it does not reduce it
  // (parts/starfish/README.md, "Arcs").
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
  EXPECT_EQ(cp["blocks"].get<int>(), 1 + 2 * 4);  // the G1, then each full circle in four quarter arcs
  const std::string ngc = slurp(p / "c" / "compensated.ngc");
  EXPECT_NE(ngc.find("G3 X"), std::string::npos);
  EXPECT_EQ(ngc.find("G1 X19"), std::string::npos) << "arcs written as chords";
  EXPECT_TRUE(cp["within_limits"].get<bool>());
  // Where the program form cuts worse on the machine model than the original (the arcs' correction varies between
  // their corrected ends), the user is warned on stderr; where it cuts better, not.
  const auto& on_machine = rep["contour_error"]["compensated_program_on_machine"];
  const bool worse =
      on_machine["after"]["max_mm"].get<double>() > 1.05 * on_machine["before"]["max_mm"].get<double>() ||
      on_machine["after"]["mean_mm"].get<double>() > on_machine["before"]["mean_mm"].get<double>();
  EXPECT_EQ(r.err.find("compensated program cuts worse") != std::string::npos, worse) << r.err;
  r = run_vmsim("interp '" + (p / "job.toml").string() + "' --summary-only", d);
  ASSERT_EQ(r.code, 0) << r.err;
  const double t_orig = cycle_time(r.out);
  std::ofstream(p / "c" / "job.toml") << "[job]\nname = \"circle_c\"\nmachine = \"" << machine
                                      << "\"\nprogram = \"compensated.ngc\"\nstart_mm = [0.0, 0.0, 0.0]\n"
                                         "[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n";
  r = run_vmsim("interp '" + (p / "c" / "job.toml").string() + "' --summary-only", d);
  ASSERT_EQ(r.code, 0) << r.err;
  const double t_comp = cycle_time(r.out);
  std::printf("circle cycle time: original %.3f s, compensated program %.3f s\n", t_orig, t_comp);
  ASSERT_GT(t_orig, 0.0);
  EXPECT_NEAR(t_comp, t_orig, 0.05 * t_orig);
}
