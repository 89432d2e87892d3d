// [job] gain_schedule in vmsim motion and vmsim run, end to end as a user runs them.
// References: the drive model itself (a schedule of the machine's own gains is no schedule at all; halving Kv
// doubles the steady following error v (1 - KF) / Kv of a position loop with velocity feedforward, the feed-drive
// simulation paper Fig. 2), and the gain schedule's documented format (drives/oga_schedule.hpp, parts/README.md): the
// schedules here are written by the test from that description, not by vmsim.
#include "core/job.hpp"
#include "core/machine.hpp"

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
using vmsim_test::Csv;
using vmsim_test::read_csv;
using vmsim_test::read_json;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;
using vmsim_test::write_file;

namespace fs = std::filesystem;

namespace {

using vmsim::test::kMikronMachine;
using vmsim::test::kSourceDir;

// A short XZ profile at 3 m/min (1.1 s): 8 mm straight, concave R30 over 35 deg, convex R20 over 70 deg (Z reverses),
// 6 mm straight; `feed` in mm/min.
void write_short_job(const fs::path& dir, const std::string& name, int feed = 3000, const std::string& extra = "",
                     const std::string& tables = "") {
  write_file(dir / (name + ".ngc"), "G21 G90 G94 G18\nG1 X-12.000000 Z0.000000 F" + std::to_string(feed) +
                                        "\nG2 X5.207293 Z5.425439 I0.000000 K30.000000\n"
                                        "G3 X28.150351 Z5.425439 I11.471529 K-16.383041\n"
                                        "G1 X33.065263 Z1.983980\nM30\n");
  write_file(dir / (name + ".toml"), "[job]\nname = \"" + name + "\"\nmachine = \"" + kMikronMachine +
                                         "\"\nprogram = \"" + name + ".ngc\"\nstart_mm = [-20.0, 0.0, 0.0]\n" + extra +
                                         "\n[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n" + tables);
}

// A gain schedule written from the format's description (not by vmsim): every setpoint of `setpoints_csv` (vmsim
// motion's) with the given X and Z gains.
void write_schedule(const fs::path& file, const fs::path& setpoints_csv, double kv_x, double kf_x, double kv_z,
                    double kf_z) {
  const Csv sp = read_csv(setpoints_csv);
  const int t = sp.col("t_s"), x = sp.col("X_mm"), z = sp.col("Z_mm");
  std::ostringstream s;
  s << "# vmsim gain schedule 1: written by hand in a test\n# period_s=0.001\n# samples=" << sp.rows.size() << "\n";
  s << "row,t_s,X_setpoint_mm,X_kv_1000_per_min,X_kf,Z_setpoint_mm,Z_kv_1000_per_min,Z_kf\n";
  char buf[256];
  for (std::size_t k = 0; k < sp.rows.size(); ++k) {
    std::snprintf(buf, sizeof buf, "%zu,%.6f,%.9f,%.17g,%.17g,%.9f,%.17g,%.17g\n", k, sp.rows[k][t], sp.rows[k][x],
                  kv_x, kf_x, sp.rows[k][z], kv_z, kf_z);
    s << buf;
  }
  write_file(file, s.str());
}

double max_abs_col(const Csv& c, const std::string& n) {
  double m = 0;
  const int i = c.col(n);
  for (const auto& r : c.rows) m = std::max(m, std::abs(r[static_cast<std::size_t>(i)]));
  return m;
}

}  // namespace

