// signals.csv: binning keeps every bin's extremes (so the peaks of the full-rate signals survive, sample for sample),
// the file round-trips, and bad files are errors naming the line. Reference: the same signals unbinned (one sample
// per bin) on the plane-cylinder fast pass.
#include "sim/job_program.hpp"
#include "sim/signals.hpp"

#include "motion/contour.hpp"
#include "core/error.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"
#include "drives/simulate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

using namespace vmsim;

namespace {

struct FastPass {
  core::Job job;
  core::ToolPath program;
  motion::InterpResult interp;
  drives::AxisResponse response;
  motion::ContourError contour;
};

const FastPass& fast_pass() {
  static const FastPass f = [] {
    FastPass p;
    p.job = core::load_job(std::string(VMSIM_SOURCE_DIR) + "/parts/plane_cylinder/job_fast.toml");
    p.program = sim::read_job_program(p.job);
    motion::InterpOptions o;
    o.period_s = p.job.interp.period_s;
    o.tolerance_mm = p.job.interp.tolerance_mm;
    p.interp = motion::interpolate(motion::toolpath_in_axis_space(p.program, p.job.machine), p.job.machine, o);
    p.response = drives::simulate_axes(p.interp.setpoints, p.job.machine);
    const auto kin = motion::make_kinematics(p.job.machine);
    const core::Setpoints& sp = p.interp.setpoints;
    Eigen::MatrixXd cmd(p.response.samples(), 3), act(p.response.samples(), 3);
    for (Eigen::Index k = 0; k < cmd.rows(); ++k) {
      const int mi = sp.move_index[std::min(k, sp.samples() - 1)];
      const double tlo = mi >= 0 ? p.program.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
      cmd.row(k) = kin->forward(sp.position.row(std::min(k, sp.samples() - 1)).transpose(), tlo).tip_mm.transpose();
      act.row(k) = kin->forward(p.response.position.row(k).transpose(), tlo).tip_mm.transpose();
    }
    p.contour = motion::contour_error(cmd, act);
    return p;
  }();
  return f;
}

sim::BinnedSignals signals(Eigen::Index max_bins) {
  const FastPass& f = fast_pass();
  return sim::motion_signals(f.job, f.program, f.interp.setpoints, f.response, f.contour, 1.0, max_bins);
}

std::filesystem::path temp_file(const std::string& name) {
  std::random_device rd;
  return std::filesystem::temp_directory_path() / ("vmsim_signals_" + std::to_string(rd()) + "_" + name);
}

}  // namespace

