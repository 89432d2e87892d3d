// vmsim excite / identify end to end, as a user runs them on a machine: the excitation G-code of the
// predictive-compensation paper (inverse M-sequence on a ramp) run as a job through `vmsim motion` (the NC's
// interpolator and the Mikron X cascade drive of parts/machines/mikron_ucp710.toml), its trace.csv identified by `vmsim
// identify` (ARX, ARMAX, OE, orders 2/5), and a job on a DIFFERENT trajectory (a circle) run with [job] axis_models =
// the identified X. References: the cascade itself (the identified X must reproduce its positions on the circle with
// fit >= 99 %, the criterion, and its tracking error within 5 %); the error conventions of DESIGN.md (exit 2,
// the file / option named, nothing half-written).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

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
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;
using vmsim_test::write_file;

namespace fs = std::filesystem;

namespace {

using vmsim::test::kMikronMachine;

// One column of a CSV with a header row ('#' lines skipped).
std::vector<double> csv_column(const fs::path& p, const std::string& name) {
  std::ifstream in(p);
  std::string line;
  int col = -1;
  std::vector<double> v;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    if (col < 0) {
      for (std::size_t i = 0; i < cells.size(); ++i)
        if (cells[i] == name) col = static_cast<int>(i);
      if (col < 0) return v;
      continue;
    }
    v.push_back(std::stod(cells[static_cast<std::size_t>(col)]));
  }
  return v;
}

// 100 (1 - |y - yhat| / |y - mean y|): the predictive-compensation paper's fit, computed here independently of
// drives/sysid.
double fit_percent(const std::vector<double>& y, const std::vector<double>& yhat) {
  double mean = 0;
  for (double x : y) mean += x;
  mean /= static_cast<double>(y.size());
  double e2 = 0, t2 = 0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    e2 += (y[k] - yhat[k]) * (y[k] - yhat[k]);
    t2 += (y[k] - mean) * (y[k] - mean);
  }
  return 100.0 * (1.0 - std::sqrt(e2 / t2));
}

std::string job_toml(const std::string& name, const std::string& program, const std::string& start,
                     const std::string& extra = "") {
  return "[job]\nname = \"" + name + "\"\nmachine = \"" + kMikronMachine + "\"\nprogram = \"" + program +
         "\"\nstart_mm = " + start + "\n" + extra + "\n[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n";
}

