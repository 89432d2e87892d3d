// The actual motion streamed in blocks (sim/motion_stream.hpp, issue 21) against the same run held whole. Reference:
// the whole-response functions main ran before the streaming (simulate_motion, add_contour_error, track_of,
// motion_signals, axis_following_json, Chain::simulate's drive checks), bit for bit, at blocks of 1, 7 and 65 536
// rows and with one and two threads; and Eigen's own sum for the summation order.
#include "sim/motion_stream.hpp"

#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "sim/axis_following.hpp"
#include "sim/chain.hpp"
#include "sim/pipeline.hpp"
#include "sim/signals.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cstring>
#include <random>

using namespace vmsim;

namespace {

// Bit for bit, NaN included (the signals' bins hold NaN where a signal is undefined).
template <class A>
bool same_bits(const A& a, const A& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<std::size_t>(a.size())) == 0;
}

// Reference: Eigen's ArrayXd::sum() (the reduction a whole array's RMS would use), for every length up to 70 (every
// remainder of the packets' groups) and a long one, on positive values (squares) and signed ones.
TEST(EigenOrderSum, EqualsEigensSumBitForBit) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const bool squares : {true, false}) {
    for (Eigen::Index n = 1; n <= 70; ++n) {
      Eigen::ArrayXd x(n);
      for (Eigen::Index k = 0; k < n; ++k) x[k] = squares ? std::pow(u(rng), 2) * 1e-6 : u(rng) * std::exp(8 * u(rng));
      sim::EigenOrderSum s;
      for (Eigen::Index k = 0; k < n; ++k) s.add(x[k]);
      const double eigen = x.sum();
      EXPECT_EQ(s.sum(), eigen) << "n = " << n;
      EXPECT_EQ(s.count(), n);
    }
  }
  Eigen::ArrayXd x(1000003);
  for (Eigen::Index k = 0; k < x.size(); ++k) x[k] = u(rng) * std::exp(20 * u(rng));
  sim::EigenOrderSum s;
  for (Eigen::Index k = 0; k < x.size(); ++k) s.add(x[k]);
  EXPECT_EQ(s.sum(), x.sum());
  // And not merely a plain left-to-right sum, which differs on such data (else the test would prove nothing).
  double plain = 0;
  for (Eigen::Index k = 0; k < x.size(); ++k) plain += x[k];
  EXPECT_NE(plain, x.sum());
}

struct Whole {
  sim::Motion m;
  removal::PoseTrack track;
  sim::BinnedSignals signals;
  nlohmann::json following;
};

Whole whole_run(const core::Job& job) {
  Whole w;
  const sim::Chain chain(job);
  w.m = sim::simulate_motion(chain, core::RemovalSpec::Motion::Actual, core::no_progress());
  sim::add_contour_error(w.m, job);
  w.track = sim::track_of(w.m, job, core::RemovalSpec::Motion::Actual);
  w.signals = sim::motion_signals(job, w.m.program, w.m.interp.setpoints, *w.m.response, *w.m.contour);
  const auto kin = motion::make_kinematics(job.machine);
  w.following = sim::axis_following_json(job.machine, w.m.interp.setpoints, w.m.response->position, kin.get(),
                                         [&](Eigen::Index k) { return sim::tlo_at(w.m, k); });
  return w;
}

void expect_streamed_equals_whole(const std::string& job_file, const std::vector<Eigen::Index>& blocks,
                                  const std::vector<int>& thread_counts, bool turning) {
  const core::Job job = core::load_job(std::string(VMSIM_SOURCE_DIR) + "/" + job_file);
  const Whole w = whole_run(job);
  ASSERT_GT(w.m.interp.setpoints.samples(), 1000);
  ASSERT_EQ(w.track.axis_per_sample.rows() > 0, turning);
  const int saved = omp_get_max_threads();
  for (const Eigen::Index block : blocks) {
    for (const int threads : thread_counts) {
      SCOPED_TRACE(job_file + ", block " + std::to_string(block) + ", threads " + std::to_string(threads));
      omp_set_num_threads(threads);
      const sim::Chain chain(job);
      sim::Motion m;
      sim::StreamOptions o;
      o.block_rows = block;
      sim::MotionStream s = sim::stream_actual_motion(chain, m, o, core::no_progress());
      const removal::PoseTrack& t = s.track;
      EXPECT_TRUE(same_bits(t.tip_mm, w.track.tip_mm));
      EXPECT_TRUE(same_bits(t.tip_velocity_mm_per_s, w.track.tip_velocity_mm_per_s));
      EXPECT_TRUE(same_bits(t.axis_per_sample, w.track.axis_per_sample));
      EXPECT_EQ(t.axis, w.track.axis);
      EXPECT_EQ(t.tool, w.track.tool);
      sim::finish_streamed_motion(m, s, t.tip_mm);
      ASSERT_TRUE(m.contour && m.signals && m.response);
      EXPECT_TRUE(same_bits(m.contour->signed_mm, w.m.contour->signed_mm));
      EXPECT_TRUE((m.contour->foot_segment == w.m.contour->foot_segment).all());
      EXPECT_EQ(m.contour->rms_mm, w.m.contour->rms_mm);
      EXPECT_EQ(m.signals->names, w.signals.names);
      EXPECT_EQ(m.signals->bin_samples, w.signals.bin_samples);
      EXPECT_EQ(m.signals->samples, w.signals.samples);
      EXPECT_EQ(m.signals->limits, w.signals.limits);
      EXPECT_TRUE(same_bits(m.signals->min, w.signals.min));
      EXPECT_TRUE(same_bits(m.signals->max, w.signals.max));
      EXPECT_EQ(m.axis_following, w.following);
      EXPECT_EQ(m.drive_checks.axes, w.m.drive_checks.axes);
      EXPECT_EQ(m.drive_checks.warnings.size(), w.m.drive_checks.warnings.size());
      // What stays of the setpoints: their count and moves (the statistics per move), not their positions.
      EXPECT_EQ(m.interp.setpoints.samples(), w.m.interp.setpoints.samples());
      EXPECT_TRUE((m.interp.setpoints.move_index == w.m.interp.setpoints.move_index).all());
      EXPECT_EQ(m.interp.setpoints.position.cols(), 0);
      EXPECT_EQ(m.response->samples(), 0);
      for (Eigen::Index k : {Eigen::Index{0}, w.m.interp.setpoints.samples() / 2, w.m.response->samples() - 1})
        EXPECT_EQ(sim::tlo_at(m, k), sim::tlo_at(w.m, k));
    }
  }
  omp_set_num_threads(saved);
}

TEST(MotionStream, ThreeAxisPartEqualsTheWholeRun) {
  expect_streamed_equals_whole("parts/plane_cylinder/job_fast.toml", {1, 7, 65536}, {1, 2}, false);
}

// A turning tool axis (the track's axis per row) and rotary drives.
TEST(MotionStream, FiveAxisPartEqualsTheWholeRun) {
  expect_streamed_equals_whole("parts/five_axis/job.toml", {7, 65536}, {2}, true);
}

}  // namespace
