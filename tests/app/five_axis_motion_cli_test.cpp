// `vmsim motion` on a five-axis table-tilting machine, end to end as a user runs it: LinuxCNC's CAM-posted demo
// boat-xyzac.ngc (tool-centre-point programming, G93 inverse-time moves, A/C table turns) on LinuxCNC's xyzac-trt sim
// machine (parts/machines/xyzac_trt.toml, the job parts/boat_xyzac/job.toml). The program is read from ../shared/data
// (LinuxCNC's, GPL-2+, not copied into the project); the test skips without it. To keep `make test` short it runs the
// program's header and its first finishing passes (lines 1-12 and 318-355: two table turns, G93 passes), ending as
// the program ends; `vmsim motion parts/boat_xyzac/job.toml` runs the whole program (parts/README.md).
// References: the machine's limits (setpoints and currents within them), and the steady following error of a
// P position loop with a PI velocity loop, v ((1 - KF)/Kv + d Te) (Duong et al. Fig. 6; drives/cascade_axis tests), for
// each axis at its peak setpoint speed: the largest tracking error of every axis, rotary ones in degrees, is that
// (the program runs the axes at constant speed long enough to settle) and not more.
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

using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace fs = std::filesystem;

namespace {

const fs::path kData = fs::path(VMSIM_SHARED_DIR) / "data" / "gcode";

std::vector<std::string> lines_of(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> v;
  std::string l;
  while (std::getline(in, l)) {
    if (!l.empty() && l.back() == '\r') l.pop_back();
    v.push_back(l);
  }
  return v;
}

TEST(FiveAxisMotionCli, BoatXyzacFinishingPassesOnXyzacTrt) {
  if (!fs::exists(kData / "programs" / "boat-xyzac.ngc"))
    GTEST_SKIP() << "reference data not found at " << kData.string()
                 << " (../shared/data is written outside the project; a fresh clone does not have it)";
  TempDir tmp;
  const std::vector<std::string> src = lines_of(kData / "programs" / "boat-xyzac.ngc");
  ASSERT_GE(src.size(), 360u);
  ASSERT_EQ(src[1].rfind("M428", 0), 0u);
  ASSERT_EQ(src[317], "( FINISH1 FLOWLINE SRF_MILL1 )");
  ASSERT_EQ(src[354], "G00 Z5.0");
  std::string prog;
  for (std::size_t i = 0; i < 12; ++i) prog += src[i] + "\n";
  for (std::size_t i = 317; i < 355; ++i) prog += src[i] + "\n";
  prog += "G00 Z10 M09\nG00 X0. Y0. A0 C0\nM429\nM30\n%\n";  // the program's own ending
  std::ofstream(tmp.path() / "boat_part.ngc") << prog;
  const fs::path machine = fs::path(VMSIM_SOURCE_DIR) / "parts" / "machines" / "xyzac_trt.toml";
  std::ofstream(tmp.path() / "job.toml")
      << "[job]\nmachine = \"" << machine.string() << "\"\nprogram = \"boat_part.ngc\"\ntool_table = \""
      << (kData / "tooltables" / "xyzac-trt.tbl").string()
      << "\"\nno_motion_mcodes = [428, 429]\ntcp = true\n[tool]\ntype = \"flat\"\ndiameter_mm = 10.0\n"
         "flute_length_mm = 25.0\nlength_mm = 50.0\n[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n";
  const fs::path out = tmp.path() / "out";
  const std::string cmd = std::string("'") + VMSIM_EXE + "' motion '" + (tmp.path() / "job.toml").string() +
                          "' --out '" + out.string() + "' >'" + (tmp.path() / "stdout.txt").string() + "' 2>'" +
                          (tmp.path() / "stderr.txt").string() + "'";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(tmp.path() / "stderr.txt");
  const nlohmann::json r = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_TRUE(r["limits_held"]["setpoints_velocity_acceleration_jerk"].get<bool>());
  EXPECT_TRUE(r["limits_held"]["currents"].get<bool>());

  // The drives of parts/machines/xyzac_trt.toml: Kv 6 (m/min)/mm or (1000 deg/min)/deg = 100 1/s and KF 0.1 on all
  // five axes; one Te of delay in the position path.
  struct Drive {
    const char* axis;
    const char* unit;
    double kv_per_s, kf;
  };
  const double te = 1e-3;
  for (const Drive& d : {Drive{"X", "mm", 100.0, 0.1}, Drive{"Y", "mm", 100.0, 0.1}, Drive{"Z", "mm", 100.0, 0.1},
                         Drive{"A", "deg", 100.0, 0.1}, Drive{"C", "deg", 100.0, 0.1}}) {
    SCOPED_TRACE(d.axis);
    const nlohmann::json& a = r["axes"][d.axis];
    const std::string u = d.unit;
    EXPECT_TRUE(a["setpoints_within_limits"].get<bool>());
    const double v = a["setpoint_peaks"]["velocity_" + u + "_per_s"].get<double>();
    const double ref = v * ((1 - d.kf) / d.kv_per_s + te);
    const double e = a["tracking_error_max_" + u].get<double>();
    EXPECT_GT(v, 0.0);
    EXPECT_LE(e, 1.02 * ref) << "tracking error " << e << " " << u << ", v((1-KF)/Kv + Te) = " << ref;
    EXPECT_GE(e, 0.9 * ref) << "tracking error " << e << " " << u << ", v((1-KF)/Kv + Te) = " << ref;
    std::printf("%s: peak setpoint speed %.3f %s/s, max tracking error %.5f %s (v((1-KF)/Kv + Te) = %.5f)\n", d.axis, v,
                d.unit, e, d.unit, ref);
  }
  // The tip's contour error in the workpiece frame: the table turns only in rapids here, so it comes from the linear
  // axes' following errors (at most |(eX, eY, eZ)|) and the turns' (the tip within 150 mm of both rotary axes).
  const double ce = r["contour_error"]["all_moves"]["max_abs_mm"].get<double>();
  double bound = 0;
  for (const char* ax : {"X", "Y", "Z"}) bound += std::pow(r["axes"][ax]["tracking_error_max_mm"].get<double>(), 2);
  bound = std::sqrt(bound);
  for (const char* ax : {"A", "C"}) bound += 150.0 * r["axes"][ax]["tracking_error_max_deg"].get<double>() * M_PI / 180;
  EXPECT_GT(ce, 0.0);
  EXPECT_LE(ce, bound);
  std::printf("cycle %.2f s, tip contour error max %.1f um (all moves), %.1f um (cutting moves)\n",
              r["interpolation"]["cycle_time_s"].get<double>(), ce * 1e3,
              r["contour_error"]["cutting_moves"]["max_abs_mm"].get<double>() * 1e3);
}

}  // namespace
