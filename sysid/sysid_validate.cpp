// Validation figures (the predictive-compensation paper eq. 16-17, residual whiteness) and order selection by BIC.
#include "core/error.hpp"
#include "sysid/sysid_detail.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::sysid {

using detail::monic;

namespace {

double fit_percent(const Eigen::VectorXd& y, const Eigen::VectorXd& yhat) {
  const double den = (y.array() - y.mean()).matrix().norm();
  return den > 0.0 ? 100.0 * (1.0 - (y - yhat).norm() / den) : 0.0;
}

}  // namespace

Eigen::VectorXd prediction_errors(const IdentifiedModel& m, const IdData& data) {
  Eigen::VectorXd bq = Eigen::VectorXd::Zero(m.g.nk + m.g.nb());
  bq.tail(m.g.nb()) = m.g.b;
  switch (m.structure) {
    case ModelStructure::Arx:
      return drives::filter_q(monic(m.g.a), Eigen::VectorXd::Ones(1), data.y) -
             drives::filter_q(bq, Eigen::VectorXd::Ones(1), data.u);
    case ModelStructure::Armax:
      return drives::filter_q(monic(m.g.a), monic(m.c), data.y) - drives::filter_q(bq, monic(m.c), data.u);
    case ModelStructure::Oe:
      return data.y - drives::simulate_tf(m.g, data.u);
  }
  return {};
}

Validation validate(const IdentifiedModel& m, const IdData& data, int lags, Eigen::Index first) {
  const Eigen::Index total = data.y.size();
  if (data.u.size() != total || first < 0 || total - first < 2 * lags + 10)
    throw core::Error(fmt::format("validation data: {} samples, at least {} needed",
                                  std::max<Eigen::Index>(total - first, 0), 2 * lags + 10));
  Validation v;
  const Eigen::Index n_val = total - first;
  Eigen::VectorXd sim = drives::simulate_tf(m.g, data.u);
  if (data.initial_state_estimated) {
    // The initial state and output offset fitted over the whole record: y - sim loses its component in their span.
    Eigen::VectorXd e = data.y - sim;
    IdData one = data;
    one.starts.clear();
    const detail::Segments seg(one, 0);
    seg.project_out_initial_state(monic(m.g.a), std::max(m.g.na(), m.g.nb() + m.g.nk - 1), e, nullptr);
    sim = data.y - e;
  }
  v.simulated = sim.tail(n_val);
  const Eigen::VectorXd y = data.y.tail(n_val), u = data.u.tail(n_val);
  const Eigen::VectorXd err = y - v.simulated;
  const double n = static_cast<double>(n_val);
  v.fit_percent = fit_percent(y, v.simulated);
  const double ss_tot = (y.array() - y.mean()).square().sum();
  v.r2 = ss_tot > 0.0 ? 1.0 - err.squaredNorm() / ss_tot : 0.0;
  v.mse = err.squaredNorm() / n;
  v.max_abs_error = err.cwiseAbs().maxCoeff();
  v.tracking_fit_percent = fit_percent(u - y, u - v.simulated);
  const double y_abs = (y.array() + data.y_reference).matrix().norm();
  v.relative_error_percent = y_abs > 0.0 ? 100.0 * err.norm() / y_abs : 0.0;

  // Whiteness of the one-step errors, past the start-up transient.
  const Eigen::Index skip = std::max<Eigen::Index>({first, m.g.na(), m.g.nb() + m.g.nk, m.c.size()});
  // (OE's one-step errors are its simulation errors: with an estimated initial state, those of the fitted start.)
  const Eigen::VectorXd eps_all = m.structure == ModelStructure::Oe && data.initial_state_estimated
                                      ? Eigen::VectorXd(data.y - sim)
                                      : prediction_errors(m, data);
  const Eigen::VectorXd eps = eps_all.tail(total - skip).array() - eps_all.tail(total - skip).mean();
  const double r0 = eps.squaredNorm();
  v.lags = lags;
  v.whiteness_bound = 2.58 / std::sqrt(static_cast<double>(eps.size()));
  v.max_abs_autocorrelation = 0.0;
  double q = 0.0;
  for (int tau = 1; tau <= lags && r0 > 0.0; ++tau) {
    const Eigen::Index len = eps.size() - tau;
    const double r = eps.head(len).dot(eps.tail(len)) / r0;
    v.max_abs_autocorrelation = std::max(v.max_abs_autocorrelation, std::abs(r));
    q += r * r;
  }
  v.portmanteau_q = static_cast<double>(eps.size()) * q;
  // chi^2 quantile by the Wilson-Hilferty approximation (z = 2.326 for 99 %; within 0.5 % for lags >= 5).
  const double k = lags, h = 2.0 / (9.0 * k);
  v.portmanteau_limit = k * std::pow(1.0 - h + 2.326 * std::sqrt(h), 3.0);
  v.white = r0 > 0.0 && v.portmanteau_q <= v.portmanteau_limit;
  return v;
}

int select_delay(const IdData& data, int na, int nb, int max_nk) {
  int best = 1;
  double best_loss = std::numeric_limits<double>::infinity();
  for (int nk = 1; nk <= max_nk; ++nk) {
    const double loss = identify_arx(data, {na, nb, 0, nk}).loss;
    if (loss < best_loss * (1.0 - 1e-9)) {  // a longer delay must do strictly better
      best_loss = loss;
      best = nk;
    }
  }
  return best;
}

ModelOrders select_orders_bic(const IdData& data, const OrderSearch& search) {
  ModelOrders best;
  double best_bic = std::numeric_limits<double>::infinity();
  for (int nk = 1; nk <= search.max_nk; ++nk)
    for (int na = 1; na <= search.max_na; ++na)
      for (int nb = 1; nb <= std::min(na, search.max_nb); ++nb) {
        const IdentifiedModel m = identify_arx(data, {na, nb, 0, nk});
        const double rows = static_cast<double>(data.y.size() - std::max(na, nb + nk - 1));
        const double bic = rows * std::log(std::max(m.loss, 1e-300)) + (na + nb) * std::log(rows);
        if (bic < best_bic) {
          best_bic = bic;
          best = {na, nb, nb, nk};
        }
      }
  return best;
}

}  // namespace vmsim::sysid
