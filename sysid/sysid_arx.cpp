// ARX by least squares (the predictive-compensation paper Table 1; Ljung, System Identification, 2nd ed., section 7.3).
#include "sysid/sysid_detail.hpp"

namespace vmsim::sysid {

IdentifiedModel identify_arx(const IdData& data, const ModelOrders& orders) {
  const Eigen::Index k0 = detail::check_problem(data, orders, orders.na + orders.nb, false);
  const double s = detail::common_scale(data);
  const Eigen::VectorXd u = data.u * s, y = data.y * s;
  Eigen::MatrixXd phi;
  Eigen::VectorXd rhs;
  const detail::Segments seg(data, k0);
  detail::arx_regression(u, y, orders.na, orders.nb, orders.nk, seg, phi, rhs);
  if (data.initial_state_estimated) {
    // A constant per experiment (the rest offset, not assumed): A y = B u + c.
    seg.demean_gathered(rhs);
    for (Eigen::Index j = 0; j < phi.cols(); ++j) {
      Eigen::VectorXd col = phi.col(j);
      seg.demean_gathered(col);
      phi.col(j) = col;
    }
  }
  const Eigen::VectorXd theta = detail::least_squares(phi, rhs);

  IdentifiedModel m;
  m.structure = ModelStructure::Arx;
  m.orders = orders;
  m.orders.nc = 0;
  m.g.a = theta.head(orders.na);
  m.g.b = theta.tail(orders.nb);
  m.g.nk = orders.nk;
  m.g.period_s = data.period_s;
  m.loss = (rhs - phi * theta).squaredNorm() / static_cast<double>(rhs.size()) / (s * s);
  return m;
}

}  // namespace vmsim::sysid
