// Prediction-error identification (drives/sysid) on systems whose coefficients are known: data simulated here from
// the true ARX, ARMAX and OE models (Ljung, System Identification, 2nd ed., sections 7.3, 7.5, 10.4: the true
// parameters are recovered as N grows; the tolerances below are about 5 standard errors at these N and noise
// levels), and the excitation signals of the predictive-compensation paper eq. 8-9 against their defining properties.
#include "drives/discrete_tf.hpp"
#include "sysid/excite.hpp"
#include "sysid/sysid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace vmsim::sysid {
namespace {

Eigen::VectorXd prbs_input(int n) {
  const std::vector<int> m = m_sequence(10);
  Eigen::VectorXd u(n);
  for (int k = 0; k < n; ++k) u[k] = m[static_cast<std::size_t>(k) % m.size()] ? 1.0 : -1.0;
  return u;
}

Eigen::VectorXd white(int n, double sigma, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> nd(0.0, sigma);
  Eigen::VectorXd e(n);
  for (int k = 0; k < n; ++k) e[k] = nd(rng);
  return e;
}

Eigen::VectorXd poly(std::initializer_list<double> c) {
  Eigen::VectorXd p(static_cast<Eigen::Index>(c.size()));
  Eigen::Index i = 0;
  for (double v : c) p[i++] = v;
  return p;
}

TEST(Excite, MSequenceHasMaximalPeriodAndBalance) {
  for (int n = 2; n <= 16; ++n) {
    const std::vector<int> m = m_sequence(n);
    ASSERT_EQ(m.size(), (std::size_t{1} << n) - 1);
    // A maximal-length sequence has 2^(n-1) ones and 2^(n-1) - 1 zeros, and no shorter period.
    int ones = 0;
    for (int b : m) ones += b;
    EXPECT_EQ(ones, 1 << (n - 1)) << "n = " << n;
    for (std::size_t p = 1; p < m.size(); ++p) {
      if (m.size() % p != 0) continue;
      bool periodic = true;
      for (std::size_t k = 0; k + p < m.size() && periodic; ++k) periodic = m[k] == m[k + p];
      EXPECT_FALSE(periodic) << "n = " << n << " repeats every " << p;
    }
  }
}

TEST(Excite, InverseMSequenceHasNoDc) {
  const std::vector<int> im = inverse_m_sequence(7);
  ASSERT_EQ(im.size(), 2u * 127u);
  int ones = 0;
  for (int b : im) ones += b;
  EXPECT_EQ(ones, 127);
  // Eq. 14-15 at the predictive-compensation paper's own numbers: f_s = 500 Hz, B = 100 Hz -> Td = 2 samples.
  EXPECT_EQ(switch_samples_for_bandwidth(100.0, 1.0 / 500.0), 2);
  EXPECT_EQ(bits_for_resolution(10.0, 2.0 / 500.0, true), 4);  // the predictive-compensation paper: "a 4-bit register"
}

TEST(Sysid, ArxRecoversKnownSystem) {
  const int n = 4000;
  const Eigen::VectorXd a0 = poly({1.0, -1.5, 0.7}), b0 = poly({0.0, 1.0, 0.5});
  IdData d;
  d.u = prbs_input(n);
  d.y = drives::filter_q(b0, a0, d.u) + drives::filter_q(poly({1.0}), a0, white(n, 0.05, 1));
  const IdentifiedModel m = identify_arx(d, {2, 2, 0, 1});
  EXPECT_NEAR(m.g.a[0], -1.5, 0.005);
  EXPECT_NEAR(m.g.a[1], 0.7, 0.005);
  EXPECT_NEAR(m.g.b[0], 1.0, 0.005);
  EXPECT_NEAR(m.g.b[1], 0.5, 0.01);
  EXPECT_NEAR(m.loss / (0.05 * 0.05), 1.0, 0.05);
}

TEST(Sysid, ArmaxRecoversKnownSystem) {
  const int n = 8000;
  const Eigen::VectorXd a0 = poly({1.0, -1.5, 0.7}), b0 = poly({0.0, 1.0, 0.5}), c0 = poly({1.0, -0.6, 0.2});
  IdData d;
  d.u = prbs_input(n);
  d.y = drives::filter_q(b0, a0, d.u) + drives::filter_q(c0, a0, white(n, 0.1, 2));
  const IdentifiedModel m = identify_armax(d, {2, 2, 2, 1});
  EXPECT_NEAR(m.g.a[0], -1.5, 0.01);
  EXPECT_NEAR(m.g.a[1], 0.7, 0.01);
  EXPECT_NEAR(m.g.b[0], 1.0, 0.01);
  EXPECT_NEAR(m.g.b[1], 0.5, 0.02);
  EXPECT_NEAR(m.c[0], -0.6, 0.05);
  EXPECT_NEAR(m.c[1], 0.2, 0.05);
  EXPECT_NEAR(m.loss / (0.1 * 0.1), 1.0, 0.05);
  // ARX on the same data is biased by the coloured noise: ARMAX must do better on a.
  const IdentifiedModel arx = identify_arx(d, {2, 2, 0, 1});
  EXPECT_GT(std::abs(arx.g.a[0] + 1.5), std::abs(m.g.a[0] + 1.5));
}

TEST(Sysid, OeRecoversKnownSystemAtTheNoiseFloor) {
  const int n = 8000;
  const Eigen::VectorXd f0 = poly({1.0, -1.5, 0.7}), b0 = poly({0.0, 0.0, 1.0, 0.5});  // nk = 2
  IdData d;
  d.u = prbs_input(n);
  const double sigma = 0.5;
  d.y = drives::filter_q(b0, f0, d.u) + white(n, sigma, 3);
  const IdentifiedModel m = identify_oe(d, {2, 2, 0, 2});
  EXPECT_NEAR(m.g.a[0], -1.5, 0.01);
  EXPECT_NEAR(m.g.a[1], 0.7, 0.01);
  EXPECT_NEAR(m.g.b[0], 1.0, 0.03);
  EXPECT_NEAR(m.g.b[1], 0.5, 0.03);
  EXPECT_NEAR(m.loss / (sigma * sigma), 1.0, 0.05);  // the issue: within 5 % of the noise variance
  // ARX on output-error data is biased (Ljung section 8.3 for the equation-error/output-error mismatch): its
  // simulation error stays well above the noise floor.
  const IdentifiedModel arx = identify_arx(d, {2, 2, 0, 2});
  const double arx_sim = (d.y - drives::simulate_tf(arx.g, d.u)).squaredNorm() / n;
  EXPECT_GT(arx_sim, 1.2 * m.loss);
}

TEST(Sysid, BicFindsTheTrueOrdersAndDelay) {
  const int n = 4000;
  const Eigen::VectorXd a0 = poly({1.0, -1.5, 0.7}), b0 = poly({0.0, 0.0, 0.0, 1.0, 0.5});  // nk = 3
  IdData d;
  d.u = prbs_input(n);
  d.y = drives::filter_q(b0, a0, d.u) + drives::filter_q(poly({1.0}), a0, white(n, 0.05, 4));
  const ModelOrders o = select_orders_bic(d, {6, 3, 5});
  EXPECT_EQ(o.na, 2);
  EXPECT_EQ(o.nb, 2);
  EXPECT_EQ(o.nk, 3);
  EXPECT_EQ(select_delay(d, 2, 2), 3);
}

TEST(Sysid, ValidationFiguresFollowTheirDefinitions) {
  const int n = 2000;
  const Eigen::VectorXd a0 = poly({1.0, -1.5, 0.7}), b0 = poly({0.0, 1.0, 0.5});
  IdData d;
  d.u = prbs_input(n);
  d.y = drives::filter_q(b0, a0, d.u) + white(n, 0.01, 5);
  IdentifiedModel m;
  m.structure = ModelStructure::Oe;
  m.g.a = poly({-1.5, 0.7});
  m.g.b = poly({1.0, 0.5});
  const Validation v = validate(m, d);
  const Eigen::VectorXd e = d.y - drives::simulate_tf(m.g, d.u);
  const double ybar = d.y.mean();
  EXPECT_NEAR(v.mse, e.squaredNorm() / n, 1e-15);
  EXPECT_NEAR(v.r2, 1.0 - e.squaredNorm() / (d.y.array() - ybar).square().sum(), 1e-12);
  EXPECT_NEAR(v.fit_percent, 100.0 * (1.0 - e.norm() / (d.y.array() - ybar).matrix().norm()), 1e-9);
  EXPECT_TRUE(v.white);  // the residual of the true OE model is the white noise added
}

// Several experiments (IdData::starts): each record starts from rest, the first ends in motion. Both are simulated
// noise-free from a known system, each from zero state. With the boundary respected, ARX and OE recover the system to
// rounding (without noise an OE system is also an ARX system). Gluing the records into one experiment (no starts)
// lets the second record's first rows regress on the first record's last samples, which the system never saw, and the
// estimate moves off the truth. Reference: the true coefficients.
TEST(Sysid, SeveralExperimentsAreNotMixedAcrossTheirBoundary) {
  drives::DiscreteTf g;
  g.a = poly({-1.5, 0.7});
  g.b = poly({0.12, 0.08});
  g.nk = 1;
  const int n1 = 1500, n2 = 1200;
  IdData e1, e2;
  e1.u = prbs_input(n1) + Eigen::VectorXd::LinSpaced(n1, 0.0, 30.0);  // ends far from rest, in motion
  e2.u = -prbs_input(n2);
  e1.y = drives::simulate_tf(g, e1.u);
  e2.y = drives::simulate_tf(g, e2.u);
  const IdData both = concatenate({e1, e2});
  ASSERT_EQ(both.starts, (std::vector<Eigen::Index>{0, n1}));
  ModelOrders o;
  o.na = 2;
  o.nb = 2;
  o.nk = 1;
  for (ModelStructure s : {ModelStructure::Arx, ModelStructure::Oe}) {
    const IdentifiedModel m = identify(s, both, o);
    EXPECT_NEAR(m.g.a[0], -1.5, 1e-7) << structure_name(s);
    EXPECT_NEAR(m.g.a[1], 0.7, 1e-7) << structure_name(s);
    EXPECT_NEAR(m.g.b[0], 0.12, 1e-7) << structure_name(s);
    EXPECT_NEAR(m.g.b[1], 0.08, 1e-7) << structure_name(s);
  }
  IdData glued = both;
  glued.starts.clear();
  const IdentifiedModel naive = identify_arx(glued, o);
  EXPECT_GT(std::abs(naive.g.a[1] - 0.7) + std::abs(naive.g.b[0] - 0.12), 1e-5)
      << "the glued records should have biased the estimate (else this test shows nothing)";
  // A record too short for the orders is an error naming it.
  IdData tiny;
  tiny.u = poly({1.0, 2.0});
  tiny.y = poly({0.0, 1.0});
  try {
    (void)identify_arx(concatenate({e1, tiny}), o);
    ADD_FAILURE() << "expected an error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("experiment 2"), std::string::npos) << e.what();
  }
}

TEST(Sysid, BadOrdersAreErrors) {
  IdData d;
  d.u = prbs_input(500);
  d.y = d.u;
  EXPECT_THROW(identify_arx(d, {2, 0, 0, 1}), std::runtime_error);
  EXPECT_THROW(identify_arx(d, {2, 2, 0, 0}), std::runtime_error);
  EXPECT_THROW(identify_oe(d, {30, 30, 0, 1}), std::runtime_error);  // 60 parameters from 500 samples
  d.u.setConstant(1.0);
  EXPECT_THROW(identify_arx(d, {2, 2, 0, 1}), std::runtime_error);
}

}  // namespace
}  // namespace vmsim::sysid
