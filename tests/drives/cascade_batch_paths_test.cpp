// The batched cascade's short plant path (drives/cascade_batch_kernel.inc, taken when every lane of a vector has
// friction and neither tilting gravity nor a Stribeck hump: the Mikron's X, Y, Z) on the cases it shortcuts and the
// ones it hands to the general code: lanes sticking and breaking away at different current periods, all lanes stuck
// at once, one lane stuck (not at a fixed point: its integrators move) for a whole block of rows.
// Reference: each axis alone through CascadeAxis::step (drives/cascade_axis.cpp), rows and commands as
// simulate_axes documents them (drives/simulate.hpp), bit for bit, with every kernel the processor runs (generic,
// AVX2, AVX-512VL).
#include "drives/cascade_batch.hpp"
#include "drives/simulate.hpp"

#include "tests/drives/cascade_reference.hpp"
#include "tests/drives/drive_test_support.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

namespace vmsim::drives {
namespace {

bool cbp_same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

// The first row/axis whose bits differ between got's rows and want's rows [row0, row0 + got rows), per column.
void cbp_expect_rows(const AxisResponse& got, const AxisResponse& want, Eigen::Index row0, const std::string& what) {
  const std::pair<const char*, Eigen::MatrixXd AxisResponse::*> cols[] = {
      {"position", &AxisResponse::position},
      {"velocity", &AxisResponse::velocity},
      {"acceleration", &AxisResponse::acceleration},
      {"jerk", &AxisResponse::jerk},
      {"current_A", &AxisResponse::current_A},
      {"current_setpoint_A", &AxisResponse::current_setpoint_A},
      {"current_mean_A", &AxisResponse::current_mean_A},
      {"current_peak_A", &AxisResponse::current_peak_A}};
  for (const auto& [name, col] : cols) {
    const Eigen::MatrixXd& g = got.*col;
    const Eigen::MatrixXd& w = want.*col;
    ASSERT_EQ(g.cols(), w.cols()) << what;
    ASSERT_LE(row0 + g.rows(), w.rows()) << what;
    for (Eigen::Index a = 0; a < g.cols(); ++a)
      for (Eigen::Index r = 0; r < g.rows(); ++r)
        if (!cbp_same_bits(g(r, a), w(row0 + r, a))) {
          ADD_FAILURE() << what << ": " << name << " differs at row " << row0 + r << ", axis " << a << ": " << g(r, a)
                        << " against " << w(row0 + r, a);
          return;
        }
  }
}

// X, Y, Z of the Mikron (Coulomb friction, Z's constant gravity): X creeps at 10 um/s from 0.1 s and Y at -13 um/s
// from 0.35 s (stick-slip: each sticks and breaks loose again, at its own instants); Z is held 0.5 um off its
// starting point (it sticks against friction while its velocity integrator winds up: not a fixed point) until
// 1.2 s, then moves 0.2 mm in a smooth 0.1 s step and rests.
core::Setpoints cbp_profile(const core::Machine& m) {
  return test::sampled(m, 1e-3, 2000, [](double t, double* out) {
    const auto smooth = [](double u) { return u <= 0.0 ? 0.0 : u >= 1.0 ? 1.0 : u * u * (3.0 - 2.0 * u); };
    out[0] = t < 0.1 ? 0.0 : 0.010 * (t - 0.1);
    out[1] = 20.0 - (t < 0.35 ? 0.0 : 0.013 * (t - 0.35));
    out[2] = -50.0 + 0.0005 + 0.2 * smooth((t - 1.2) / 0.1);
  });
}

// The profile does what the header claims, in the reference's full-rate trace (speed exactly 0: stuck).
void cbp_expect_exercised(const AxisResponse& ref, Eigen::Index nin) {
  const Eigen::Index n = ref.trace[0].velocity.size();
  bool mixed = false, all_stuck_moving = false;
  std::set<Eigen::Index> breaks[3];
  for (Eigen::Index q = 1; q < n; ++q) {
    int stuck = 0;
    bool current_moves = false;
    for (int a = 0; a < 3; ++a) {
      const FullRateTrace& t = ref.trace[static_cast<std::size_t>(a)];
      stuck += t.velocity[q] == 0.0;
      current_moves = current_moves || t.current_A[q] != t.current_A[q - 1];
      if (t.velocity[q - 1] == 0.0 && t.velocity[q] != 0.0) breaks[a].insert(q);
    }
    mixed = mixed || (stuck > 0 && stuck < 3);
    all_stuck_moving = all_stuck_moving || (stuck == 3 && current_moves);
  }
  EXPECT_TRUE(mixed) << "no current period with some lanes stuck and others sliding";
  EXPECT_TRUE(all_stuck_moving) << "no current period with every lane stuck and a current still moving";
  EXPECT_GE(breaks[0].size(), 2u) << "X does not break loose repeatedly";
  EXPECT_GE(breaks[1].size(), 2u) << "Y does not break loose repeatedly";
  EXPECT_NE(breaks[0], breaks[1]) << "X and Y break loose at the same periods";
  // Some inner period where one lane breaks loose while another stays stuck or slides: not all at once.
  bool apart = false;
  for (Eigen::Index q : breaks[0]) apart = apart || !breaks[1].count(q);
  EXPECT_TRUE(apart);
  // Z stuck through a whole block of 256 rows (its speed 0 in every current period) while its current moves.
  bool z_block = false;
  for (Eigen::Index r0 = 0; r0 + 256 < ref.samples() && !z_block; r0 += 256) {
    bool still = true, moves = false;
    for (Eigen::Index q = r0 * nin; q <= (r0 + 256) * nin; ++q) {
      still = still && ref.trace[2].velocity[q] == 0.0;
      moves = moves || (q > r0 * nin && ref.trace[2].current_A[q] != ref.trace[2].current_A[q - 1]);
    }
    z_block = still && moves;
  }
  EXPECT_TRUE(z_block) << "Z is never stuck (and moving its current) through a whole block of 256 rows";
}

TEST(CascadeBatchPaths, SticksBreaksAndStuckBlocksBitForBit) {
  const core::Machine m = test::only_axes(test::mikron(), {"X", "Y", "Z"});
  ASSERT_EQ(m.axes.size(), 3u);
  for (const auto& ax : m.axes) {
    ASSERT_GT(ax.drive->coulomb_Nm, 0.0);  // the short path's lanes: friction, no tilt, no Stribeck
    ASSERT_EQ(ax.drive->stribeck_static_Nm, 0.0);
    ASSERT_NE(ax.drive->gravity, core::DriveParams::Gravity::Tilting);
  }
  const core::Setpoints sp = cbp_profile(m);
  const AxisResponse ref = test::cascade_reference(sp, m, nullptr, 0.2);
  const CascadeAxis probe(*m.axes[0].drive, 1e-3, m.axes[0].kind);
  cbp_expect_exercised(ref, probe.inner_steps());
  for (CascadeBatchKernel kernel : test::cascade_batch_kernels()) {
    cascade_batch_kernel_limit() = kernel;
    for (Eigen::Index block :
         {Eigen::Index{1}, Eigen::Index{7}, Eigen::Index{256}, Eigen::Index{257}, Eigen::Index{1 << 20}}) {
      const std::string what = "blocks of " + std::to_string(block) + ", " + test::cascade_batch_kernel_name(kernel);
      BlockSimulation sim(sp, m);
      ASSERT_EQ(sim.rows(), ref.samples());
      while (!sim.done() && !::testing::Test::HasFailure()) {
        const Eigen::Index row0 = sim.next_row();
        cbp_expect_rows(sim.next(block), ref, row0, what);
      }
    }
    // simulate_axes with the full-rate trace steps the batch one Te at a time (CascadeBatch::step): rows and trace.
    SimulateOptions o;
    o.full_rate_trace = true;
    const AxisResponse r = simulate_axes(sp, m, o);
    const std::string what = std::string("simulate_axes with trace, ") + test::cascade_batch_kernel_name(kernel);
    cbp_expect_rows(r, ref, 0, what);
    for (std::size_t a = 0; a < 3; ++a) {
      const FullRateTrace &g = r.trace[a], &w = ref.trace[a];
      ASSERT_EQ(g.velocity.size(), w.velocity.size()) << what;
      for (Eigen::Index q = 0; q < g.velocity.size(); ++q)
        if (!cbp_same_bits(g.position[q], w.position[q]) || !cbp_same_bits(g.velocity[q], w.velocity[q]) ||
            !cbp_same_bits(g.current_A[q], w.current_A[q]) ||
            !cbp_same_bits(g.current_setpoint_A[q], w.current_setpoint_A[q]) ||
            !cbp_same_bits(g.voltage_V[q], w.voltage_V[q])) {
          ADD_FAILURE() << what << ": trace of axis " << a << " differs at current period " << q;
          break;
        }
    }
    cascade_batch_kernel_limit() = CascadeBatchKernel::Avx512;
    if (::testing::Test::HasFailure()) return;
  }
}

}  // namespace
}  // namespace vmsim::drives
