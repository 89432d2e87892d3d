// A whole run (sim::run_job) whose deviation has an analytic answer: a plane of slope 0, 30, 60 and 80 deg milled up
// its slope by a ball of radius R, measured against the part the same tool centres leave with a ball of radius
// R - d. The material a ball removes is the smaller ball's grown by d (a Minkowski sum), so the part is the
// reference moved d along its normal into the material: the normal deviation is -d whatever the slope, the vertical
// one -d / cos(slope), and the marks say so (depth along the normal, the vertical depth, the slope, steep beyond 60).
#include "tests/app/cli_util.hpp"
#include "core/job.hpp"
#include "metrology/marks.hpp"
#include "sim/run.hpp"
#include "tests/test_paths.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace fs = std::filesystem;
using namespace vmsim;
using vmsim_test::TempDir;  // tests/app/cli_util.hpp

namespace {
using vmsim::core::units::kPi;
using vmsim::test::kPartsDir;

// Passes up the slope (along +x) every `step` mm in y, the tool tip `lift` above the ball of radius R's.
void write_program(const fs::path& file, double slope_rad, double R, double lift) {
  std::ofstream p(file);
  p << "G21 G90 G94 G17\n";
  const double t = std::tan(slope_rad), c = std::cos(slope_rad);
  auto tip = [&](double x) { return x * t + R / c - R + lift; };  // ball centre R/cos above the plane z = x tan
  const double step = 0.02;
  for (int k = 0; k <= 100; ++k) {
    const double y = -0.5 + k * step;
    p << fmt::format("G0 X-4 Y{:.4f} Z120\nG1 X-4 Z{:.6f} F1000\nG1 X12 Z{:.6f}\nG0 Z120\n", y, tip(-4), tip(12));
  }
  p << "M30\n";
}

void write_job(const fs::path& file, const std::string& name, const std::string& program, double diameter,
               const std::string& reference) {
  std::ofstream(file) << "[job]\nname = \"" << name << "\"\nmachine = \"" << kPartsDir
                      << "machines/mikron_ucp710.toml\"\nprogram = \"" << program
                      << "\"\nstart_mm = [-4.0, -0.5, 120.0]\n\n[tool]\ntype = \"ball\"\ndiameter_mm = " << diameter
                      << "\nflute_length_mm = 100.0\nlength_mm = 100.0\n\n[stock]\ntype = \"box\"\n"
                      << "min_mm = [0.0, 0.0, -2.0]\nmax_mm = [8.0, 1.0, 48.0]\n\n[removal]\nfield = \"zmap\"\n"
                      << "spacing_mm = 0.01\nmotion = \"program\"\n\n[reference]\n"
                      << reference << "\n";
}
}  // namespace

TEST(NormalMarks, BallMilledTiltedPlaneAgainstTheSmallerBallsPartIsTheOffsetAlongTheNormal) {
  const double R = 3.0, d = 0.01;
  for (const double deg : {0.0, 30.0, 60.0, 80.0}) {
    const double th = deg * kPi / 180;
    TempDir tmp("vmsim_normal_marks_");
    write_program(tmp.path() / "cut.ngc", th, R, 0.0);
    write_program(tmp.path() / "ref.ngc", th, R, d);  // the smaller ball's tip d higher: the same centres
    write_job(tmp.path() / "ref.toml", "ref", "ref.ngc", 2 * (R - d), "kind = \"none\"");
    write_job(tmp.path() / "cut.toml", "cut", "cut.ngc", 2 * R, "kind = \"job\"\njob = \"ref.toml\"");
    const sim::RunResult r = sim::run_job(core::load_job(tmp.path() / "cut.toml"));
    ASSERT_TRUE(r.deviation && r.deviation_vertical) << deg;
    const core::HeightGrid& n = *r.deviation;
    const core::HeightGrid& v = *r.deviation_vertical;
    // Away from the passes' ends and the stock's edges (more than R): scallops 0.02^2 / 8R = 17 nm deep, and the
    // reference's gradient at their cusps is that of a kinked surface (0.02 / R rad): 2 % of d allowed for it.
    int checked = 0;
    double worst_n = 0, worst_v = 0;
    for (Eigen::Index j = 0; j < n.ny(); ++j)
      for (Eigen::Index i = 0; i < n.nx(); ++i) {
        if (n.x(i) < 3.5 || n.x(i) > 4.5 || n.y(j) < 0.3 || n.y(j) > 0.7) continue;
        EXPECT_NEAR(n.z_mm(j, i), -d, 0.02 * d) << deg << " deg at x " << n.x(i) << " y " << n.y(j);
        EXPECT_NEAR(v.z_mm(j, i), -d / std::cos(th), 0.02 * d / std::cos(th)) << deg << " deg";
        worst_n = std::max(worst_n, std::abs(n.z_mm(j, i) + d));
        worst_v = std::max(worst_v, std::abs(v.z_mm(j, i) + d / std::cos(th)));
        ++checked;
      }
    std::printf(
        "[ normal   ] %2.0f deg: %d nodes, normal deviation -d within %.3g um, vertical -d/cos within %.3g um\n", deg,
        checked, worst_n * 1e3, worst_v * 1e3);
    EXPECT_GT(checked, 3000) << deg;
    ASSERT_FALSE(r.marks.empty()) << deg;
    const nlohmann::json& m = r.report["marks"][0];
    EXPECT_NEAR(m["depth_mm"].get<double>(), d, 0.05 * d) << deg;
    EXPECT_NEAR(m["depth_vertical_mm"].get<double>(), d / std::cos(th), 0.05 * d / std::cos(th)) << deg;
    EXPECT_NEAR(m["slope_deg"].get<double>(), deg, 1.0) << deg;
    EXPECT_EQ(m["steep_wall"].get<bool>(), deg > metrology::kSteepWallSlopeDeg) << deg;
    EXPECT_EQ(r.report["surface"]["deviation_along"], "normal");
  }
}