TEST(SysidCli, ExciteOnTheMachineIdentifyAndRunAnotherJobOnTheIdentifiedAxis) {
  TempDir d("vmsim_sysid_cli_");
  const fs::path p = d.path();
  // 1. The excitation program for X (Td from a 40 Hz bandwidth: 10 ms; 7 bits; 4 periods on 1.2 m/min).
  CliRun r = run_vmsim("excite X --machine '" + kMikronMachine + "' --out '" + (p / "excite_x.ngc").string() +
                           "' --bandwidth-hz 40 --bits 7 --amplitude 0.05 --feed 1200 --periods 4",
                       d);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string ngc = slurp(p / "excite_x.ngc");
  ASSERT_NE(ngc.find("G1 X"), std::string::npos);
  // Its first move is "G0 X<start>": the job starts there at rest.
  const auto g0 = ngc.find("G0 X");
  ASSERT_NE(g0, std::string::npos);
  const double x0 = std::stod(ngc.substr(g0 + 4));
  write_file(p / "excite.toml", job_toml("excite_x", "excite_x.ngc", "[" + std::to_string(x0) + ", 0.0, 0.0]"));

  // 2. Run it: the trace the NC would log.
  r = run_vmsim("motion '" + (p / "excite.toml").string() + "' --out '" + (p / "m_excite").string() + "'", d);
  ASSERT_EQ(r.code, 0) << r.err;
  ASSERT_TRUE(fs::exists(p / "m_excite" / "trace.csv"));

  // 3. Identify: three structures, ranked; the chosen one in axis_models.toml.
  r = run_vmsim("identify --trace '" + (p / "m_excite" / "trace.csv").string() +
                    "' --structure all --orders 2,5 --out '" + (p / "id").string() + "'",
                d);
  ASSERT_EQ(r.code, 0) << r.err;
  std::printf("%s", r.out.c_str());
  const nlohmann::json rep = nlohmann::json::parse(slurp(p / "id" / "report.json"));
  vmsim_test::expect_report_html(p / "id", "--pictures no");  // a command without its own sections: all figures
  const auto& x = rep["axes"]["X"];
  std::vector<int> ranks;
  for (const char* s : {"arx", "armax", "oe"}) {
    ASSERT_TRUE(x["models"].contains(s)) << s;
    ranks.push_back(x["models"][s]["rank"].get<int>());
    EXPECT_GE(x["models"][s]["validation"]["fit_percent"].get<double>(), 99.0) << s;
    EXPECT_EQ(x["models"][s]["a"].size(), 5u);
    EXPECT_EQ(x["models"][s]["b"].size(), 2u);
  }
  std::sort(ranks.begin(), ranks.end());
  EXPECT_EQ(ranks, (std::vector<int>{1, 2, 3}));
  const std::string chosen = x["chosen"].get<std::string>();
  EXPECT_EQ(x["models"][chosen]["rank"].get<int>(), 1);
  ASSERT_TRUE(fs::exists(p / "id" / "axis_models.toml"));

  // 4. Another trajectory: a circle of radius 20 mm at 3 m/min, on the cascades and on the identified X.
  write_file(p / "circle.ngc", "G21 G90 G17\nG1 X20 Y0 F3000\nG3 X20 Y0 I-20 J0\nM2\n");
  write_file(p / "circle_cascade.toml", job_toml("circle_cascade", "circle.ngc", "[0.0, 0.0, 0.0]"));
  write_file(p / "circle_identified.toml",
             job_toml("circle_identified", "circle.ngc", "[0.0, 0.0, 0.0]",
                      "axis_models = \"" + (p / "id" / "axis_models.toml").string() + "\""));
  r = run_vmsim("motion '" + (p / "circle_cascade.toml").string() + "' --out '" + (p / "m_cascade").string() + "'", d);
  ASSERT_EQ(r.code, 0) << r.err;
  r = run_vmsim(
      "motion '" + (p / "circle_identified.toml").string() + "' --out '" + (p / "m_identified").string() + "'", d);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json mrep = nlohmann::json::parse(slurp(p / "m_identified" / "report.json"));
  vmsim_test::expect_report_html(p / "m_identified", "--pictures no");
  ASSERT_TRUE(mrep.contains("axis_models"));
  EXPECT_EQ(mrep["axis_models"]["identified_axes"], nlohmann::json::array({"X"}));
  const auto cmd = csv_column(p / "m_cascade" / "trace.csv", "X_command_mm");
  const auto y_cascade = csv_column(p / "m_cascade" / "trace.csv", "X_actual_mm");
  const auto y_ident = csv_column(p / "m_identified" / "trace.csv", "X_actual_mm");
  ASSERT_GT(y_cascade.size(), 1000u);
  ASSERT_EQ(y_cascade.size(), y_ident.size());
  const double fit = fit_percent(y_cascade, y_ident);
  std::vector<double> lag_c(cmd.size()), lag_i(cmd.size());
  for (std::size_t k = 0; k < cmd.size(); ++k) lag_c[k] = cmd[k] - y_cascade[k], lag_i[k] = cmd[k] - y_ident[k];
  const double tracking_fit = fit_percent(lag_c, lag_i);
  std::printf("circle, X identified vs cascade: position fit %.5f %%, tracking-error fit %.3f %%\n", fit, tracking_fit);
  EXPECT_GE(fit, 99.0);
  EXPECT_GE(tracking_fit, 95.0);
  // Y has no identified model: it runs its cascade in both jobs, to the same positions.
  EXPECT_EQ(csv_column(p / "m_cascade" / "trace.csv", "Y_actual_mm"),
            csv_column(p / "m_identified" / "trace.csv", "Y_actual_mm"));
}