// Reference: the drive model. A schedule holding the machine file's own Kv and KF is the same drive: the motion is
// the same to the last digit. Halving X's Kv doubles its steady following error v (1 - KF) / Kv on the straights.
TEST(GainScheduleCli, GainScheduleKeyAppliesItsGainsToMotionAndRun) {
  TempDir tmp;
  const fs::path d = tmp.path();
  write_short_job(d, "plain");
  const CliRun plain =
      run_vmsim("motion '" + (d / "plain.toml").string() + "' --out '" + (d / "plain").string() + "'", tmp);
  ASSERT_EQ(plain.code, 0) << plain.err;

  const vmsim::core::Machine m = vmsim::core::load_machine(kMikronMachine);
  const auto& dx = *m.axes[static_cast<std::size_t>(m.axis_index(0))].drive;
  const auto& dz = *m.axes[static_cast<std::size_t>(m.axis_index(2))].drive;
  const double kv_x = dx.kv_per_s * 60.0 / 1000.0, kv_z = dz.kv_per_s * 60.0 / 1000.0;
  EXPECT_NEAR(kv_x, 6.0, 1e-12);  // Duong et al.'s C1 (the machine file's value; never tuned per test)

  write_schedule(d / "same.csv", d / "plain" / "setpoints.csv", kv_x, dx.kf, kv_z, dz.kf);
  write_short_job(d, "same", 3000, "gain_schedule = \"same.csv\"");
  const CliRun same =
      run_vmsim("motion '" + (d / "same.toml").string() + "' --out '" + (d / "same").string() + "'", tmp);
  ASSERT_EQ(same.code, 0) << same.err;
  EXPECT_EQ(slurp(d / "same" / "actual.csv"), slurp(d / "plain" / "actual.csv"));
  EXPECT_EQ(slurp(d / "same" / "currents.csv"), slurp(d / "plain" / "currents.csv"));
  EXPECT_NE(read_json(d / "same" / "report.json")["gain_schedule"].get<std::string>().find("same.csv"),
            std::string::npos);

  write_schedule(d / "half.csv", d / "plain" / "setpoints.csv", kv_x / 2, dx.kf, kv_z, dz.kf);
  write_short_job(d, "half", 3000, "gain_schedule = \"half.csv\"");
  const CliRun half =
      run_vmsim("motion '" + (d / "half.toml").string() + "' --out '" + (d / "half").string() + "'", tmp);
  ASSERT_EQ(half.code, 0) << half.err;
  const double e_plain = max_abs_col(read_csv(d / "plain" / "errors.csv"), "X_tracking_mm");
  const double e_half = max_abs_col(read_csv(d / "half" / "errors.csv"), "X_tracking_mm");
  EXPECT_NEAR(e_half / e_plain, 2.0, 0.15) << e_plain << " " << e_half;
  // Z keeps its gains: its tracking error barely moves (the X lag shifts the contour, not Z's loop).
  const double z_plain = max_abs_col(read_csv(d / "plain" / "errors.csv"), "Z_tracking_mm");
  const double z_half = max_abs_col(read_csv(d / "half" / "errors.csv"), "Z_tracking_mm");
  EXPECT_NEAR(z_half / z_plain, 1.0, 1e-6);

  // vmsim run applies it too (report names it), and refuses --feed-scale (other setpoints) before simulating.
  write_short_job(d, "same", 3000, "gain_schedule = \"same.csv\"",
                  "[stock]\ntype = \"box\"\nmin_mm = [-25.0, -6.0, -5.0]\nmax_mm = [40.0, 6.0, 2.0]\n"
                  "[removal]\nspacing_mm = 0.2\n");
  const CliRun run =
      run_vmsim("run '" + (d / "same.toml").string() + "' --out '" + (d / "run").string() + "' --no-render -q", tmp);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(read_json(d / "run" / "report.json")["gain_schedule"].get<std::string>().find("same.csv"),
            std::string::npos);
  const CliRun scaled = run_vmsim("run '" + (d / "same.toml").string() + "' --out '" + (d / "scaled").string() +
                                      "' --feed-scale 0.5 --no-render -q",
                                  tmp);
  EXPECT_EQ(scaled.code, 2);
  EXPECT_NE(scaled.err.find("gain_schedule"), std::string::npos) << scaled.err;
  EXPECT_FALSE(fs::exists(d / "scaled" / "report.json"));
}

// Reference: drives/oga_schedule.hpp: a schedule is checked against the setpoints it is applied to.
TEST(GainScheduleCli, GainScheduleForAnotherPathIsRefusedNamingTheFile) {
  TempDir tmp;
  const fs::path d = tmp.path();
  write_short_job(d, "plain");
  ASSERT_EQ(run_vmsim("motion '" + (d / "plain.toml").string() + "' --out '" + (d / "plain").string() + "'", tmp).code,
            0);
  write_schedule(d / "for_3000.csv", d / "plain" / "setpoints.csv", 6, 0.1, 6, 0.1);
  // The same program at 2 m/min: other setpoints.
  write_short_job(d, "slower", 2000, "gain_schedule = \"for_3000.csv\"");
  const CliRun r =
      run_vmsim("motion '" + (d / "slower.toml").string() + "' --out '" + (d / "slower").string() + "'", tmp);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("for_3000.csv"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("vmsim oga"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(d / "slower" / "report.json"));
  // A missing file is an error naming the key.
  write_short_job(d, "missing", 3000, "gain_schedule = \"nowhere.csv\"");
  const CliRun miss =
      run_vmsim("motion '" + (d / "missing.toml").string() + "' --out '" + (d / "missing").string() + "'", tmp);
  EXPECT_EQ(miss.code, 2);
  EXPECT_NE(miss.err.find("gain_schedule"), std::string::npos) << miss.err;
  EXPECT_NE(miss.err.find("nowhere.csv"), std::string::npos) << miss.err;
}
