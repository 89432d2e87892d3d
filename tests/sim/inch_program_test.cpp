// A G20 (inch) program in a mm job follows the same path in the same time as the same program in mm (issue 18). The
// inch program is the corner part's fast pass converted here as a CAM post-processor writes it: every length word to
// 4 decimals of inch, feeds to 1 decimal, G21 -> G20. Its first point then lies 1.7 um from the job's start_mm (a
// tiny move that, with the kink it leaves, was blended as a full corner: 5.37 s and 5 blends instead of 4.56 s and 4).
// Reference: the part's own mm program, parts/corner/corner_fast.ngc, through the same chain.
#include "core/job.hpp"
#include "drives/simulate.hpp"
#include "motion/contour.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>
#include <string>

using namespace vmsim;
namespace fs = std::filesystem;

namespace {

const std::string kCorner = std::string(VMSIM_SOURCE_DIR) + "/parts/corner/";

// The program with every length word in inches to 4 decimals (feeds to 1), G21 -> G20; comments kept.
std::string to_inches(const std::string& mm) {
  std::istringstream in(mm);
  std::string line, out;
  const std::regex word("([XYZIJKRF])(-?[0-9.]+)");
  while (std::getline(in, line)) {
    const std::size_t c = line.find('(');
    std::string code = line.substr(0, c), rest = c == std::string::npos ? "" : line.substr(c);
    std::string conv;
    std::sregex_iterator it(code.begin(), code.end(), word), end;
    std::size_t last = 0;
    for (; it != end; ++it) {
      conv += code.substr(last, static_cast<std::size_t>(it->position()) - last);
      const double v = std::stod((*it)[2]) / 25.4;
      char buf[64];
      std::snprintf(buf, sizeof buf, (*it)[1] == "F" ? "%s%.1f" : "%s%.4f", (*it)[1].str().c_str(), v);
      conv += buf;
      last = static_cast<std::size_t>(it->position() + it->length());
    }
    conv += code.substr(last);
    out += std::regex_replace(conv, std::regex("G21"), "G20") + rest + "\n";
  }
  return out;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The X Y Z columns of a samples x machine-axes matrix.
Eigen::MatrixXd xyz_columns(const Eigen::MatrixXd& m, const std::vector<std::string>& names) {
  Eigen::MatrixXd out(m.rows(), 3);
  for (int c = 0; c < 3; ++c) {
    const auto it = std::find(names.begin(), names.end(), std::string(1, "XYZ"[c]));
    EXPECT_NE(it, names.end());
    out.col(c) = m.col(it - names.begin());
  }
  return out;
}

struct JobRun {
  motion::InterpResult interp;
  Eigen::MatrixXd command, actual;  // X Y Z
};

JobRun run_job(const fs::path& job_file) {
  const core::Job job = core::load_job(job_file);
  const sim::Chain chain(job);
  JobRun r;
  r.interp = chain.interpolate(sim::read_job_program(job));
  const drives::AxisResponse resp = chain.simulate(r.interp.setpoints);
  r.command = xyz_columns(r.interp.setpoints.position, r.interp.setpoints.axis_names);
  r.actual = xyz_columns(resp.position, resp.axis_names);
  return r;
}

TEST(InchProgram, FollowsTheSamePathInTheSameTimeAsInMm) {
  std::random_device rd;
  const fs::path dir = fs::temp_directory_path() / ("vmsim_inch_" + std::to_string(rd()));
  fs::create_directories(dir);
  const std::string inch = to_inches(slurp(kCorner + "corner_fast.ngc"));
  ASSERT_NE(inch.find("G20"), std::string::npos);
  ASSERT_NE(inch.find("X0.1969 Y-2.9528"), std::string::npos) << inch;  // 5.00126, -75.00112 mm: off the start
  std::ofstream(dir / "corner_in.ngc") << inch;
  std::string job = slurp(kCorner + "job_fast.toml");
  job = std::regex_replace(job, std::regex("\"corner_fast.ngc\""), "\"corner_in.ngc\"");
  job = std::regex_replace(job, std::regex("\"\\.\\./machines/"),
                           "\"" + std::string(VMSIM_SOURCE_DIR) + "/parts/machines/");
  job = std::regex_replace(job, std::regex("\"tools.tbl\""), "\"" + kCorner + "tools.tbl\"");
  job = std::regex_replace(job, std::regex("\"job_reference.toml\""), "\"" + kCorner + "job_reference.toml\"");
  job = std::regex_replace(job, std::regex("\"corner_needles.csv\""), "\"" + kCorner + "corner_needles.csv\"");
  std::ofstream(dir / "job.toml") << job;

  const JobRun mm = run_job(kCorner + "job_fast.toml");
  const JobRun in = run_job(dir / "job.toml");
  fs::remove_all(dir);
  const double te = mm.interp.setpoints.period_s;
  std::printf("cycle time: mm %.4f s, inch %.4f s; blends %d / %d; stops %d / %d\n", mm.interp.stats.cycle_time_s,
              in.interp.stats.cycle_time_s, mm.interp.stats.blends, in.interp.stats.blends, mm.interp.stats.exact_stops,
              in.interp.stats.exact_stops);
  // The same cycle time to within one setpoint period, the same corners.
  EXPECT_LE(std::abs(in.interp.stats.cycle_time_s - mm.interp.stats.cycle_time_s), te);
  EXPECT_EQ(in.interp.stats.blends, mm.interp.stats.blends);
  EXPECT_EQ(in.interp.stats.exact_stops, mm.interp.stats.exact_stops);

  // The same path: every inch setpoint lies within the rounding of 4 decimals of inch (half a last digit on each
  // coordinate: sqrt(3) x 1.27 um) of the mm program's setpoint polyline near the same time.
  const double rounding_mm = std::sqrt(3.0) * 0.5e-4 * 25.4;
  double worst = 0;
  const Eigen::MatrixXd& a = in.command;
  const Eigen::MatrixXd& b = mm.command;
  for (Eigen::Index k = 0; k < a.rows(); ++k) {
    double best = INFINITY;
    const Eigen::Index lo = std::max<Eigen::Index>(0, k - 20), hi = std::min<Eigen::Index>(b.rows() - 1, k + 20);
    for (Eigen::Index j = lo; j < hi; ++j) {
      const Eigen::Vector3d p = a.row(k).transpose(), s0 = b.row(j).transpose(), d = b.row(j + 1).transpose() - s0;
      const double t = d.squaredNorm() > 0 ? std::clamp((p - s0).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
      best = std::min(best, (p - s0 - t * d).norm());
    }
    worst = std::max(worst, best);
  }
  std::printf("largest distance of an inch setpoint from the mm setpoints: %.3f um (rounding %.3f um)\n", worst * 1e3,
              rounding_mm * 1e3);
  EXPECT_LE(worst, rounding_mm);

  // And the drives follow it alike: the contour error's largest value within 0.1 um of the mm program's.
  const motion::ContourError cmm = motion::contour_error(mm.command, mm.actual);
  const motion::ContourError cin = motion::contour_error(in.command, in.actual);
  std::printf("contour error max: mm %.4f um, inch %.4f um\n", cmm.max_abs_mm * 1e3, cin.max_abs_mm * 1e3);
  EXPECT_NEAR(cin.max_abs_mm, cmm.max_abs_mm, 1e-4);
}

}  // namespace
