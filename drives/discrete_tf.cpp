#include "drives/discrete_tf.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace vmsim::drives {

double DiscreteTf::static_gain() const { return b.sum() / (1.0 + a.sum()); }

std::vector<std::complex<double>> poles(const Eigen::VectorXd& a) {
  const Eigen::Index n = a.size();
  std::vector<std::complex<double>> out;
  if (n == 0) return out;
  // Companion matrix of z^n + a1 z^(n-1) + ... + a_n: its eigenvalues are the roots.
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(n, n);
  c.row(0) = -a.transpose();
  for (Eigen::Index i = 1; i < n; ++i) c(i, i - 1) = 1.0;
  const Eigen::EigenSolver<Eigen::MatrixXd> es(c, false);
  for (Eigen::Index i = 0; i < n; ++i) out.push_back(es.eigenvalues()[i]);
  return out;
}

double spectral_radius(const Eigen::VectorXd& a) {
  double r = 0.0;
  for (const auto& p : poles(a)) r = std::max(r, std::abs(p));
  return r;
}

Eigen::VectorXd filter_q(const Eigen::VectorXd& num, const Eigen::VectorXd& den, const Eigen::VectorXd& x) {
  const Eigen::Index n = x.size();
  Eigen::VectorXd y(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    double s = 0.0;
    for (Eigen::Index i = 0; i < num.size() && i <= k; ++i) s += num[i] * x[k - i];
    for (Eigen::Index i = 1; i < den.size() && i <= k; ++i) s -= den[i] * y[k - i];
    y[k] = s;
  }
  return y;
}

Eigen::VectorXd simulate_tf(const DiscreteTf& tf, const Eigen::VectorXd& u) {
  Eigen::VectorXd num = Eigen::VectorXd::Zero(tf.nk + tf.nb());
  num.tail(tf.nb()) = tf.b;
  Eigen::VectorXd den(tf.na() + 1);
  den << 1.0, tf.a;
  return filter_q(num, den, u);
}

}  // namespace vmsim::drives
