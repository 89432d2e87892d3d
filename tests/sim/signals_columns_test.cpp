// SignalBinner's per-axis columns (issue 21, session 9: the setpoint's differences computed for a block's rows at once,
// then folded) against a reference written here from the file's definition (sim/signals.hpp): per response row k, the
// setpoint x_k held at the last one after the setpoints and at the first before them, its backward differences over
// Te, Te^2 and Te^3, the tracking error, and the drive's own signals, each scaled to the axis unit; per bin of
// bin_samples rows, the minimum and maximum of the finite values in row order (std::min / std::max: the first of equal
// values stays), NaN for a bin without one. Bit for bit, with the response fed to the binner in blocks of 1, 7 and all
// rows. The run: plane_cylinder's fast job (Mikron, actual motion) through the chain.
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
#include <string>

using namespace vmsim;

namespace {

TEST(SignalColumns, AxisColumnsEqualTheirDefinitionInBlocksOf1And7AndAll) {
  const core::Job job = core::load_job(std::string(VMSIM_SOURCE_DIR) + "/parts/plane_cylinder/job_fast.toml");
  sim::Motion m = sim::simulate_motion(sim::Chain(job), core::RemovalSpec::Motion::Actual, core::no_progress());
  sim::add_contour_error(m, job);
  ASSERT_TRUE(m.response && m.contour);
  const core::Setpoints& sp = m.interp.setpoints;
  const drives::AxisResponse& resp = *m.response;
  const Eigen::Index n = resp.samples(), ns = sp.samples();
  ASSERT_GT(ns, 1000);
  const double te = sp.period_s;
  for (const Eigen::Index block : {Eigen::Index{1}, Eigen::Index{7}, n}) {
    SCOPED_TRACE("blocks of " + std::to_string(block));
    sim::SignalBinner binner(job, m.program, sp, n);
    for (Eigen::Index k0 = 0; k0 < n; k0 += block)
      binner.add(k0, vmsim_test::response_rows(resp, k0, std::min(block, n - k0)));
    binner.add_contour(*m.contour);
    const sim::BinnedSignals s = binner.finish();
    ASSERT_FALSE(s.axes.empty());
    int checked = 0;
    for (const auto& [name, unit] : s.axes) {
      Eigen::Index a = -1;
      for (std::size_t i = 0; i < job.machine.axes.size(); ++i)
        if (job.machine.axes[i].name == name) a = static_cast<Eigen::Index>(i);
      ASSERT_GE(a, 0) << name;
      const double f = unit == "deg" ? core::units::kRadToDeg : 1.0;
      auto x = [&](Eigen::Index k) { return sp.position(std::clamp<Eigen::Index>(k, 0, ns - 1), a); };
      const std::string u = unit;
      const std::vector<std::pair<std::string, std::function<double(Eigen::Index)>>> defs = {
          {name + "_setpoint_" + u, [&](Eigen::Index k) { return x(k) * f; }},
          {name + "_tracking_error_" + u, [&](Eigen::Index k) { return (x(k) - resp.position(k, a)) * f; }},
          {name + "_velocity_setpoint_" + u + "_per_s", [&](Eigen::Index k) { return (x(k) - x(k - 1)) / te * f; }},
          {name + "_acceleration_setpoint_" + u + "_per_s2",
           [&](Eigen::Index k) { return (x(k) - 2 * x(k - 1) + x(k - 2)) / (te * te) * f; }},
          {name + "_jerk_setpoint_" + u + "_per_s3",
           [&](Eigen::Index k) { return (x(k) - 3 * x(k - 1) + 3 * x(k - 2) - x(k - 3)) / (te * te * te) * f; }},
          {name + "_actual_" + u, [&](Eigen::Index k) { return resp.position(k, a) * f; }},
          {name + "_velocity_actual_" + u + "_per_s", [&](Eigen::Index k) { return resp.velocity(k, a) * f; }},
          {name + "_acceleration_actual_" + u + "_per_s2", [&](Eigen::Index k) { return resp.acceleration(k, a) * f; }},
          {name + "_jerk_actual_" + u + "_per_s3", [&](Eigen::Index k) { return resp.jerk(k, a) * f; }},
          {name + "_current_A", [&](Eigen::Index k) { return resp.current_mean_A(k, a); }},
          {name + "_current_peak_A", [&](Eigen::Index k) { return resp.current_peak_A(k, a); }},
      };
      for (const auto& [col, value] : defs) {
        const int c = s.find(col);
        ASSERT_GE(c, 0) << col;
        const vmsim_test::BinRange ref = vmsim_test::fold_bins_in_row_order(n, s.bin_samples, value);
        ASSERT_EQ(ref.lo.size(), s.bins());
        for (Eigen::Index b = 0; b < s.bins(); ++b) {
          ASSERT_TRUE(vmsim_test::same_double_bits(ref.lo[b], s.min(b, c))) << col << " bin " << b;
          ASSERT_TRUE(vmsim_test::same_double_bits(ref.hi[b], s.max(b, c))) << col << " bin " << b;
        }
        ++checked;
      }
    }
    EXPECT_EQ(checked, 11 * static_cast<int>(s.axes.size()));
  }
}

}  // namespace