TEST(SysidCli, ExciteCsvAndSimulatedTraceIdentifyOnTheirOwn) {
  TempDir d("vmsim_sysid_cli_");
  const fs::path p = d.path();
  CliRun r = run_vmsim("excite X --machine '" + kMikronMachine + "' --out '" + (p / "x.csv").string() +
                           "' --bits 6 --td-ms 5 --periods 4 --simulate '" + (p / "trace.csv").string() + "'",
                       d);
  ASSERT_EQ(r.code, 0) << r.err;
  // Inverse M-sequence of 6 bits: 2 (2^6 - 1) = 126 switching intervals of 5 samples per period, 4 periods, plus the
  // rests (0.1 s each side), the ramps (0.1 s each) and the final sample.
  EXPECT_EQ(csv_column(p / "x.csv", "X_mm").size(), static_cast<std::size_t>(126 * 5 * 4 + 400 + 1));
  r = run_vmsim("identify --trace '" + (p / "trace.csv").string() + "' --structure arx --orders 2,5 --out '" +
                    (p / "id").string() + "'",
                d);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json rep = nlohmann::json::parse(slurp(p / "id" / "report.json"));
  EXPECT_EQ(rep["axes"]["X"]["chosen"], "arx");
  EXPECT_FALSE(rep["axes"]["X"]["models"].contains("oe"));
}

TEST(SysidCli, TwoTracesIdentifyAtLeastAsWellAsOneOnAThirdTrace) {
  // Several experiments (repeated --trace): the Mikron X cascade excited by inverse M-sequences on a ramp up
  // (+1.2 m/min, switching interval Td 5 ms) and on a ramp down (-1.2 m/min, Td 2 ms: faster content the first trace
  // lacks), validated on a third trace neither saw (-0.6 m/min, Td 3 ms, another register length). The two traces
  // together (estimated as separate experiments) must validate at least as well as the first alone. Reference: the
  // validation MSE of the one-trace model on the same third trace. (Measured at this commit: ARX 3.154e-6 mm2 with
  // one trace, 3.065e-6 with two; the rest is the cascade's friction at the signal's reversals, which no linear model
  // carries.)
  TempDir d("vmsim_sysid_cli_");
  const fs::path p = d.path();
  auto excite = [&](const std::string& name, const std::string& opts) {
    const CliRun r = run_vmsim("excite X --machine '" + kMikronMachine + "' --out '" + (p / (name + ".csv")).string() +
                                   "' " + opts + " --simulate '" + (p / (name + "_trace.csv")).string() + "'",
                               d);
    ASSERT_EQ(r.code, 0) << r.err;
  };
  excite("up", "--bits 6 --td-ms 5 --periods 2 --feed 1200");
  excite("down", "--bits 6 --td-ms 2 --periods 2 --feed -1200");
  excite("val", "--bits 7 --td-ms 3 --periods 1 --feed -600");
  auto mse = [&](const std::string& traces, const std::string& out) {
    const CliRun r = run_vmsim("identify " + traces + " --validate '" + (p / "val_trace.csv").string() +
                                   "' --structure arx --orders 2,5 --out '" + (p / out).string() + "'",
                               d);
    EXPECT_EQ(r.code, 0) << r.err;
    const nlohmann::json rep = nlohmann::json::parse(slurp(p / out / "report.json"));
    return std::make_pair(rep["axes"]["X"]["models"]["arx"]["validation"]["mse"].get<double>(), rep);
  };
  const auto [one, rep1] = mse("--trace '" + (p / "up_trace.csv").string() + "'", "id1");
  const auto [two, rep2] =
      mse("--trace '" + (p / "up_trace.csv").string() + "' --trace '" + (p / "down_trace.csv").string() + "'", "id2");
  std::printf("validation MSE on the third trace: one trace %.4e mm2, two traces %.4e mm2\n", one, two);
  EXPECT_LE(two, one);
  ASSERT_EQ(rep2["inputs"]["traces"].size(), 2u);
  EXPECT_EQ(rep2["inputs"]["traces"][1]["use"], "estimation");
  EXPECT_NE(rep2["estimation"].get<std::string>().find("2 traces"), std::string::npos);
  // Without --validate the last of several traces is held out for validation.
  const CliRun r =
      run_vmsim("identify --trace '" + (p / "up_trace.csv").string() + "' --trace '" + (p / "down_trace.csv").string() +
                    "' --structure arx --out '" + (p / "id3").string() + "'",
                d);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json rep3 = nlohmann::json::parse(slurp(p / "id3" / "report.json"));
  EXPECT_EQ(rep3["inputs"]["traces"][1]["use"], "validation");
  EXPECT_EQ(rep3["validation"], "the last trace, held out");
}

