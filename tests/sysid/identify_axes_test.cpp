// sysid::identify_axes, what `vmsim identify` runs, on position traces simulated here from known discrete transfer
// functions (difference equations written out below, independent of drives/discrete_tf): the reference is the
// systems' own coefficients and delays, and the rules of the data split stated in sysid/identify_axes.hpp (second
// half, held-out last trace, separate trace; each trace its own experiment from its own rest point).
#include "core/error.hpp"
#include "sysid/excite.hpp"
#include "sysid/identify_axes.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace vmsim::sysid {
namespace {

// A known system: y(k) = -a1 y(k-1) - a2 y(k-2) + b1 u(k-nk) + b2 u(k-nk-1), static gain 1 (a position loop).
struct System {
  double a1, a2, b1, b2;
  int nk;
};
const System kX{-1.5, 0.7, 0.1, 0.1, 1};    // poles 0.75 +- 0.37i
const System kA{-1.2, 0.36, 0.1, 0.06, 2};  // a double pole at 0.6, two samples of delay

// An excitation (PRBS steps, +-amplitude, switching every 4 samples) and the system's answer plus white noise: on
// the output (an OE system), or, with `equation_error`, inside the difference equation (an ARX system).
void simulate_axis(const System& s, int n, double amplitude, double noise, unsigned seed, Eigen::VectorXd& u,
                   Eigen::VectorXd& y, bool equation_error = false) {
  const std::vector<int> m = m_sequence(9);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> e(0.0, noise);
  u = Eigen::VectorXd::Zero(n);
  for (int k = 10; k < n; ++k) u[k] = amplitude * (m[static_cast<std::size_t>(k / 4 + seed) % m.size()] ? 1.0 : -1.0);
  Eigen::VectorXd clean = Eigen::VectorXd::Zero(n);
  const auto at = [](const Eigen::VectorXd& v, int k) { return k >= 0 ? v[k] : 0.0; };
  for (int k = 0; k < n; ++k)
    clean[k] = -s.a1 * at(clean, k - 1) - s.a2 * at(clean, k - 2) + s.b1 * at(u, k - s.nk) +
               s.b2 * at(u, k - s.nk - 1) + (equation_error && k > 0 ? e(rng) : 0.0);
  y = clean;
  if (!equation_error)
    for (int k = 1; k < n; ++k) y[k] += e(rng);  // the first sample stays at rest
}

// A trace of axis X (mm, about `x0`) and, with `with_a`, axis A (rad, about 0.5 rad).
PositionTrace make_trace(const std::string& source, int n, double x0, unsigned seed, bool with_a = true,
                         double period_s = 1e-3, bool equation_error = false) {
  PositionTrace t;
  t.source = source;
  t.period_s = period_s;
  t.t_s = Eigen::ArrayXd::LinSpaced(n, 0.0, (n - 1) * period_s);
  t.axes = {"X"};
  t.rotary = {false};
  if (with_a) t.axes.push_back("A"), t.rotary.push_back(true);
  t.command.resize(n, static_cast<Eigen::Index>(t.axes.size()));
  t.actual.resizeLike(t.command);
  Eigen::VectorXd u, y;
  simulate_axis(kX, n, 1.0, 1e-4, seed, u, y, equation_error);
  t.command.col(0) = u.array() + x0;
  t.actual.col(0) = y.array() + x0;
  if (with_a) {
    simulate_axis(kA, n, 0.01, 1e-6, seed + 7, u, y);
    t.command.col(1) = u.array() + 0.5;
    t.actual.col(1) = y.array() + 0.5;
  }
  return t;
}

AxesIdentificationOptions given_orders() {
  AxesIdentificationOptions o;
  o.orders = ModelOrders{2, 2, 2, 1};  // na, nb, nc, nk (nk: found per axis)
  return o;
}

void expect_system(const IdentifiedModel& m, const System& s, double tol, const std::string& what) {
  ASSERT_EQ(m.g.a.size(), 2) << what;
  ASSERT_EQ(m.g.b.size(), 2) << what;
  EXPECT_EQ(m.g.nk, s.nk) << what;
  EXPECT_NEAR(m.g.a[0], s.a1, tol) << what;
  EXPECT_NEAR(m.g.a[1], s.a2, tol) << what;
  EXPECT_NEAR(m.g.b[0], s.b1, tol) << what;
  EXPECT_NEAR(m.g.b[1], s.b2, tol) << what;
}

TEST(IdentifyAxes, OneTraceTwoAxesRecoverTheirSystemsOnTheFirstHalfValidatedOnTheSecond) {
  const int n = 6000;
  const PositionTrace t = make_trace("/data/run.csv", n, -150.0, 3);
  const AxesIdentification r = identify_axes({t}, nullptr, given_orders());

  EXPECT_EQ(r.data.validation, ValidationData::SecondHalf);
  EXPECT_EQ(r.data.estimation_traces, 1u);
  ASSERT_EQ(r.data.axes.size(), 2u);
  const AxisData& x = r.data.axes[0];
  EXPECT_EQ(x.name, "X");
  EXPECT_FALSE(x.rotary);
  EXPECT_TRUE(r.data.axes[1].rotary);
  EXPECT_EQ(x.estimation.u.size(), n / 2);      // the first half estimates
  EXPECT_EQ(x.validation.u.size(), n);          // the model runs over the whole record...
  EXPECT_EQ(x.first_validation_sample, n / 2);  // ...and the second half is counted
  // Deviations from the rest point: the -150 mm offset is gone.
  EXPECT_EQ(x.estimation.u[0], 0.0);
  EXPECT_NEAR(x.estimation.u.cwiseAbs().maxCoeff(), 1.0, 1e-9);
  EXPECT_TRUE(x.starts_at_rest());

  ASSERT_EQ(r.axes.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const AxisIdentification& a = r.axes[i];
    const System& s = i == 0 ? kX : kA;
    EXPECT_EQ(a.orders.nk, s.nk) << a.name << ": the delay with the smallest ARX loss";
    ASSERT_EQ(a.models.size(), 3u);
    for (const ModelResult& m : a.models) {
      // Output noise 1e-4 of the amplitude: every structure lands on the system (OE is consistent, ARX and
      // ARMAX nearly so at this noise), and predicts the held-out half to the noise.
      expect_system(m.model, s, 2e-3, a.name + " " + structure_name(m.model.structure));
      EXPECT_GT(m.validation.fit_percent, 99.9) << a.name;
    }
    // Ranks are the order of the validation MSE, and the chosen model is rank 1.
    for (const ModelResult& m : a.models)
      for (const ModelResult& o : a.models)
        if (m.rank < o.rank) {
          EXPECT_LE(m.validation.mse, o.validation.mse);
        }
    EXPECT_EQ(a.models[a.chosen].rank, 1);
  }
  // The model file: one axis each, the chosen structure, the trace's file name.
  EXPECT_EQ(r.file.trace, "run.csv");
  EXPECT_EQ(r.file.period_s, 1e-3);
  ASSERT_EQ(r.file.axes.size(), 2u);
  EXPECT_EQ(r.file.axes[1].name, "A");
  EXPECT_EQ(r.file.axes[1].structure, r.axes[1].models[r.axes[1].chosen].model.structure);
  EXPECT_EQ(r.file.axes[1].tf.nk, 2);
}

TEST(IdentifyAxes, SeveralTracesAreSeparateExperimentsAndTheLastIsHeldOut) {
  const PositionTrace one = make_trace("/data/one.csv", 3000, 10.0, 1, false);
  const PositionTrace two = make_trace("/data/two.csv", 2500, 50.0, 2, false);
  const PositionTrace three = make_trace("/data/three.csv", 2000, -20.0, 5, false);
  const AxesIdentification r = identify_axes({one, two, three}, nullptr, given_orders());
  EXPECT_EQ(r.data.validation, ValidationData::HeldOutTrace);
  EXPECT_EQ(r.data.estimation_traces, 2u);
  const AxisData& x = r.data.axes.at(0);
  EXPECT_EQ(x.estimation.u.size(), 5500);
  ASSERT_EQ(x.estimation.starts.size(), 2u);
  EXPECT_EQ(x.estimation.starts[1], 3000);
  EXPECT_EQ(x.estimation.u[3000], 0.0) << "the second trace from its own rest point (50 mm), not the first's";
  EXPECT_EQ(x.validation.u.size(), 2000);
  EXPECT_EQ(x.first_validation_sample, 0);
  EXPECT_EQ(r.file.trace, "one.csv, two.csv");
  for (const ModelResult& m : r.axes.at(0).models) expect_system(m.model, kX, 2e-3, structure_name(m.model.structure));

  // A separate validation trace: every trace estimates.
  const PositionTrace val = make_trace("/data/val.csv", 2000, 0.0, 9, false);
  const IdentificationData d = prepare_identification({one, two}, &val, given_orders());
  EXPECT_EQ(d.validation, ValidationData::SeparateTrace);
  EXPECT_EQ(d.estimation_traces, 2u);
  EXPECT_EQ(d.axes.at(0).estimation.u.size(), 5500);
  EXPECT_EQ(d.axes.at(0).validation.u.size(), 2000);
}

TEST(IdentifyAxes, UseOverridesTheRankingAndBicFindsTheOrders) {
  const PositionTrace t = make_trace("run.csv", 6000, 0.0, 4, false);
  AxesIdentificationOptions o = given_orders();
  o.use = ModelStructure::Arx;
  o.delay = 1;
  const AxesIdentification r = identify_axes({t}, nullptr, o);
  EXPECT_EQ(r.axes[0].models[r.axes[0].chosen].model.structure, ModelStructure::Arx);
  EXPECT_EQ(r.file.axes[0].structure, ModelStructure::Arx);

  // Orders by BIC over ARX fits, on an ARX system: the true na 2, nb 2, nk 1; nc as given.
  const PositionTrace arx = make_trace("arx.csv", 6000, 0.0, 4, false, 1e-3, true);
  o = AxesIdentificationOptions{};
  o.orders.reset();
  o.nc = 3;
  o.structures = {ModelStructure::Arx};
  const AxisIdentification a = identify_axes({arx}, nullptr, o).axes.at(0);
  EXPECT_EQ(a.orders.na, 2);
  EXPECT_EQ(a.orders.nb, 2);
  EXPECT_EQ(a.orders.nk, 1);
  EXPECT_EQ(a.orders.nc, 3);
}

TEST(IdentifyAxes, ATraceNotAtRestIsReported) {
  PositionTrace t = make_trace("run.csv", 2000, 0.0, 6);
  t.actual(1, 0) += 0.01;                             // X: the encoder moves 10 um within the first samples
  t.actual(1, 1) += 0.5e-3 * 3.14159265358979 / 180;  // A: half a thousandth of a degree, within the tolerance
  const IdentificationData d = prepare_identification({t}, nullptr, given_orders());
  EXPECT_FALSE(d.axes[0].starts_at_rest());
  EXPECT_TRUE(d.axes[0].estimation.initial_state_estimated);
  EXPECT_TRUE(d.axes[1].starts_at_rest());
  EXPECT_FALSE(d.axes[1].estimation.initial_state_estimated);
}

// A capture that starts mid-motion: kX driven by PRBS steps riding a slow sine (the axis never stops) from long
// before the capture starts, the first `cut` samples dropped, the encoder reading `offset` above the command at
// rest. With `hold` the command stops for 400 samples in the middle (a still stretch the rest offset is measured on).
PositionTrace moving_trace(int n, int cut, double offset, bool hold, unsigned seed) {
  const std::vector<int> m = m_sequence(9);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> e(0.0, 1e-4);
  const int total = n + cut;
  Eigen::VectorXd u(total), y = Eigen::VectorXd::Zero(total);
  for (int k = 0; k < total; ++k) {
    u[k] = 5.0 * std::sin(2 * 3.14159265358979 * k / 1500.0) + (m[static_cast<std::size_t>(k / 4) % m.size()] ? 1 : -1);
    if (hold && k >= cut + n / 2 && k < cut + n / 2 + 400) u[k] = u[cut + n / 2 - 1];
  }
  for (int k = 2; k < total; ++k) y[k] = -kX.a1 * y[k - 1] - kX.a2 * y[k - 2] + kX.b1 * u[k - 1] + kX.b2 * u[k - 2];
  PositionTrace t;
  t.source = "moving.csv";
  t.period_s = 1e-3;
  t.t_s = Eigen::ArrayXd::LinSpaced(n, 0.0, (n - 1) * 1e-3);
  t.axes = {"X"};
  t.rotary = {false};
  t.command = (u.tail(n).array() + 40.0).matrix();
  t.actual.resize(n, 1);
  for (int k = 0; k < n; ++k) t.actual(k, 0) = y[cut + k] + 40.0 + offset + e(rng);
  return t;
}

TEST(IdentifyAxes, ATraceStartingMidMotionIsIdentifiedWithItsInitialStateAndRestOffset) {
  // Reference: kX's own coefficients. The old rule (the first sample taken as the rest point of both signals)
  // is shown for comparison: it misses them.
  const double offset = 0.005;  // mm, as the halscope captures' encoder at rest
  const PositionTrace t = moving_trace(6000, 777, offset, true, 11);
  AxesIdentificationOptions o = given_orders();
  o.delay = 1;
  const AxesIdentification r = identify_axes({t}, nullptr, o);
  const AxisData& x = r.data.axes.at(0);
  EXPECT_FALSE(x.starts_at_rest());
  EXPECT_NEAR(x.rest_offset, offset, 2e-4);  // the still stretch: the system settled, noise 1e-4
  EXPECT_NE(x.rest_offset_from.find("the still stretch at t = 3"), std::string::npos) << x.rest_offset_from;
  for (const ModelResult& m : r.axes.at(0).models) {
    expect_system(m.model, kX, 5e-3, std::string("estimated initial state: ") + structure_name(m.model.structure));
    EXPECT_GT(m.validation.fit_percent, 99.9) << structure_name(m.model.structure);
    EXPECT_FALSE(m.marginal);
  }

  // The rest offset given by the user instead (no still stretch in this capture).
  const PositionTrace moving = moving_trace(6000, 500, offset, false, 12);
  o.rest_offsets["X"] = offset;
  const AxesIdentification g = identify_axes({moving}, nullptr, o);
  EXPECT_EQ(g.data.axes.at(0).rest_offset_from, "--rest-offset");
  for (const ModelResult& m : g.axes.at(0).models)
    expect_system(m.model, kX, 5e-3, std::string("given rest offset: ") + structure_name(m.model.structure));

  // Neither given nor measurable (no still stretch): taken as 0, and every structure estimates the constant itself
  // (here 50 um: an axis resting against friction under a proportional loop).
  o.rest_offsets.clear();
  const AxesIdentification none = identify_axes({moving_trace(6000, 500, 0.05, false, 13)}, nullptr, o);
  EXPECT_EQ(none.data.axes.at(0).rest_offset, 0.0);
  EXPECT_NE(none.data.axes.at(0).rest_offset_from.find("none"), std::string::npos);
  for (const ModelResult& m : none.axes.at(0).models) {
    expect_system(m.model, kX, 5e-3, std::string("offset estimated: ") + structure_name(m.model.structure));
    EXPECT_GT(m.validation.fit_percent, 99.9) << structure_name(m.model.structure);
  }

  // The old rule on the same capture: deviations from each signal's first sample, the model started from rest.
  AxisData old = g.data.axes.at(0);
  const auto first_sample = [&](IdData& d, const PositionTrace& tr, Eigen::Index from, Eigen::Index len) {
    d.u = tr.command.col(0).segment(from, len).array() - tr.command(0, 0);
    d.y = tr.actual.col(0).segment(from, len).array() - tr.actual(0, 0);
    d.initial_state_estimated = false;
  };
  first_sample(old.estimation, moving, 0, 3000);
  first_sample(old.validation, moving, 0, 6000);
  const IdentifiedModel oe_old = identify_oe(old.estimation, {2, 2, 0, 1});
  const double pole_error_old = std::abs(oe_old.g.a[0] - kX.a1) + std::abs(oe_old.g.a[1] - kX.a2);
  const IdentifiedModel& oe_new = g.axes.at(0).models.at(2).model;
  const double pole_error_new = std::abs(oe_new.g.a[0] - kX.a1) + std::abs(oe_new.g.a[1] - kX.a2);
  EXPECT_GT(pole_error_old, 10 * pole_error_new) << "old " << pole_error_old << ", new " << pole_error_new;
}

TEST(IdentifyAxes, MarginalModelsRankLast) {
  // The rule on its own: a marginal model with the smaller MSE ranks after a stable one.
  EXPECT_TRUE(is_marginal({Eigen::VectorXd::Constant(1, -1.0), Eigen::VectorXd::Ones(1), 1, 1e-3}));  // pole at 1
  EXPECT_TRUE(is_marginal({Eigen::VectorXd::Constant(1, -(1.0 - 1e-5)), Eigen::VectorXd::Ones(1), 1, 1e-3}));
  EXPECT_TRUE(is_marginal({Eigen::VectorXd::Constant(1, -1.01), Eigen::VectorXd::Ones(1), 1, 1e-3}));
  EXPECT_FALSE(is_marginal({Eigen::VectorXd::Constant(1, -0.99), Eigen::VectorXd::Ones(1), 1, 1e-3}));
  std::vector<ModelResult> models(3);
  models[0].validation.mse = 1.0, models[0].marginal = true;
  models[1].validation.mse = 2.0;
  models[2].validation.mse = NAN;
  rank_models(models);
  EXPECT_EQ(models[1].rank, 1);
  EXPECT_EQ(models[0].rank, 2);
  EXPECT_EQ(models[2].rank, 3);

  // An integrating axis (a velocity-commanded drive read as position: y(k) = y(k-1) + 0.1 u(k-1)): every model
  // has its pole on the unit circle and is flagged, whatever --orders chose.
  PositionTrace t = make_trace("integrator.csv", 4000, 0.0, 3, false);
  const Eigen::VectorXd u = t.command.col(0);
  for (Eigen::Index k = 1; k < u.size(); ++k) t.actual(k, 0) = t.actual(k - 1, 0) + 0.1 * u[k - 1];
  AxesIdentificationOptions o;
  o.orders.reset();
  const AxisIdentification a = identify_axes({t}, nullptr, o).axes.at(0);
  for (const ModelResult& m : a.models) EXPECT_TRUE(m.marginal) << structure_name(m.model.structure);
}

TEST(IdentifyAxes, InconsistentInputIsAnErrorNamingTheTrace) {
  const PositionTrace one = make_trace("/data/one.csv", 2000, 0.0, 1);
  const PositionTrace slow = make_trace("/data/slow.csv", 2000, 0.0, 2, true, 2e-3);
  try {
    prepare_identification({one, slow}, nullptr, given_orders());
    ADD_FAILURE() << "traces sampled at different periods were accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/data/slow.csv: sampled every 0.002 s, /data/one.csv every 0.001 s"),
              std::string::npos)
        << e.what();
  }
  try {
    prepare_identification({one}, &slow, given_orders());
    ADD_FAILURE() << "a validation trace at another period was accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/data/slow.csv"), std::string::npos) << e.what();
  }
  AxesIdentificationOptions o = given_orders();
  o.axes = {"X", "Y"};
  try {
    prepare_identification({one}, nullptr, o);
    ADD_FAILURE() << "an axis the trace lacks was accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/data/one.csv: --axis Y: the trace has no columns for it"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(prepare_identification({}, nullptr, given_orders()), core::Error);
  o = given_orders();
  o.structures = {ModelStructure::Arx};
  o.use = ModelStructure::Oe;
  EXPECT_THROW(identify_axes({one}, nullptr, o), core::Error);
}

}  // namespace
}  // namespace vmsim::sysid
