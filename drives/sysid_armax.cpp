// ARMAX: extended least squares (the pseudo-linear regression with past residuals, Ljung section 7.5) for a start,
// then Levenberg-Marquardt on the one-step prediction error eps = (A y - B q^-nk u) / C (Ljung section 10.2).
#include "drives/sysid_detail.hpp"

namespace vmsim::drives {

namespace {

Eigen::VectorXd delayed(const Eigen::VectorXd& x, Eigen::Index shift) {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(x.size());
  if (shift < x.size()) out.tail(x.size() - shift) = x.head(x.size() - shift);
  return out;
}

Eigen::VectorXd monic(const Eigen::VectorXd& tail) {
  Eigen::VectorXd p(tail.size() + 1);
  p << 1.0, tail;
  return p;
}

Eigen::VectorXd delayed_numerator(const Eigen::VectorXd& b, int nk) {
  Eigen::VectorXd p = Eigen::VectorXd::Zero(nk + b.size());
  p.tail(b.size()) = b;
  return p;
}

}  // namespace

IdentifiedModel identify_armax(const IdData& data, const ModelOrders& o, const SearchOptions& options) {
  const int na = o.na, nb = o.nb, nc = o.nc, nk = o.nk;
  const Eigen::Index k0 = detail::check_problem(data, o, na + nb + nc, true);
  const double s = detail::common_scale(data);
  const Eigen::VectorXd u = data.u * s, y = data.y * s;
  const Eigen::Index n = y.size(), rows = n - k0;

  // Start: ARX, then extended least squares with the residuals of the previous pass as the C regressors.
  Eigen::MatrixXd phi_arx;
  Eigen::VectorXd rhs;
  detail::arx_regression(u, y, na, nb, nk, k0, phi_arx, rhs);
  Eigen::VectorXd theta(na + nb + nc);
  theta.setZero();
  theta.head(na + nb) = detail::least_squares(phi_arx, rhs);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(n);
  e.tail(rows) = rhs - phi_arx * theta.head(na + nb);
  // The start kept is the pass with the smallest one-step error (the ARX fit with C = 1 to begin with): on data an
  // ARX fits to rounding (a noise-free simulation, 1 - R^2 ~ 1e-12) the residual regressors are rounding noise, and
  // a pass may come back worse or not finite.
  Eigen::VectorXd best = theta;
  double best_loss = e.tail(rows).squaredNorm();
  for (int pass = 0; pass < 10 && nc > 0; ++pass) {
    Eigen::MatrixXd phi(rows, na + nb + nc);
    phi.leftCols(na + nb) = phi_arx;
    for (int i = 1; i <= nc; ++i) phi.col(na + nb + i - 1) = e.segment(k0 - i, rows);
    theta = detail::least_squares(phi, rhs);
    if (!theta.allFinite()) break;
    theta.tail(nc) = detail::reflect_into_unit_circle(theta.tail(nc));
    if (!theta.allFinite()) break;
    // Residuals of this model, recursively: C e = A y - B q^-nk u.
    const Eigen::VectorXd cpoly = monic(theta.tail(nc));
    e = filter_q(monic(theta.head(na)), cpoly, y) - filter_q(delayed_numerator(theta.segment(na, nb), nk), cpoly, u);
    if (!e.allFinite()) break;
    const double l = e.tail(rows).squaredNorm();
    if (l < best_loss) best = theta, best_loss = l;
  }
  theta = best;

  // Prediction-error minimisation.
  const detail::ResidualFn evaluate = [&](const Eigen::VectorXd& th, Eigen::VectorXd& eps, Eigen::MatrixXd* jac) {
    const Eigen::VectorXd c = th.tail(nc);
    if (nc > 0 && spectral_radius(c) >= 1.0) return false;
    const Eigen::VectorXd cpoly = monic(c), one = Eigen::VectorXd::Ones(1);
    const Eigen::VectorXd yf = filter_q(one, cpoly, y), uf = filter_q(one, cpoly, u);
    eps = filter_q(monic(th.head(na)), cpoly, y) - filter_q(delayed_numerator(th.segment(na, nb), nk), cpoly, u);
    if (!eps.allFinite()) return false;
    if (jac) {
      jac->resize(n, na + nb + nc);
      for (int i = 1; i <= na; ++i) jac->col(i - 1) = delayed(yf, i);
      for (int j = 1; j <= nb; ++j) jac->col(na + j - 1) = -delayed(uf, nk + j - 1);
      if (nc > 0) {
        const Eigen::VectorXd ef = filter_q(one, cpoly, eps);
        for (int i = 1; i <= nc; ++i) jac->col(na + nb + i - 1) = -delayed(ef, i);
      }
    }
    return true;
  };
  IdentifiedModel m;
  m.structure = ModelStructure::Armax;
  m.orders = o;
  double loss = 0.0;
  m.iterations = detail::levenberg_marquardt(evaluate, k0, options, theta, loss, m.converged);
  m.g.a = theta.head(na);
  m.g.b = theta.segment(na, nb);
  m.c = theta.tail(nc);
  m.g.nk = nk;
  m.g.period_s = data.period_s;
  m.loss = loss / (s * s);
  return m;
}

}  // namespace vmsim::drives
