// sysid::excitation_for_axis and simulate_excitation, what `vmsim excite` runs, on the Mikron UCP 710 of
// parts/machines. References: the predictive-compensation paper's eq. 11-12 and 14-15 evaluated here from their
// definitions (the bandwidth 0.433 / Td must cover the axis's, the signal period must resolve the frequency asked for);
// the axis's travel read from the machine file; a position loop with integral action ends at rest on its last setpoint.
#include "core/error.hpp"
#include "core/machine.hpp"
#include "sysid/excite_axis.hpp"
#include "tests/test_paths.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace vmsim::sysid {
namespace {

using vmsim::test::kMikronMachine;

const core::MachineAxis& axis(const core::Machine& m, const std::string& name) {
  for (const auto& a : m.axes)
    if (a.name == name) return a;
  throw core::Error("no axis " + name);
}

TEST(ExciteAxis, TdAndRegisterLengthFollowTheBandwidthAndResolutionAndTheSignalIsCentred) {
  const core::Machine m = core::load_machine(kMikronMachine);
  const core::MachineAxis& x = axis(m, "X");
  AxisExcitationOptions o;
  o.bandwidth_hz = 40.0;
  o.resolution_hz = 1.0;
  o.amplitude = 0.05;
  o.velocity = 20.0;  // 1200 mm/min
  o.periods = 4;
  const AxisExcitation e = excitation_for_axis(x, o);
  // Eq. 14-15: the largest q with 0.433 / (q Te) >= 40 Hz.
  int q = 1;
  while (0.433 / ((q + 1) * o.period_s) >= o.bandwidth_hz) ++q;
  EXPECT_EQ(e.spec.switch_samples, q);
  EXPECT_EQ(q, 10);
  // Eq. 11-12, inverse M-sequence: the smallest n with 2 (2^n - 1) Td >= 1 / resolution.
  int n = 2;
  while (2 * (std::ldexp(1.0, n) - 1) * q * o.period_s < 1.0 / o.resolution_hz) ++n;
  EXPECT_EQ(e.spec.bits, n);
  // Centred in X's travel (-355 .. 355 mm): the ramp's ends are symmetric about the travel's middle.
  const Eigen::VectorXd& s = e.setpoints;
  EXPECT_NEAR(s[0] + s[s.size() - 1], x.travel_min + x.travel_max, 1e-9);
  EXPECT_GT(s[s.size() - 1] - s[0], 0.0);
  EXPECT_NEAR(s.maxCoeff() - s.minCoeff(), s[s.size() - 1] - s[0] + 2 * o.amplitude, 0.5);

  // A given start and Td; a continuous table (C) has no travel to centre in: it starts at 0.
  o.start = -100.0;
  o.switch_samples = 3;
  o.bits = 5;
  const AxisExcitation g = excitation_for_axis(x, o);
  EXPECT_EQ(g.setpoints[0], -100.0);
  EXPECT_EQ(g.spec.switch_samples, 3);
  EXPECT_EQ(g.spec.bits, 5);
  o.start.reset();
  EXPECT_EQ(excitation_for_axis(axis(m, "C"), o).setpoints[0], 0.0);
}

TEST(ExciteAxis, ASignalOutsideTheTravelIsRefused) {
  const core::Machine m = core::load_machine(kMikronMachine);
  AxisExcitationOptions o;
  o.velocity = 500.0;  // 30 m/min for 50 periods: far beyond 710 mm
  o.periods = 50;
  try {
    excitation_for_axis(axis(m, "X"), o);
    ADD_FAILURE() << "an excitation beyond the travel was accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("outside axis X's travel -355.0000 .. 355.0000"), std::string::npos)
        << e.what();
  }
}

TEST(ExciteAxis, TheSimulatedTraceHoldsTheLastSetpointAndEndsAtRestOnIt) {
  const core::Machine m = core::load_machine(kMikronMachine);
  AxisExcitationOptions o;
  o.switch_samples = 5;
  o.bits = 6;
  o.velocity = 20.0;
  o.periods = 2;
  const AxisExcitation e = excitation_for_axis(axis(m, "X"), o);
  const PositionTrace t = simulate_excitation(axis(m, "X"), e, kMikronMachine);
  const Eigen::Index n = e.setpoints.size(), rows = n + 100;  // 0.1 s past the end at Te = 1 ms
  ASSERT_EQ(t.t_s.size(), rows);
  ASSERT_EQ(t.command.rows(), rows);
  EXPECT_EQ(t.axes, std::vector<std::string>{"X"});
  EXPECT_DOUBLE_EQ(t.t_s[rows - 1], (rows - 1) * 1e-3);
  EXPECT_EQ(t.command(0, 0), e.setpoints[0]);
  EXPECT_EQ(t.command(rows - 1, 0), e.setpoints[n - 1]);
  EXPECT_EQ(t.actual(0, 0), e.setpoints[0]) << "from rest at the first setpoint";
  EXPECT_NEAR(t.actual(rows - 1, 0), e.setpoints[n - 1], 1e-4) << "the loop settles on the last setpoint";
  // While the signal plays the axis follows it, but not exactly: the trace carries the dynamics to identify.
  const double lag = (t.command.col(0) - t.actual.col(0)).cwiseAbs().maxCoeff();
  EXPECT_GT(lag, 1e-3);
  EXPECT_LT(lag, 1.0);

  // An axis without [axes.drive] cannot be simulated; the message names the machine file.
  core::MachineAxis bare = axis(m, "X");
  bare.drive.reset();
  try {
    simulate_excitation(bare, e, "machine.toml");
    ADD_FAILURE() << "an axis without a drive was simulated";
  } catch (const core::Error& err) {
    EXPECT_NE(std::string(err.what()).find("machine.toml: axis X has no [axes.drive]"), std::string::npos)
        << err.what();
  }
}

}  // namespace
}  // namespace vmsim::sysid
