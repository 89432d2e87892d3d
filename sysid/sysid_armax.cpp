// ARMAX: extended least squares (the pseudo-linear regression with past residuals, Ljung section 7.5) for a start,
// then Levenberg-Marquardt on the one-step prediction error eps = (A y - B q^-nk u) / C (Ljung section 10.2).
#include "sysid/sysid_detail.hpp"

namespace vmsim::sysid {

using detail::monic;

namespace {

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
  const Eigen::Index n = y.size();
  const detail::Segments seg(data, k0);

  // Start: ARX, then extended least squares with the residuals of the previous pass as the C regressors.
  Eigen::MatrixXd phi_arx;
  Eigen::VectorXd rhs;
  detail::arx_regression(u, y, na, nb, nk, seg, phi_arx, rhs);
  // A constant per experiment when the experiments do not start at rest (the rest offset, not assumed): demeaned
  // regressions for the start, projected out of the prediction errors in the search.
  const bool offsets = data.initial_state_estimated;
  const auto demean = [&](Eigen::MatrixXd& phi, Eigen::VectorXd* r) {
    if (!offsets) return;
    if (r) seg.demean_gathered(*r);
    for (Eigen::Index j = 0; j < phi.cols(); ++j) {
      Eigen::VectorXd col = phi.col(j);
      seg.demean_gathered(col);
      phi.col(j) = col;
    }
  };
  demean(phi_arx, &rhs);
  Eigen::VectorXd theta(na + nb + nc);
  theta.setZero();
  theta.head(na + nb) = detail::least_squares(phi_arx, rhs);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(n);
  {
    // The ARX residuals at the summed rows (0 elsewhere: the experiments' first samples).
    const Eigen::VectorXd r = rhs - phi_arx * theta.head(na + nb);
    Eigen::VectorXd idx = seg.gather(Eigen::VectorXd::LinSpaced(n, 0.0, static_cast<double>(n - 1)));
    for (Eigen::Index i = 0; i < r.size(); ++i) e[static_cast<Eigen::Index>(idx[i])] = r[i];
  }
  // The start kept is the pass with the smallest one-step error (the ARX fit with C = 1 to begin with): on data an
  // ARX fits to rounding (a noise-free simulation, 1 - R^2 ~ 1e-12) the residual regressors are rounding noise, and
  // a pass may come back worse or not finite.
  Eigen::VectorXd best = theta;
  double best_loss = seg.gather(e).squaredNorm();
  for (int pass = 0; pass < 10 && nc > 0; ++pass) {
    Eigen::MatrixXd phi(seg.rows(), na + nb + nc);
    phi.leftCols(na + nb) = phi_arx;
    for (int i = 1; i <= nc; ++i) phi.col(na + nb + i - 1) = seg.gather(seg.delayed(e, i));
    demean(phi, nullptr);
    theta = detail::least_squares(phi, rhs);
    if (!theta.allFinite()) break;
    theta.tail(nc) = detail::reflect_into_unit_circle(theta.tail(nc));
    if (!theta.allFinite()) break;
    // Residuals of this model, recursively: C e = A y - B q^-nk u.
    const Eigen::VectorXd cpoly = monic(theta.tail(nc));
    e = seg.filter(monic(theta.head(na)), cpoly, y) -
        seg.filter(delayed_numerator(theta.segment(na, nb), nk), cpoly, u);
    if (!e.allFinite()) break;
    if (offsets) {
      seg.mask(e, nullptr);
      seg.project_out_offset(cpoly, e, nullptr);
    }
    const double l = seg.gather(e).squaredNorm();
    if (l < best_loss) best = theta, best_loss = l;
  }
  theta = best;

  // Prediction-error minimisation.
  const detail::ResidualFn evaluate = [&](const Eigen::VectorXd& th, Eigen::VectorXd& eps, Eigen::MatrixXd* jac) {
    const Eigen::VectorXd c = th.tail(nc);
    if (nc > 0 && drives::spectral_radius(c) >= 1.0) return false;
    const Eigen::VectorXd cpoly = monic(c), one = Eigen::VectorXd::Ones(1);
    const Eigen::VectorXd yf = seg.filter(one, cpoly, y), uf = seg.filter(one, cpoly, u);
    eps = seg.filter(monic(th.head(na)), cpoly, y) - seg.filter(delayed_numerator(th.segment(na, nb), nk), cpoly, u);
    if (!eps.allFinite()) return false;
    if (jac) {
      jac->resize(n, na + nb + nc);
      for (int i = 1; i <= na; ++i) jac->col(i - 1) = seg.delayed(yf, i);
      for (int j = 1; j <= nb; ++j) jac->col(na + j - 1) = -seg.delayed(uf, nk + j - 1);
      if (nc > 0) {
        const Eigen::VectorXd ef = seg.filter(one, cpoly, eps);
        for (int i = 1; i <= nc; ++i) jac->col(na + nb + i - 1) = -seg.delayed(ef, i);
      }
    }
    seg.mask(eps, jac);
    if (offsets) seg.project_out_offset(cpoly, eps, jac);
    return true;
  };
  IdentifiedModel m;
  m.structure = ModelStructure::Armax;
  m.orders = o;
  double loss = 0.0;
  m.iterations = detail::levenberg_marquardt(evaluate, 0, options, theta, loss, m.converged);
  loss *= static_cast<double>(n) / static_cast<double>(seg.rows());  // the mean over the summed rows only
  m.g.a = theta.head(na);
  m.g.b = theta.segment(na, nb);
  m.c = theta.tail(nc);
  m.g.nk = nk;
  m.g.period_s = data.period_s;
  m.loss = loss / (s * s);
  return m;
}

}  // namespace vmsim::sysid
