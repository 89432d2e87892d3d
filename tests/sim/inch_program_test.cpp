// A G20 (inch) program in a mm job follows the same path in the same time as the same program in mm (issue 18: the
// corner part's pass in inches, its coordinates rounded to 5 decimals, starts 0.1 um from the job's start_mm; that
// rounding move was a corner of its own, crawled through for 0.8 s with a 17 um excursion). Reference: the part's own
// mm program, parts/corner/corner_fast.ngc, through the same chain.
#include "core/job.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"

#include <gtest/gtest.h>

#include <cmath>
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

// The program with every length word in inches to 5 decimals (feeds to 3), G21 -> G20.
std::string to_inches(const std::string& mm) {
  std::istringstream in(mm);
  std::string line, out;
  const std::regex word("([XYZIJKRF])(-?[0-9.]+)");
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '(') {
      out += line + "\n";
      continue;
    }
    const std::size_t c = line.find('(');
    std::string code = line.substr(0, c), rest = c == std::string::npos ? "" : line.substr(c);
    std::string conv;
    std::sregex_iterator it(code.begin(), code.end(), word), end;
    std::size_t last = 0;
    for (; it != end; ++it) {
      conv += code.substr(last, static_cast<std::size_t>(it->position()) - last);
      const double v = std::stod((*it)[2]) / 25.4;
      char buf[64];
      std::snprintf(buf, sizeof buf, (*it)[1] == "F" ? "%s%.3f" : "%s%.5f", (*it)[1].str().c_str(), v);
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

TEST(InchProgram, FollowsTheSamePathInTheSameTimeAsInMm) {
  std::random_device rd;
  const fs::path dir = fs::temp_directory_path() / ("vmsim_inch_" + std::to_string(rd()));
  fs::create_directories(dir);
  const std::string inch = to_inches(slurp(kCorner + "corner_fast.ngc"));
  ASSERT_NE(inch.find("G20"), std::string::npos);
  std::ofstream(dir / "corner_in.ngc") << inch;
  std::string job = slurp(kCorner + "job_fast.toml");
  job = std::regex_replace(job, std::regex("\"corner_fast.ngc\""), "\"corner_in.ngc\"");
  job = std::regex_replace(job, std::regex("\"\\.\\./machines/"), "\"" + std::string(VMSIM_SOURCE_DIR) + "/parts/machines/");
  job = std::regex_replace(job, std::regex("\"tools.tbl\""), "\"" + kCorner + "tools.tbl\"");
  job = std::regex_replace(job, std::regex("\"job_reference.toml\""), "\"" + kCorner + "job_reference.toml\"");
  job = std::regex_replace(job, std::regex("\"corner_needles.csv\""), "\"" + kCorner + "corner_needles.csv\"");
  std::ofstream(dir / "job.toml") << job;

  const core::Job jmm = core::load_job(kCorner + "job_fast.toml"), jin = core::load_job(dir / "job.toml");
  const sim::Chain cmm(jmm), cin(jin);
  const motion::InterpResult rmm = cmm.interpolate(sim::read_job_program(jmm));
  const motion::InterpResult rin = cin.interpolate(sim::read_job_program(jin));
  fs::remove_all(dir);
  // The same cycle time to within a period.
  EXPECT_NEAR(rin.stats.cycle_time_s, rmm.stats.cycle_time_s, 1.5e-3);
  EXPECT_EQ(rin.stats.blends, rmm.stats.blends);
  // Every inch setpoint within 1 um of the mm program's setpoint polyline (searched around the same time).
  const Eigen::MatrixXd& a = rin.setpoints.position;
  const Eigen::MatrixXd& b = rmm.setpoints.position;
  double worst = 0;
  for (Eigen::Index k = 0; k < a.rows(); ++k) {
    double best = INFINITY;
    const Eigen::Index lo = std::max<Eigen::Index>(0, k - 20), hi = std::min<Eigen::Index>(b.rows() - 1, k + 20);
    for (Eigen::Index j = lo; j < hi; ++j) {
      const Eigen::VectorXd p = a.row(k).transpose(), s0 = b.row(j).transpose(), d = b.row(j + 1).transpose() - s0;
      const double t = d.squaredNorm() > 0 ? std::clamp((p - s0).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
      best = std::min(best, (p - s0 - t * d).norm());
    }
    worst = std::max(worst, best);
  }
  EXPECT_LT(worst, 1e-3) << "mm";
}

}  // namespace
