// SignalBinner's fold (issue 21, session 10: each column's bin decided from a packed range, the sign of a zero end
// from the bin's first zero, bins with a non-finite value folded in row order) against a reference written here from
// the file's definition (sim/signals.hpp): per bin of bin_samples rows, the minimum and maximum of the finite values in
// row order (std::min / std::max: the first of equal values stays, so +0 before -0 gives +0), NaN for a bin without
// one. The drive's signals and the contour error are random here, drawn to make the order matter: runs of +0 and -0,
// repeated values, NaN and infinities, a rotary axis turning (its columns scaled to degrees). Bit for bit, with the
// response fed in blocks of 1, 7 and all rows, and bins of 1, 5 and 64 rows. The setpoints: plane_cylinder's fast
// job interpolated (Mikron; its A axis given a ramp so that it moves).
#include "core/job.hpp"
#include "core/progress.hpp"
#include "core/units.hpp"
#include "sim/chain.hpp"
#include "sim/pipeline.hpp"
#include "sim/signals.hpp"
#include "tests/sim/signal_test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>

using namespace vmsim;

namespace {

// Values whose order matters to a fold: stretches of zeros of both signs, of one repeated value, of ordinary
// numbers, with NaN and infinities now and then.
Eigen::ArrayXd sigfold_values(Eigen::Index n, std::mt19937_64& rng) {
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  std::uniform_int_distribution<int> kind(0, 9), run(1, 40);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  Eigen::ArrayXd v(n);
  Eigen::Index k = 0;
  while (k < n) {
    const int what = kind(rng), len = run(rng);
    const double repeated = u(rng);
    for (int i = 0; i < len && k < n; ++i, ++k) {
      switch (what) {
        case 0:
        case 1:
          v[k] = (rng() & 1) ? 0.0 : -0.0;  // zeros of random sign
          break;
        case 2:
          v[k] = (rng() & 1) ? 0.0 : u(rng);  // zeros among numbers of both signs
          break;
        case 3:
          v[k] = repeated;
          break;
        case 4:
          v[k] = (rng() % 16 == 0) ? ((rng() & 1) ? nan : ((rng() & 1) ? inf : -inf)) : u(rng);
          break;
        case 5:
          v[k] = std::abs(u(rng));  // positive only: a zero that enters is the minimum
          break;
        case 6:
          v[k] = -std::abs(u(rng));
          break;
        default:
          v[k] = u(rng);
      }
    }
  }
  return v;
}

TEST(SignalFold, RandomSignalsWithSignedZerosAndNonFiniteValuesEqualTheRowOrderFold) {
  const core::Job job = core::load_job(std::string(VMSIM_SOURCE_DIR) + "/parts/plane_cylinder/job_fast.toml");
  sim::Motion m;
  sim::read_and_interpolate(sim::Chain(job), core::RemovalSpec::Motion::Setpoints, m, core::no_progress());
  core::Setpoints& sp = m.interp.setpoints;
  // A shorter run (the fold does not care how long): the first 6000 setpoints, 40 settling rows after them.
  const Eigen::Index ns = std::min<Eigen::Index>(sp.samples(), 6000), n = ns + 40;
  ASSERT_GT(ns, 1000);
  sp.position.conservativeResize(ns, Eigen::NoChange);
  sp.path_speed_mm_per_s.conservativeResize(ns);
  sp.move_index.conservativeResize(ns);
  Eigen::Index rotary = -1;
  for (std::size_t i = 0; i < job.machine.axes.size(); ++i)
    if (job.machine.axes[i].kind == core::AxisKind::Rotary) rotary = static_cast<Eigen::Index>(i);
  ASSERT_GE(rotary, 0);
  for (Eigen::Index k = 0; k < ns; ++k) sp.position(k, rotary) = 1e-4 * static_cast<double>(k);

  std::mt19937_64 rng(20261127);
  drives::AxisResponse resp;
  resp.period_s = sp.period_s;
  resp.axis_names = sp.axis_names;
  const auto axes = static_cast<Eigen::Index>(job.machine.axes.size());
  for (Eigen::MatrixXd* x :
       {&resp.position, &resp.velocity, &resp.acceleration, &resp.jerk, &resp.current_mean_A, &resp.current_peak_A}) {
    x->resize(n, axes);
    for (Eigen::Index a = 0; a < axes; ++a) x->col(a) = sigfold_values(n, rng).matrix();
  }
  // Positions stay finite (the tips' kinematics take them); their column still gets zeros and ties.
  resp.position = resp.position.unaryExpr([](double x) { return std::isfinite(x) ? x : 0.5; });
  motion::ContourError ce;
  ce.signed_mm = sigfold_values(n, rng);
  ce.foot_segment = Eigen::ArrayXi::Zero(n);

  const double te = sp.period_s;
  for (const Eigen::Index bin : {Eigen::Index{1}, Eigen::Index{5}, Eigen::Index{64}}) {
    for (const Eigen::Index block : {Eigen::Index{1}, Eigen::Index{7}, n}) {
      SCOPED_TRACE("bins of " + std::to_string(bin) + " rows, blocks of " + std::to_string(block));
      sim::SignalBinner binner(job, m.program, sp, n, 1.0, (n + bin - 1) / bin);
      for (Eigen::Index k0 = 0; k0 < n; k0 += block)
        binner.add(k0, vmsim_test::response_rows(resp, k0, std::min(block, n - k0)));
      binner.add_contour(ce);
      const sim::BinnedSignals s = binner.finish();
      ASSERT_EQ(s.bin_samples, bin);
      std::vector<std::pair<std::string, std::function<double(Eigen::Index)>>> defs = {
          {"t_s", [&](Eigen::Index k) { return static_cast<double>(k) * te; }},
          {"contour_error_mm",
           [&](Eigen::Index k) {
             const int mi = sp.move_index[std::min(k, ns - 1)];
             const bool cut = mi >= 0 && !m.program.moves[static_cast<std::size_t>(mi)].rapid;
             return cut ? ce.signed_mm[k] : std::numeric_limits<double>::quiet_NaN();
           }},
      };
      bool rotary_seen = false;
      for (const auto& [name, unit] : s.axes) {
        Eigen::Index a = -1;
        for (std::size_t i = 0; i < job.machine.axes.size(); ++i)
          if (job.machine.axes[i].name == name) a = static_cast<Eigen::Index>(i);
        ASSERT_GE(a, 0) << name;
        rotary_seen = rotary_seen || a == rotary;
        const double f = unit == "deg" ? core::units::kRadToDeg : 1.0;
        const std::string u = unit;
        auto x = [&sp, ns, a](Eigen::Index k) { return sp.position(std::clamp<Eigen::Index>(k, 0, ns - 1), a); };
        defs.emplace_back(name + "_setpoint_" + u, [x, f](Eigen::Index k) { return x(k) * f; });
        defs.emplace_back(name + "_tracking_error_" + u,
                          [x, f, a, &resp](Eigen::Index k) { return (x(k) - resp.position(k, a)) * f; });
        defs.emplace_back(name + "_actual_" + u, [f, a, &resp](Eigen::Index k) { return resp.position(k, a) * f; });
        defs.emplace_back(name + "_velocity_actual_" + u + "_per_s",
                          [f, a, &resp](Eigen::Index k) { return resp.velocity(k, a) * f; });
        defs.emplace_back(name + "_acceleration_actual_" + u + "_per_s2",
                          [f, a, &resp](Eigen::Index k) { return resp.acceleration(k, a) * f; });
        defs.emplace_back(name + "_jerk_actual_" + u + "_per_s3",
                          [f, a, &resp](Eigen::Index k) { return resp.jerk(k, a) * f; });
        defs.emplace_back(name + "_current_A", [a, &resp](Eigen::Index k) { return resp.current_mean_A(k, a); });
        defs.emplace_back(name + "_current_peak_A", [a, &resp](Eigen::Index k) { return resp.current_peak_A(k, a); });
      }
      ASSERT_TRUE(rotary_seen);
      int zero_ends = 0, nan_bins = 0;
      for (const auto& [col, value] : defs) {
        const int c = s.find(col);
        ASSERT_GE(c, 0) << col;
        const vmsim_test::BinRange ref = vmsim_test::fold_bins_in_row_order(n, s.bin_samples, value);
        ASSERT_EQ(ref.lo.size(), s.bins());
        for (Eigen::Index b = 0; b < s.bins(); ++b) {
          ASSERT_TRUE(vmsim_test::same_double_bits(ref.lo[b], s.min(b, c)))
              << col << " bin " << b << ": " << ref.lo[b] << " vs " << s.min(b, c);
          ASSERT_TRUE(vmsim_test::same_double_bits(ref.hi[b], s.max(b, c)))
              << col << " bin " << b << ": " << ref.hi[b] << " vs " << s.max(b, c);
          zero_ends += (ref.lo[b] == 0.0) + (ref.hi[b] == 0.0);
          nan_bins += std::isnan(ref.lo[b]);
        }
      }
      // The draw reaches what the fold must get right: zero ends (of both signs) and empty bins.
      EXPECT_GT(zero_ends, bin == 64 ? 20 : 100);
      if (bin == 1) {
        EXPECT_GT(nan_bins, 10);
      }
    }
  }
}

}  // namespace
