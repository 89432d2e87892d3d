// Output error: a Steiglitz-McBride start (ARX fits on data prefiltered by 1/F of the previous pass, Steiglitz &
// McBride 1965; Ljung section 10.4), then Levenberg-Marquardt on the simulation error eps = y - B/F q^-nk u.
#include "sysid/sysid_detail.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::sysid {

using detail::monic;

IdentifiedModel identify_oe(const IdData& data, const ModelOrders& o, const SearchOptions& options) {
  const int nf = o.na, nb = o.nb, nk = o.nk;
  const Eigen::Index k0 = detail::check_problem(data, o, nf + nb, false);
  const double s = detail::common_scale(data);
  const Eigen::VectorXd u = data.u * s, y = data.y * s;
  const Eigen::Index n = y.size();
  const Eigen::VectorXd one = Eigen::VectorXd::Ones(1);
  const detail::Segments seg(data, k0);
  const bool free_start = data.initial_state_estimated;
  const int n_free = std::max(nf, nb + nk - 1);

  // Simulation error of a candidate (infinite when F is unstable): the OE criterion itself.
  auto sim_loss = [&](const Eigen::VectorXd& th) {
    if (!th.allFinite() || (nf > 0 && drives::spectral_radius(th.head(nf)) >= 1.0)) return HUGE_VAL;
    drives::DiscreteTf g;
    g.a = th.head(nf);
    g.b = th.tail(nb);
    g.nk = nk;
    Eigen::VectorXd eps = y - seg.simulate(g, u);
    seg.mask(eps, nullptr);
    if (free_start) seg.project_out_initial_state(monic(g.a), n_free, eps, nullptr);
    const double l = eps.squaredNorm();
    return std::isfinite(l) ? l : HUGE_VAL;
  };
  // Steiglitz-McBride: F from ARX, then ARX on (u, y) filtered by 1/F until F settles. The search starts from the
  // candidate (the ARX fit or a pass) with the smallest simulation error: on data an ARX fits to rounding (a
  // noise-free simulation) the passes can drift away from it.
  Eigen::MatrixXd phi;
  Eigen::VectorXd rhs;
  // Experiments that do not start at rest: a constant per experiment in the start's regressions (the rest offset).
  const auto demean = [&] {
    if (!free_start) return;
    seg.demean_gathered(rhs);
    for (Eigen::Index j = 0; j < phi.cols(); ++j) {
      Eigen::VectorXd col = phi.col(j);
      seg.demean_gathered(col);
      phi.col(j) = col;
    }
  };
  detail::arx_regression(u, y, nf, nb, nk, seg, phi, rhs);
  demean();
  Eigen::VectorXd theta = detail::least_squares(phi, rhs);  // [f; b]
  theta.head(nf) = detail::reflect_into_unit_circle(theta.head(nf));
  Eigen::VectorXd best = theta;
  double best_loss = sim_loss(theta);
  for (int pass = 0; pass < 30 && nf > 0; ++pass) {
    const Eigen::VectorXd fpoly = monic(theta.head(nf));
    detail::arx_regression(seg.filter(one, fpoly, u), seg.filter(one, fpoly, y), nf, nb, nk, seg, phi, rhs);
    demean();
    Eigen::VectorXd next = detail::least_squares(phi, rhs);
    if (!next.allFinite()) break;
    next.head(nf) = detail::reflect_into_unit_circle(next.head(nf));
    const double change = (next - theta).norm() / std::max(theta.norm(), 1e-300);
    theta = next;
    const double l = sim_loss(theta);
    if (l < best_loss) best = theta, best_loss = l;
    if (change < 1e-10) break;
  }
  theta = best;

  const detail::ResidualFn evaluate = [&](const Eigen::VectorXd& th, Eigen::VectorXd& eps, Eigen::MatrixXd* jac) {
    const Eigen::VectorXd f = th.head(nf);
    if (nf > 0 && drives::spectral_radius(f) >= 1.0) return false;
    drives::DiscreteTf g;
    g.a = f;
    g.b = th.tail(nb);
    g.nk = nk;
    const Eigen::VectorXd yhat = seg.simulate(g, u);
    eps = y - yhat;
    if (!eps.allFinite()) return false;
    if (jac) {
      const Eigen::VectorXd fpoly = monic(f);
      const Eigen::VectorXd uf = seg.filter(one, fpoly, u), yf = seg.filter(one, fpoly, yhat);
      jac->resize(n, nf + nb);
      for (int i = 1; i <= nf; ++i) jac->col(i - 1) = seg.delayed(yf, i);  // d eps / d f_i = yhat(k-i)/F
      for (int j = 1; j <= nb; ++j) jac->col(nf + j - 1) = -seg.delayed(uf, nk + j - 1);
    }
    seg.mask(eps, jac);
    if (free_start) seg.project_out_initial_state(monic(f), n_free, eps, jac);
    return true;
  };
  IdentifiedModel m;
  m.structure = ModelStructure::Oe;
  m.orders = o;
  m.orders.nc = 0;
  double loss = 0.0;
  m.iterations = detail::levenberg_marquardt(evaluate, 0, options, theta, loss, m.converged);
  loss *= static_cast<double>(n) / static_cast<double>(seg.rows());  // the mean over the summed rows only
  m.g.a = theta.head(nf);
  m.g.b = theta.tail(nb);
  m.g.nk = nk;
  m.g.period_s = data.period_s;
  m.loss = loss / (s * s);
  return m;
}

}  // namespace vmsim::sysid