TEST(SysidCli, BadInputIsAnErrorNamingWhatToFix) {
  TempDir d("vmsim_sysid_cli_");
  const fs::path p = d.path();
  write_file(p / "trace.csv", "t_s,X_command_mm,X_actual_mm\n0,0,0\n0.001,0.1,0\n0.002,oops,0.05\n");
  CliRun r = run_vmsim("identify --trace '" + (p / "trace.csv").string() + "' --out '" + (p / "id").string() + "'", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("trace.csv:4"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(p / "id" / "axis_models.toml"));

  r = run_vmsim("identify --trace '" + (p / "trace.csv").string() + "' --structure bj", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--structure 'bj'"), std::string::npos) << r.err;
  r = run_vmsim("identify --trace '" + (p / "trace.csv").string() + "' --orders 5", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--orders '5'"), std::string::npos) << r.err;

  r = run_vmsim("excite Q --machine '" + kMikronMachine + "' --out '" + (p / "q.ngc").string() + "'", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("no axis Q"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(p / "q.ngc"));
  // An excitation that leaves the travel says so and writes nothing.
  r = run_vmsim(
      "excite X --machine '" + kMikronMachine + "' --out '" + (p / "x.ngc").string() + "' --feed 30000 --periods 50",
      d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("outside axis X's travel"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(p / "x.ngc"));

  // A model file at another Te than the job's: the job names the model file.
  write_file(
      p / "models.toml",
      "[model]\nperiod_ms = 2.0\n\n[[axes]]\nname = \"X\"\nstructure = \"arx\"\na = [-0.5]\nb = [0.5]\nnk = 1\n");
  write_file(p / "circle.ngc", "G21 G90 G17\nG1 X20 Y0 F3000\nG3 X20 Y0 I-20 J0\nM2\n");
  write_file(p / "job.toml", job_toml("j", "circle.ngc", "[0.0, 0.0, 0.0]", "axis_models = \"models.toml\""));
  r = run_vmsim("motion '" + (p / "job.toml").string() + "' --out '" + (p / "m").string() + "'", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("models.toml"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("period_ms"), std::string::npos) << r.err;
}

TEST(SysidCli, CompensateTheStarfishWritesSetpointsProgramAndReport) {
  // vmsim compensate on parts/starfish (the predictive-compensation paper section 5) with the machine file's cascades
  // as the prediction: report.json's figures (reference: the predictive-compensation paper's mean reduction, -61.76 %),
  // the limits, and the compensated program readable by vmsim's own G-code reader and interpolator.
  TempDir d("vmsim_sysid_cli_");
  const fs::path p = d.path();
  CliRun r = run_vmsim(
      "compensate '" + std::string(VMSIM_SOURCE_DIR) + "/parts/starfish/job.toml' --out '" + (p / "c").string() + "'",
      d);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json rep = nlohmann::json::parse(slurp(p / "c" / "report.json"));
  const auto& ce = rep["contour_error"]["predicted"];
  std::printf("starfish: max %.3f -> %.3f um, mean %.3f -> %.3f um\n", ce["before"]["max_mm"].get<double>() * 1e3,
              ce["after"]["max_mm"].get<double>() * 1e3, ce["before"]["mean_mm"].get<double>() * 1e3,
              ce["after"]["mean_mm"].get<double>() * 1e3);
  EXPECT_LT(ce["after"]["max_mm"].get<double>(), ce["before"]["max_mm"].get<double>());
  EXPECT_LT(ce["after"]["mean_mm"].get<double>(), (1.0 - 0.6176) * ce["before"]["mean_mm"].get<double>());
  EXPECT_TRUE(rep["limits"]["compensated_within_limits"].get<bool>());
  for (const char* a : {"X", "Y"})
    EXPECT_LE(rep["limits"]["compensated"][a]["peak_jerk_mm_per_s3"].get<double>(),
              rep["limits"]["compensated"][a]["limit_jerk_mm_per_s3"].get<double>() * (1 + 1e-6));
  ASSERT_TRUE(fs::exists(p / "c" / "compensated_setpoints.csv"));
  ASSERT_TRUE(fs::exists(p / "c" / "contour_errors.csv"));
  // The compensated program (the original's G1 moves and feed, each vertex moved) runs through vmsim's reader and
  // interpolator in the original's time (reference: `vmsim interp` of the original job, within 1 %), and run on the
  // machine model it cuts closer to the original plan than the original program (core/contour, mean |CE|).
  const auto& cp = rep["compensated_program"];
  EXPECT_EQ(cp["file"], "compensated.ngc");
  EXPECT_EQ(cp["blocks"].get<int>(), cp["original_moves"].get<int>());
  const auto& em = rep["contour_error"]["compensated_program_on_machine"];
  std::printf("starfish, compensated program on the machine: max %.3f -> %.3f um, mean %.3f -> %.3f um\n",
              em["before"]["max_mm"].get<double>() * 1e3, em["after"]["max_mm"].get<double>() * 1e3,
              em["before"]["mean_mm"].get<double>() * 1e3, em["after"]["mean_mm"].get<double>() * 1e3);
  EXPECT_LT(em["after"]["mean_mm"].get<double>(), em["before"]["mean_mm"].get<double>());
  EXPECT_TRUE(cp["within_limits"].get<bool>());
  auto cycle = [](const std::string& out) {
    const auto at = out.find("cycle time: ");
    return at == std::string::npos ? -1.0 : std::stod(out.substr(at + 12));
  };
  r = run_vmsim("interp '" + std::string(VMSIM_SOURCE_DIR) + "/parts/starfish/job.toml' --summary-only", d);
  ASSERT_EQ(r.code, 0) << r.err;
  const double t_orig = cycle(r.out);
  write_file(p / "c" / "job.toml", job_toml("compensated", "compensated.ngc", "[30.0, 0.0, 0.0]"));
  r = run_vmsim("interp '" + (p / "c" / "job.toml").string() + "' --summary-only", d);
  EXPECT_EQ(r.code, 0) << r.err;
  const double t_comp = cycle(r.out);
  std::printf("starfish cycle time: original %.3f s, compensated program %.3f s\n", t_orig, t_comp);
  ASSERT_GT(t_orig, 0.0);
  EXPECT_NEAR(t_comp, t_orig, 0.01 * t_orig);
  // Bad options name themselves.
  r = run_vmsim("compensate '" + std::string(VMSIM_SOURCE_DIR) + "/parts/starfish/job.toml' --buffer 10 --out '" +
                    (p / "bad").string() + "'",
                d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--buffer 10"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(p / "bad" / "report.json"));
}

}  // namespace