TEST(Signals, BinsKeepEveryExtremeOfTheFullRateSignals) {
  const sim::BinnedSignals full = signals(1'000'000'000);  // one sample per bin
  const sim::BinnedSignals bin = signals(100);
  ASSERT_EQ(full.bin_samples, 1);
  ASSERT_EQ(full.samples, bin.samples);
  ASSERT_LE(bin.bins(), 100);
  ASSERT_GT(bin.bin_samples, 1);
  ASSERT_EQ(full.names, bin.names);
  EXPECT_EQ(bin.bins(), (bin.samples + bin.bin_samples - 1) / bin.bin_samples);
  for (std::size_t c = 0; c < full.names.size(); ++c) {
    const auto ci = static_cast<Eigen::Index>(c);
    for (Eigen::Index b = 0; b < bin.bins(); ++b) {
      const Eigen::Index k0 = b * bin.bin_samples, k1 = std::min(full.samples, k0 + bin.bin_samples);
      double lo = NAN, hi = NAN;
      for (Eigen::Index k = k0; k < k1; ++k) {
        const double v = full.min(k, ci);
        if (std::isnan(v)) continue;
        lo = std::isnan(lo) ? v : std::min(lo, v);
        hi = std::isnan(hi) ? v : std::max(hi, v);
      }
      if (std::isnan(lo)) {
        EXPECT_TRUE(std::isnan(bin.min(b, ci))) << full.names[c] << " bin " << b;
      } else {
        EXPECT_EQ(bin.min(b, ci), lo) << full.names[c] << " bin " << b;
        EXPECT_EQ(bin.max(b, ci), hi) << full.names[c] << " bin " << b;
      }
    }
  }
  // The contour error's peak over cutting moves is the one `vmsim motion` reports (the same samples).
  const int ce = bin.find("contour_error_mm");
  ASSERT_GE(ce, 0);
  const double peak = std::max(-bin.min.col(ce).isNaN().select(0, bin.min.col(ce)).minCoeff(),
                               bin.max.col(ce).isNaN().select(0, bin.max.col(ce)).maxCoeff());
  EXPECT_GT(peak, 0.005);
  EXPECT_LT(peak, 0.05);
}

TEST(Signals, AxesLimitsAndDerivedSignals) {
  const sim::BinnedSignals s = signals(10000);
  ASSERT_EQ(s.axes.size(), 2u);  // the fast pass moves X and Z
  EXPECT_EQ(s.axes[0].first, "X");
  EXPECT_EQ(s.axes[1].first, "Z");
  EXPECT_EQ(s.held_axes, (std::vector<std::string>{"Y", "A", "C"}));
  // Mikron UCP 710 X axis (Duong et al. Table I): 30 m/min, 2.5 m/s^2, 10 m/s^3.
  EXPECT_DOUBLE_EQ(*s.limit("X_velocity_mm_per_s"), 500.0);
  EXPECT_DOUBLE_EQ(*s.limit("X_acceleration_mm_per_s2"), 2500.0);
  EXPECT_DOUBLE_EQ(*s.limit("X_jerk_mm_per_s3"), 10000.0);
  EXPECT_TRUE(s.limit("X_current_A").has_value());
  // The interpolator keeps every limit: the setpoints' differences stay within them.
  for (const char* q : {"velocity", "acceleration", "jerk"}) {
    const std::string suffix = std::string(q) == "velocity"       ? "_per_s"
                               : std::string(q) == "acceleration" ? "_per_s2"
                                                                  : "_per_s3";
    const int i = s.find(std::string("X_") + q + "_setpoint_mm" + suffix);
    ASSERT_GE(i, 0) << q;
    const double lim = *s.limit(std::string("X_") + q + "_mm" + suffix);
    EXPECT_LE(s.max.col(i).maxCoeff(), lim * (1 + 1e-6)) << q;
    EXPECT_GE(s.min.col(i).minCoeff(), -lim * (1 + 1e-6)) << q;
  }
  // The programmed feed is the job's 10 m/min on the cutting moves, undefined on rapids.
  const int f = s.find("feed_programmed_mm_per_min");
  ASSERT_GE(f, 0);
  EXPECT_DOUBLE_EQ(s.max.col(f).isNaN().select(0, s.max.col(f)).maxCoeff(), 10000.0);
  EXPECT_TRUE(s.max.col(f).isNaN().any());
  // The cutting path grows monotonically to the length of the cutting moves.
  const int cp = s.find("cutting_path_mm");
  for (Eigen::Index b = 1; b < s.bins(); ++b) EXPECT_GE(s.min(b, cp), s.max(b - 1, cp) - 1e-12);
  EXPECT_GT(s.max(s.bins() - 1, cp), 100.0);
}

TEST(Signals, FileRoundTripAndErrors) {
  const sim::BinnedSignals s = signals(500);
  const auto file = temp_file("a.csv");
  sim::write_signals(file, s);
  const sim::BinnedSignals r = sim::read_signals(file);
  EXPECT_EQ(r.job, s.job);
  EXPECT_EQ(r.samples, s.samples);
  EXPECT_EQ(r.bin_samples, s.bin_samples);
  EXPECT_EQ(r.names, s.names);
  EXPECT_EQ(r.axes, s.axes);
  EXPECT_EQ(r.held_axes, s.held_axes);
  EXPECT_EQ(r.limits.size(), s.limits.size());
  ASSERT_EQ(r.bins(), s.bins());
  for (Eigen::Index b = 0; b < s.bins(); ++b)
    for (Eigen::Index c = 0; c < static_cast<Eigen::Index>(s.names.size()); ++c) {
      const double a = s.max(b, c), v = r.max(b, c);
      if (std::isnan(a))
        EXPECT_TRUE(std::isnan(v));
      else
        EXPECT_NEAR(v, a, 1e-6 * std::max(1.0, std::abs(a)));  // 7 significant digits in the file
    }
  std::filesystem::remove(file);

  auto bad = [&](const std::string& text, const std::string& expect) {
    const auto f = temp_file("bad.csv");
    std::ofstream(f) << text;
    try {
      sim::read_signals(f);
      ADD_FAILURE() << "no error for: " << text;
    } catch (const core::Error& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
    }
    std::filesystem::remove(f);
  };
  bad("t_s.min,t_s.max\n0,1\n", "not a vmsim signals file");
  bad("# vmsim signals 1\n# period_s=0.001\nt_s.min,t_s.max\n0,1,2\n",
      ":4: 3 cells, the header (line 3) names 2 columns");
  bad("# vmsim signals 1\n# period_s=0.001\nt_s.min,x.max\n", ":3: expected NAME.min,NAME.max");
  bad("# vmsim signals 1\n# period_s=0.001\nt_s.min,t_s.max\n0,abc\n",
      ":4: column 2 't_s.max': 'abc' is not a finite number (nor nan)");
  bad("# vmsim signals 1\n# period_s=fast\n", ":2: expected a number for period_s");
  EXPECT_THROW(sim::read_signals(temp_file("missing.csv")), core::Error);
}
