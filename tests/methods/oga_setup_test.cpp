// OGA's set-up from a job's motion (methods/oga.hpp): the rows that count in MSE(CE) and the Kp ranges of the
// adjusted axes. References: the program written here (which moves are rapids, which axes move) and the setpoints'
// move indices (the interpolator's bookkeeping).
#include "core/machine.hpp"
#include "methods/oga.hpp"
#include "motion/interp.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

using namespace vmsim;
namespace fs = std::filesystem;

namespace {

struct Motion {
  core::ToolPath program;
  core::Setpoints sp;
};

// A rapid approach, a feed move in X, an arc in XZ (G18), a rapid retract; on the Mikron UCP 710.
Motion motion_of(const core::Machine& m) {
  std::random_device rd;
  const fs::path p = fs::temp_directory_path() / ("vmsim_oga_setup_" + std::to_string(rd()) + ".ngc");
  std::ofstream(p) << "G21 G90 G94 G18\nG0 X0 Y0 Z5\nG1 Z0 F3000\nG1 X10\nG2 X20 Z0 I5 K0\nG0 Z5\nM30\n";
  Motion mo;
  mo.program = program::read_program(p);
  fs::remove(p);
  mo.sp = motion::interpolate(motion::toolpath_in_axis_space(mo.program, m), m, motion::InterpOptions{}).setpoints;
  return mo;
}

}  // namespace

TEST(OgaSetup, RowWeightsCountTheFeedMovesAndTheSettlingRows) {
  const core::Machine m = core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml");
  const Motion mo = motion_of(m);
  const core::Setpoints& sp = mo.sp;
  const Eigen::Index ns = sp.samples();
  ASSERT_EQ(mo.program.moves.size(), 5u);
  EXPECT_TRUE(mo.program.moves[0].rapid);
  EXPECT_TRUE(mo.program.moves[4].rapid);
  const Eigen::ArrayXd w = methods::feed_move_row_weights(sp, mo.program, 0.2);
  ASSERT_EQ(w.size(), ns + 200);  // 0.2 s of settling at Te = 1 ms
  Eigen::Index feed_rows = 0;
  for (Eigen::Index k = 0; k < ns; ++k) {
    const int mi = sp.move_index[k];
    const bool feed = mi >= 1 && mi <= 3;
    EXPECT_EQ(w[k], feed ? 1.0 : 0.0) << k;
    feed_rows += feed;
  }
  EXPECT_GT(feed_rows, 0);
  EXPECT_EQ(w.sum(), static_cast<double>(feed_rows));  // the settling rows take the last move, a rapid: weight 0
  // A program that ends on a feed move: its settling rows count.
  core::ToolPath no_retract = mo.program;
  no_retract.moves[4].rapid = false;
  const Eigen::ArrayXd w2 = methods::feed_move_row_weights(sp, no_retract, 0.05);
  EXPECT_EQ(w2.size(), ns + 50);
  EXPECT_EQ(w2.tail(50).sum(), 50.0);
}

TEST(OgaSetup, ARangeForEveryAxisGoesToTheAxesThatMove) {
  const core::Machine m = core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml");
  const Motion mo = motion_of(m);  // X and Z move, Y does not
  std::map<std::string, std::pair<double, double>> range;
  methods::set_range_of_moving_axes(mo.sp, m, {5.0, 6.5}, range);
  ASSERT_EQ(range.size(), 2u);
  EXPECT_EQ(range.at("X"), std::make_pair(5.0, 6.5));
  EXPECT_EQ(range.at("Z"), std::make_pair(5.0, 6.5));
  // An AXIS=MIN:MAX range given as well wins on its axis.
  std::map<std::string, std::pair<double, double>> named = {{"Z", {4.0, 4.5}}};
  methods::set_range_of_moving_axes(mo.sp, m, {5.0, 6.5}, named);
  EXPECT_EQ(named.at("Z"), std::make_pair(4.0, 4.5));
  EXPECT_EQ(named.at("X"), std::make_pair(5.0, 6.5));
  EXPECT_EQ(named.count("Y"), 0u);
}
