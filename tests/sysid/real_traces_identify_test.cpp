// Identification on real servo traces (../shared/data/real/traces, README.md there; skipped with a message when
// absent), fitted on one capture and validated on the others, against figures from outside vmsim:
// - EMPS (Janot, Gautier & Brunot, "Data Set and Reference Models of EMPS", Workshop on Nonlinear System
//   Identification Benchmarks 2019). Section 3.6: the whole closed loop from the reference qg to the measured
//   position qm as a second-order structure gives a relative error 100 |y - yhat| / |y| (eq. 11) of 0.005 %. And
//   the closed loop the description's own model implies: M qdd + Fv qd = gtau nu, nu = kv (kp (qr - q) - qd)
//   (eq. 1, 6, 7 with the IDIM-LS M = 95.1089 kg, Fv = 203.5034 N s/m, gtau = 35.15 N/V, kp = 160.18 1/s,
//   kv = 243.45 V s/m): s^2 + (Fv + kv gtau)/M s + kp kv gtau / M, whose poles the second-order fit must find.
//   Both captures start mid-motion (qg = 0.108 mm and moving at the first sample).
// - LinuxCNC halscope captures of a mill's X axis: the controller's own following error pin (joint.0.f-error, the
//   previous cycle's motor-pos-cmd less the feedback) checks the channels the reader picks; the model fitted on one
//   capture predicts the following error of the three others.
#include "sysid/identify_axes.hpp"
#include "sysid/trace_formats.hpp"

#include "drives/discrete_tf.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <filesystem>

namespace vmsim::sysid {
namespace {

namespace fs = std::filesystem;

fs::path traces_dir() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "traces"; }

#define REQUIRE_REAL(path) \
  if (!fs::exists(path)) GTEST_SKIP() << (path).string() << " is absent: the real traces of ../shared are not here"

PositionTrace emps(const char* name) {
  TraceChannels ch;
  ch.variables = parse_mat_variables("t=t,command=qg,actual=qm");
  ch.unit = "m";
  return read_position_trace(traces_dir() / "emps" / name, ch);
}

TEST(RealTraces, EmpsSecondOrderClosedLoopMatchesThePublishedFitAndModel) {
  REQUIRE_REAL(traces_dir() / "emps");
  const PositionTrace est = emps("DATA_EMPS.mat"), val = emps("DATA_EMPS_PULSES.mat");
  AxesIdentificationOptions o;
  o.orders = ModelOrders{2, 2, 2, 1};  // nb 2, na 2: the benchmark's second-order structure
  // On the estimation record itself (the published figure is a fit of that record).
  const AxesIdentification self = identify_axes({est}, &est, o);
  const AxisData& d = self.data.axes.at(0);
  EXPECT_FALSE(d.starts_at_rest());
  EXPECT_TRUE(d.estimation.initial_state_estimated);
  for (const ModelResult& m : self.axes.at(0).models) {
    SCOPED_TRACE(structure_name(m.model.structure));
    EXPECT_LT(m.validation.relative_error_percent, 1.5 * 0.005);
    EXPECT_FALSE(m.marginal);
    EXPECT_NEAR(m.model.g.static_gain(), 1.0, 1e-3);  // PD loop on an integrator: type 1
    // The poles of the description's closed loop, discretised at 1 ms (z = exp(s Te)).
    const double M = 95.1089, Fv = 203.5034, gtau = 35.15065188, kp = 160.18, kv = 243.45;
    const double a1 = (Fv + kv * gtau) / M, a0 = kp * kv * gtau / M;
    const std::complex<double> s(-a1 / 2, std::sqrt(a0 - a1 * a1 / 4));
    const std::complex<double> z = std::exp(s * 1e-3);
    const std::vector<std::complex<double>> p = drives::poles(m.model.g.a);
    ASSERT_EQ(p.size(), 2u);
    // Natural frequency |ln z| / Te and damping of the fitted pair against the model's (120 rad/s, 0.38).
    const std::complex<double> sf = std::log(p[0]) / 1e-3;
    EXPECT_NEAR(std::abs(sf), std::abs(s), 0.15 * std::abs(s)) << "fitted s = " << sf << ", model s = " << s;
    // Damping: the linear model leaves out the Coulomb friction (Fc = 20.4 N against (Fv + kv gtau) |v| = 8.8 kN
    // s/m |v|), which damps the real loop further at low speed; the fitted damping is checked to within 0.15.
    EXPECT_NEAR(-sf.real() / std::abs(sf), -s.real() / std::abs(s), 0.15) << "fitted s = " << sf << ", z " << z;
  }
  // Held out: the capture with force pulses. The benchmark's reference model reaches 0.008 % there because it is
  // given the pulses as an input; a model from qg to qm sees them as unmeasured disturbances.
  const AxesIdentification held = identify_axes({est}, &val, o);
  for (const ModelResult& m : held.axes.at(0).models) {
    EXPECT_LT(m.validation.relative_error_percent, 0.1) << structure_name(m.model.structure);
    EXPECT_GT(m.validation.fit_percent, 99.9) << structure_name(m.model.structure);
  }
}

TEST(RealTraces, HalscopeModelFromOneCapturePredictsTheOthersFollowingError) {
  REQUIRE_REAL(traces_dir() / "linuxcnc_halscope");
  const fs::path dir = traces_dir() / "linuxcnc_halscope";
  std::vector<PositionTrace> caps;
  for (const char* n : {"halscope.log", "halscope2.log", "halscope3.log", "halscope4.log"}) {
    caps.push_back(read_position_trace(dir / n));
    // The controller's following error pin is the previous cycle's command less this cycle's feedback (LinuxCNC's
    // motion module computes it before it updates motor-pos-cmd): the channels picked are the controller's.
    const HalscopeLog log = read_halscope_log(dir / n);
    const auto& ferr = log.values.at(0);
    ASSERT_EQ(log.pins.at(0), "joint.0.f-error");
    const PositionTrace& t = caps.back();
    for (Eigen::Index k = 1; k < t.t_s.size(); ++k)
      ASSERT_NEAR(t.command(k - 1, 0) - t.actual(k, 0), ferr[static_cast<std::size_t>(k)], 1e-9)
          << n << " sample " << k;
  }
  const AxesIdentificationOptions o;  // nb 2, na 5 (the predictive-compensation paper)
  for (std::size_t v = 1; v < caps.size(); ++v) {
    SCOPED_TRACE(caps[v].source);
    const AxesIdentification r = identify_axes({caps[0]}, &caps[v], o);
    EXPECT_TRUE(r.data.axes.at(0).starts_at_rest());
    const ModelResult& chosen = r.axes.at(0).models.at(r.axes.at(0).chosen);
    EXPECT_FALSE(chosen.marginal);
    EXPECT_NEAR(chosen.model.g.static_gain(), 1.0, 1e-3);
    // The following error (up to 0.48 mm on these moves) predicted to within 5 % of its variation.
    EXPECT_GT(chosen.validation.tracking_fit_percent, 95.0);
    std::printf("held out %s: %s fit %.4f %%, tracking fit %.3f %%, rms %.3g um, largest pole %.5f\n",
                fs::path(caps[v].source).filename().c_str(), structure_name(chosen.model.structure),
                chosen.validation.fit_percent, chosen.validation.tracking_fit_percent,
                std::sqrt(chosen.validation.mse) * 1e3, drives::spectral_radius(chosen.model.g.a));
  }
}

}  // namespace
}  // namespace vmsim::sysid
