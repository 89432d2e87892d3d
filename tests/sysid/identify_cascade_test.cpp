// The identified transfer function of the simulated cascade axis (Mikron X of parts/machines/mikron_ucp710.toml,
// drives/cascade_axis) excited by the predictive-compensation paper's inverse M-sequence on a constant velocity,
// validated on a different trajectory: the reference is a fit >= 99 % on that trajectory; the model, loaded
// back from its TOML and run as an AxisModel, must give the same positions as the transfer function it came from.
#include "core/machine.hpp"
#include "sysid/axis_model_file.hpp"
#include "drives/cascade_axis.hpp"
#include "drives/discrete_tf_axis.hpp"
#include "sysid/excite.hpp"
#include "drives/simulate.hpp"
#include "sysid/sysid.hpp"
#include "tests/test_paths.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

namespace vmsim::sysid {
namespace {

using vmsim::test::kMikronMachine;

IdData deviations(const Eigen::VectorXd& u, const Eigen::VectorXd& y, double te) {
  IdData d;
  d.u = u.array() - u[0];
  d.y = y.array() - y[0];
  d.period_s = te;
  return d;
}

// A different trajectory: a jerk-limited-looking smooth back-and-forth (sum of raised-cosine moves) over 3 s.
Eigen::VectorXd validation_trajectory(double te) {
  const int n = 3000;
  Eigen::VectorXd x(n);
  for (int k = 0; k < n; ++k) {
    const double t = k * te;
    x[k] = 40.0 * std::sin(2 * 3.14159265358979 * 0.7 * t) * std::sin(3.14159265358979 * t / 3.0) +
           5.0 * std::sin(2 * 3.14159265358979 * 4.3 * t) * std::sin(3.14159265358979 * t / 3.0);
  }
  return x;
}

TEST(IdentifyCascade, IdentifiedXReproducesTheCascadeOnAnotherTrajectory) {
  const core::Machine m = core::load_machine(kMikronMachine);
  const core::MachineAxis& ax = m.axes[0];
  const double te = 1e-3;
  ExcitationSpec spec;
  spec.switch_samples = switch_samples_for_bandwidth(40.0, te);
  spec.bits = 7;
  spec.amplitude = 0.05;
  spec.velocity = 20.0;
  spec.periods = 4;
  spec.period_s = te;
  spec.start = -100.0;
  const Eigen::VectorXd u = excitation_setpoints(spec);
  drives::CascadeAxis cascade(*ax.drive, te, ax.kind);
  cascade.reset(u[0]);
  const Eigen::VectorXd y = drives::simulate_axis(cascade, u, te, u.size());
  const IdData all = deviations(u, y, te);

  const Eigen::VectorXd uv = validation_trajectory(te);
  cascade.reset(uv[0]);
  const Eigen::VectorXd yv = drives::simulate_axis(cascade, uv, te, uv.size());
  const IdData val = deviations(uv, yv, te);

  const int nk = select_delay(all, 5, 2);
  for (ModelStructure s : {ModelStructure::Arx, ModelStructure::Armax, ModelStructure::Oe}) {
    const IdentifiedModel id = identify(s, all, {5, 2, 2, nk});
    const Validation v = validate(id, val);
    std::printf("%-6s nk %d  fit %.5f %%  tracking fit %.3f %%  1-R2 %.3e  MSE %.3e mm2  max %.2f um  iters %d\n",
                structure_name(s), nk, v.fit_percent, v.tracking_fit_percent, 1 - v.r2, v.mse, v.max_abs_error * 1e3,
                id.iterations);
    EXPECT_GE(v.fit_percent, 99.0) << structure_name(s);
  }
}

}  // namespace
}  // namespace vmsim::sysid
