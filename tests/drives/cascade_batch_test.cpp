// The batched cascade (drives/cascade_batch, used by simulate_axes and BlockSimulation) against the reference it
// replaces: each axis alone through CascadeAxis::step (drives/cascade_axis.cpp, unchanged), rows and commands as
// simulate_axes documents them. Bit for bit on every machine in parts/machines, with friction (Coulomb, Stribeck),
// gravity (none, constant, tilting with an offset), current and voltage saturation, sticking, gain schedules, axes at
// rest (the batch's skipped periods), 1 and 2 threads, blocks of 1, 7, 255-257 and all rows, lanes leaving and
// re-entering a fixed point within CascadeBatch::run_rows, and every kernel the processor runs (the generic build's,
// AVX2 and AVX-512VL, the batch picking the widest at run time).
#include "drives/cascade_batch.hpp"
#include "drives/simulate.hpp"

#include "core/error.hpp"
#include "tests/drives/cascade_reference.hpp"
#include "tests/drives/drive_test_support.hpp"
#include "tests/test_paths.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

namespace vmsim::drives {
namespace {

// Index of the first entry whose bits differ (-1: none; sizes differ: 0). Bits, not ==: 0.0 and -0.0 differ.
template <typename A, typename B>
Eigen::Index cbt_first_difference(const A& a, const B& b) {
  if (a.size() != b.size()) return 0;
  for (Eigen::Index i = 0; i < a.size(); ++i)
    if (std::bit_cast<std::uint64_t>(a.data()[i]) != std::bit_cast<std::uint64_t>(b.data()[i])) return i;
  return -1;
}

void cbt_expect_rows(const AxisResponse& got, const AxisResponse& want, Eigen::Index row0, const std::string& what) {
  const struct {
    const char* name;
    const Eigen::MatrixXd& got;
    const Eigen::MatrixXd& want;
  } cols[] = {{"position", got.position, want.position},
              {"velocity", got.velocity, want.velocity},
              {"acceleration", got.acceleration, want.acceleration},
              {"jerk", got.jerk, want.jerk},
              {"current_A", got.current_A, want.current_A},
              {"current_setpoint_A", got.current_setpoint_A, want.current_setpoint_A},
              {"current_mean_A", got.current_mean_A, want.current_mean_A},
              {"current_peak_A", got.current_peak_A, want.current_peak_A}};
  for (const auto& c : cols) {
    ASSERT_EQ(c.got.cols(), c.want.cols()) << what << " " << c.name;
    ASSERT_LE(row0 + c.got.rows(), c.want.rows()) << what << " " << c.name;
    const Eigen::MatrixXd part = c.want.middleRows(row0, c.got.rows());
    const Eigen::Index i = cbt_first_difference(c.got, part);
    EXPECT_EQ(i, -1) << what << ": " << c.name << " differs at row "
                     << row0 + (i % std::max<Eigen::Index>(1, part.rows())) << ", axis "
                     << i / std::max<Eigen::Index>(1, part.rows());
  }
}

void cbt_expect_traces(const AxisResponse& got, const AxisResponse& want, const std::string& what) {
  ASSERT_EQ(got.trace.size(), want.trace.size()) << what;
  for (std::size_t a = 0; a < got.trace.size(); ++a) {
    const FullRateTrace &g = got.trace[a], &w = want.trace[a];
    EXPECT_EQ(g.period_s, w.period_s) << what;
    EXPECT_EQ(cbt_first_difference(g.position, w.position), -1) << what << " trace position, axis " << a;
    EXPECT_EQ(cbt_first_difference(g.velocity, w.velocity), -1) << what << " trace velocity, axis " << a;
    EXPECT_EQ(cbt_first_difference(g.current_A, w.current_A), -1) << what << " trace current, axis " << a;
    EXPECT_EQ(cbt_first_difference(g.current_setpoint_A, w.current_setpoint_A), -1)
        << what << " trace iset, axis " << a;
    EXPECT_EQ(cbt_first_difference(g.voltage_V, w.voltage_V), -1) << what << " trace voltage, axis " << a;
  }
}

// A profile that exercises every branch of the cascade, per axis (scale s: 5 mm linear, 0.2 rad rotary), 3 s:
// rest; a step of s in one Te (the velocity loop saturates at the current limit and the current loop at the voltage
// limit); rest (the axis settles and sticks); a 2 Hz sine (reversals through the friction band); a step of -2 s;
// a creep at 0.2 % of s per s (stick-slip); rest. Each axis starts its pattern at another instant. Axes in `held`
// never move (the batch skips their periods once they are at rest).
core::Setpoints cbt_profile(const core::Machine& m, const std::vector<bool>& held) {
  const std::size_t n_axes = m.axes.size();
  return test::sampled(m, 1e-3, 3000, [&](double t, double* out) {
    for (std::size_t a = 0; a < n_axes; ++a) {
      const double s = m.axes[a].kind == core::AxisKind::Rotary ? 0.2 : 5.0;
      const double x0 = m.axes[a].kind == core::AxisKind::Rotary ? 0.1 : 10.0 * static_cast<double>(a);
      const double u = t - 0.05 * static_cast<double>(a);
      double x = x0;
      if (held[a] || u < 0.3)
        x = x0;
      else if (u < 0.8)
        x = x0 + s;
      else if (u < 1.8)
        x = x0 + s * std::cos(2.0 * 3.141592653589793 * 2.0 * (u - 0.8));
      else if (u < 2.3)
        x = x0 - s;
      else if (u < 2.7)
        x = x0 - s + 0.002 * s * (u - 2.3);
      else
        x = x0 - s + 0.002 * s * 0.4;
      out[a] = x;
    }
  });
}

struct CbtVariant {
  std::string name;
  core::Machine machine;
  std::vector<bool> held;
};

// Every machine file as written (the last axis held), then with every axis moving and: Stribeck friction on every
// drive; the tilting axes' gravity with an offset of 0.3 rad; no friction at all (the exact linear step).
std::vector<CbtVariant> cbt_variants() {
  std::vector<CbtVariant> out;
  for (const auto& e : std::filesystem::directory_iterator(vmsim::test::kPartsPath / "machines")) {
    if (e.path().extension() != ".toml") continue;
    const core::Machine base = core::load_machine(e.path());
    const std::string file = e.path().stem().string();
    std::vector<bool> last_held(base.axes.size(), false), none_held(base.axes.size(), false);
    last_held.back() = true;
    out.push_back({file + " as written", base, last_held});
    core::Machine stribeck = base, offset = base, frictionless = base;
    for (auto& ax : stribeck.axes) {
      ax.drive->stribeck_static_Nm = 1.6 * ax.drive->coulomb_Nm + 0.2;
      ax.drive->stribeck_velocity_rad_per_s = 3.0;
    }
    for (auto& ax : offset.axes)
      if (ax.drive->gravity == core::DriveParams::Gravity::Tilting) ax.drive->gravity_angle_offset_rad = 0.3;
    for (auto& ax : frictionless.axes) ax.drive->coulomb_Nm = 0.0;
    out.push_back({file + " stribeck", stribeck, none_held});
    out.push_back({file + " tilting offset", offset, none_held});
    out.push_back({file + " frictionless", frictionless, none_held});
  }
  return out;
}

// The profile does what it claims: somewhere the current setpoint sits at the current limit and the voltage at the
// voltage limit, and an axis is at rest (speed exactly 0) with friction.
void cbt_expect_exercised(const CbtVariant& v, const AxisResponse& ref) {
  bool current_limited = false, voltage_limited = false, stuck = false;
  for (std::size_t a = 0; a < v.machine.axes.size(); ++a) {
    const core::DriveParams& p = *v.machine.axes[a].drive;
    const Eigen::Index c = static_cast<Eigen::Index>(a);
    current_limited |= (ref.current_setpoint_A.col(c).array().abs() == p.current_limit_A).any();
    voltage_limited |= (ref.trace[a].voltage_V.abs() == p.voltage_limit_V).any();
    stuck |= p.coulomb_Nm > 0.0 && (ref.velocity.col(c).array() == 0.0).any();
  }
  EXPECT_TRUE(current_limited) << v.name;
  EXPECT_TRUE(voltage_limited) << v.name;
  if (v.name.find("frictionless") == std::string::npos) {
    EXPECT_TRUE(stuck) << v.name;
  }
}

TEST(CascadeBatch, SimulateAxesBitForBitWithEachAxisAloneOnEveryMachine) {
  const int saved = omp_get_max_threads();
  int machines = 0;
  for (const CbtVariant& v : cbt_variants()) {
    ++machines;
    const core::Setpoints sp = cbt_profile(v.machine, v.held);
    const AxisResponse ref = test::cascade_reference(sp, v.machine, nullptr, 0.2);
    cbt_expect_exercised(v, ref);
    SimulateOptions o;
    o.full_rate_trace = true;
    for (CascadeBatchKernel kernel : test::cascade_batch_kernels())
      for (int threads : {1, 2}) {
        omp_set_num_threads(threads);
        cascade_batch_kernel_limit() = kernel;
        const AxisResponse got = simulate_axes(sp, v.machine, o);
        cascade_batch_kernel_limit() = CascadeBatchKernel::Avx512;
        const std::string what =
            v.name + ", " + std::to_string(threads) + " thread(s), " + test::cascade_batch_kernel_name(kernel);
        cbt_expect_rows(got, ref, 0, what);
        cbt_expect_traces(got, ref, what);
        // Without the full-rate trace the batch runs the rows itself (CascadeBatch::run_rows): the same rows.
        SimulateOptions no_trace;
        cascade_batch_kernel_limit() = kernel;
        const AxisResponse rows = simulate_axes(sp, v.machine, no_trace);
        cascade_batch_kernel_limit() = CascadeBatchKernel::Avx512;
        cbt_expect_rows(rows, ref, 0, what + ", rows without trace");
      }
  }
  omp_set_num_threads(saved);
  EXPECT_EQ(machines, 16);  // 4 machine files x 4 variants
}

TEST(CascadeBatch, BlocksOfOneSevenAndAllRowsBitForBit) {
  const core::Machine m = test::mikron();
  std::vector<bool> held(m.axes.size(), false);
  held[4] = true;  // C at rest all along: its periods are skipped within a block
  const core::Setpoints sp = cbt_profile(m, held);
  const AxisResponse ref = test::cascade_reference(sp, m, nullptr, 0.2);
  // 255 / 256 / 257: a block ends just before, on and after the batch's runs of 256 rows (simulate.cpp's kPollRows).
  for (CascadeBatchKernel kernel : test::cascade_batch_kernels())
    for (Eigen::Index block : {Eigen::Index{1}, Eigen::Index{7}, Eigen::Index{255}, Eigen::Index{256},
                               Eigen::Index{257}, Eigen::Index{1 << 20}}) {
      const std::string what = "blocks of " + std::to_string(block) + ", " + test::cascade_batch_kernel_name(kernel);
      cascade_batch_kernel_limit() = kernel;
      BlockSimulation sim(sp, m);
      ASSERT_EQ(sim.rows(), ref.samples());
      while (!sim.done()) {
        const Eigen::Index row0 = sim.next_row();
        const AxisResponse r = sim.next(block);
        cbt_expect_rows(r, ref, row0, what);
        if (::testing::Test::HasFailure()) break;
      }
      cascade_batch_kernel_limit() = CascadeBatchKernel::Avx512;
      if (::testing::Test::HasFailure()) return;
    }
}

// CascadeBatch::run_rows directly, in runs of rows that start and end anywhere, on lanes that rest at a fixed point,
// leave it and come back to one (frictionless X and Z: their linear loops settle onto a state that repeats itself
// bit for bit, as the skipped counts show; Y, A, C rest all along), so that the set of lanes on the vectors changes
// several times within a run.
// Reference: each axis alone through CascadeAxis::step (test::cascade_reference).
TEST(CascadeBatch, RunRowsAcrossFixedPointsLeftAndReentered) {
  core::Machine m = test::mikron();
  for (auto& ax : m.axes) ax.drive->coulomb_Nm = 0.0;
  const Eigen::Index n_set = 6000;
  const core::Setpoints sp = test::sampled(m, 1e-3, n_set, [&](double t, double* out) {
    for (int a = 0; a < 5; ++a) out[a] = 0.0;
    // X: 1 mm in a smooth 0.1 s step at 0.2 s, back at 3 s; Z: 0.5 mm at 0.25 s.
    const auto smooth = [](double u) { return u <= 0.0 ? 0.0 : u >= 1.0 ? 1.0 : u * u * (3.0 - 2.0 * u); };
    out[0] = smooth((t - 0.2) / 0.1) - smooth((t - 3.0) / 0.1);
    out[2] = 0.5 * smooth((t - 0.25) / 0.1);
  });
  const AxisResponse ref = test::cascade_reference(sp, m, nullptr, 0.0);
  for (CascadeBatchKernel kernel : test::cascade_batch_kernels()) {
    const std::string what = std::string("run_rows, ") + test::cascade_batch_kernel_name(kernel);
    std::vector<CascadeAxis> axes;
    for (const auto& ax : m.axes) {
      axes.emplace_back(*ax.drive, 1e-3, ax.kind);
      axes.back().reset(0.0);
    }
    std::vector<CascadeAxis*> ptrs;
    for (CascadeAxis& a : axes) ptrs.push_back(&a);
    CascadeBatch batch(ptrs, false);
    AxisResponse got;
    for (Eigen::MatrixXd* c : {&got.position, &got.velocity, &got.acceleration, &got.jerk, &got.current_A,
                               &got.current_setpoint_A, &got.current_mean_A, &got.current_peak_A})
      c->setConstant(n_set, 5, std::numeric_limits<double>::quiet_NaN());
    CascadeRowLane rl[5];
    for (int l = 0; l < 5; ++l) {
      rl[l].setpoints = sp.position.col(l).data();
      double* o[8] = {got.position.col(l).data(),       got.velocity.col(l).data(),
                      got.acceleration.col(l).data(),   got.jerk.col(l).data(),
                      got.current_A.col(l).data(),      got.current_mean_A.col(l).data(),
                      got.current_peak_A.col(l).data(), got.current_setpoint_A.col(l).data()};
      std::copy(o, o + 8, rl[l].out);
      rl[l].s = axes[static_cast<std::size_t>(l)].sample();
    }
    cascade_batch_kernel_limit() = kernel;
    // Runs of 1, 13, 256, 999 ... rows; the skipped periods counted in each phase of X's motion.
    long long skipped_at_3000 = 0;
    const long long runs[] = {1, 13, 256, 999};
    long long k = 0;
    for (int r = 0; k < n_set; ++r) {
      const long long k1 = std::min<long long>(n_set, k + runs[r % 4]);
      if (k < 3000 && k1 >= 3000) {
        batch.run_rows(rl, k, 3000, 0, n_set, n_set, 1e-3);
        skipped_at_3000 = batch.skipped_periods();
        k = 3000;
        continue;
      }
      batch.run_rows(rl, k, k1, 0, n_set, n_set, 1e-3);
      k = k1;
    }
    cascade_batch_kernel_limit() = CascadeBatchKernel::Avx512;
    cbt_expect_rows(got, ref, 0, what);
    // Y, A and C are skipped all along but their first period (2 999 each in the first 3 000 rows). X and Z rest
    // at first (at most 200 and 250 skipped periods), move, and re-enter a fixed point once settled: over 1 000 more.
    // In the second half Z stays at its point (3 000 more skipped, and Y, A, C's 9 000).
    EXPECT_GT(skipped_at_3000, 3 * 2999 + 200 + 250 + 1000) << what;
    EXPECT_GT(batch.skipped_periods() - skipped_at_3000, 3 * 2999 + 2900) << what;
    batch.store();
    for (int a = 0; a < 5; ++a)
      EXPECT_EQ(std::bit_cast<std::uint64_t>(axes[static_cast<std::size_t>(a)].sample().position),
                std::bit_cast<std::uint64_t>(ref.position(n_set - 1, a)))
          << what << " axis " << a;
  }
}

// Reference as above with a gain schedule (Duong et al.'s OGA): Kv and KF changing every 50 rows on every axis,
// NaN (the drive's own) on some rows; the settling rows keep the last row's gains.
TEST(CascadeBatch, GainScheduleBitForBit) {
  const core::Machine m = test::mikron();
  const core::Setpoints sp = cbt_profile(m, std::vector<bool>(m.axes.size(), false));
  GainSchedule g;
  g.kv_per_s.resize(sp.samples(), sp.position.cols());
  g.kf.resize(sp.samples(), sp.position.cols());
  for (Eigen::Index k = 0; k < sp.samples(); ++k)
    for (Eigen::Index a = 0; a < sp.position.cols(); ++a) {
      const Eigen::Index phase = (k / 50 + a) % 4;
      g.kv_per_s(k, a) =
          phase == 3 ? std::numeric_limits<double>::quiet_NaN() : 60.0 + 20.0 * static_cast<double>(phase);
      g.kf(k, a) = phase == 1 ? std::numeric_limits<double>::quiet_NaN() : 0.05 * static_cast<double>(phase);
    }
  const AxisResponse ref = test::cascade_reference(sp, m, &g, 0.2);
  SimulateOptions o;
  o.gains = &g;
  o.full_rate_trace = true;
  for (CascadeBatchKernel kernel : test::cascade_batch_kernels()) {
    cascade_batch_kernel_limit() = kernel;
    const AxisResponse got = simulate_axes(sp, m, o);
    cascade_batch_kernel_limit() = CascadeBatchKernel::Avx512;
    cbt_expect_rows(got, ref, 0, std::string("gain schedule, ") + test::cascade_batch_kernel_name(kernel));
    cbt_expect_traces(got, ref, std::string("gain schedule, ") + test::cascade_batch_kernel_name(kernel));
    SimulateOptions rows_only;  // no trace: CascadeBatch::run_rows
    rows_only.gains = &g;
    cascade_batch_kernel_limit() = kernel;
    const AxisResponse rows = simulate_axes(sp, m, rows_only);
    cascade_batch_kernel_limit() = CascadeBatchKernel::Avx512;
    cbt_expect_rows(rows, ref, 0, std::string("gain schedule, rows, ") + test::cascade_batch_kernel_name(kernel));
  }
}

// Axes with different loop periods go into different batches: X's current loop at 31.25 us (32 periods per Te,
// velocity loop every 4), the rest as in the machine file. Reference as above.
TEST(CascadeBatch, AxesWithOtherLoopPeriodsRunInTheirOwnBatch) {
  core::Machine m = test::mikron();
  m.axes[0].drive->current_period_s = 31.25e-6;
  const core::Setpoints sp = cbt_profile(m, std::vector<bool>(m.axes.size(), false));
  const AxisResponse ref = test::cascade_reference(sp, m, nullptr, 0.2);
  SimulateOptions o;
  o.full_rate_trace = true;
  const AxisResponse got = simulate_axes(sp, m, o);
  cbt_expect_rows(got, ref, 0, "mixed loop periods");
  cbt_expect_traces(got, ref, "mixed loop periods");
}

// The batch directly: an axis at rest under a constant command has its periods skipped (the count says so), the
// results are CascadeAxis::step's, and after store() the axes go on by themselves exactly as the reference does.
TEST(CascadeBatch, SkipsPeriodsAtAFixedPointAndHandsTheStateBack) {
  const core::Machine m = test::mikron();
  std::vector<CascadeAxis> ref_axes, batch_axes;
  for (std::size_t a = 0; a < m.axes.size(); ++a) {
    ref_axes.emplace_back(*m.axes[a].drive, 1e-3, m.axes[a].kind);
    ref_axes.back().reset(0.0);
  }
  batch_axes = ref_axes;
  std::vector<CascadeAxis*> ptrs;
  for (CascadeAxis& a : batch_axes) ptrs.push_back(&a);
  CascadeBatch batch(ptrs, false);
  ASSERT_EQ(batch.lanes(), 5);
  AxisCommand commands[5];
  AxisSample samples[5];
  for (int k = 0; k < 400; ++k) {
    // X moves 1 mm at k = 10 and is then held; the other axes hold 0 all along.
    commands[0] = AxisCommand{};
    commands[0].position = k >= 10 ? 1.0 : 0.0;
    commands[0].velocity = k == 10 ? 1000.0 : 0.0;
    commands[0].acceleration = k == 10 ? 1e6 : (k == 11 ? -1e6 : 0.0);
    for (int a = 1; a < 5; ++a) commands[a] = AxisCommand{};
    batch.step(commands, samples);
    for (int a = 0; a < 5; ++a) {
      const AxisSample want = ref_axes[static_cast<std::size_t>(a)].step(commands[a]);
      ASSERT_EQ(std::bit_cast<std::uint64_t>(samples[a].position), std::bit_cast<std::uint64_t>(want.position))
          << "axis " << a << " row " << k;
      ASSERT_EQ(std::bit_cast<std::uint64_t>(samples[a].current_mean_A),
                std::bit_cast<std::uint64_t>(want.current_mean_A))
          << "axis " << a << " row " << k;
      ASSERT_EQ(std::bit_cast<std::uint64_t>(samples[a].acceleration), std::bit_cast<std::uint64_t>(want.acceleration))
          << "axis " << a << " row " << k;
    }
  }
  // Y, A and C rest at 0 from the start (no gravity on them at 0): all but their first period are skipped.
  EXPECT_GE(batch.skipped_periods(), 3 * 399);
  batch.store();
  AxisCommand c;
  c.position = -0.5;
  for (std::size_t a = 0; a < 5; ++a) {
    const AxisSample got = batch_axes[a].step(c), want = ref_axes[a].step(c);
    EXPECT_EQ(std::bit_cast<std::uint64_t>(got.position), std::bit_cast<std::uint64_t>(want.position)) << a;
    EXPECT_EQ(std::bit_cast<std::uint64_t>(got.current_A), std::bit_cast<std::uint64_t>(want.current_A)) << a;
  }
}

TEST(CascadeBatch, RefusesWhatItCannotBatch) {
  const core::Machine m = test::mikron();
  CascadeAxis x(*m.axes[0].drive, 1e-3, m.axes[0].kind);
  core::DriveParams other = *m.axes[1].drive;
  other.current_period_s = 31.25e-6;
  CascadeAxis y(other, 1e-3, m.axes[1].kind);
  EXPECT_FALSE(CascadeBatch::compatible(x, y));
  EXPECT_THROW(CascadeBatch({&x, &y}, false), core::Error);
  EXPECT_THROW(CascadeBatch({}, false), core::Error);
  std::vector<CascadeAxis> many(CascadeBatch::kMaxLanes + 1, x);
  std::vector<CascadeAxis*> ptrs;
  for (CascadeAxis& a : many) ptrs.push_back(&a);
  EXPECT_THROW(CascadeBatch(ptrs, false), core::Error);
}

}  // namespace
}  // namespace vmsim::drives
