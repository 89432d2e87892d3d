// Shared pieces of the estimators: checks, scaling, QR least squares, pole reflection, Levenberg-Marquardt.
#include "core/error.hpp"
#include "drives/sysid_detail.hpp"

#include <Eigen/QR>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <complex>

namespace vmsim::drives {

const char* structure_name(ModelStructure s) {
  switch (s) {
    case ModelStructure::Arx: return "arx";
    case ModelStructure::Armax: return "armax";
    case ModelStructure::Oe: return "oe";
  }
  return "?";
}

std::optional<ModelStructure> parse_structure(const std::string& s) {
  if (s == "arx") return ModelStructure::Arx;
  if (s == "armax") return ModelStructure::Armax;
  if (s == "oe") return ModelStructure::Oe;
  return std::nullopt;
}

IdentifiedModel identify(ModelStructure s, const IdData& data, const ModelOrders& orders,
                         const SearchOptions& options) {
  switch (s) {
    case ModelStructure::Arx: return identify_arx(data, orders);
    case ModelStructure::Armax: return identify_armax(data, orders, options);
    case ModelStructure::Oe: return identify_oe(data, orders, options);
  }
  throw core::Error("identify: unknown model structure");
}

namespace detail {

Eigen::Index check_problem(const IdData& data, const ModelOrders& o, int parameters, bool use_nc) {
  if (o.na < 0 || o.na > 30) throw core::Error(fmt::format("orders: na must be in [0, 30], found {}", o.na));
  if (o.nb < 1 || o.nb > 30) throw core::Error(fmt::format("orders: nb must be in [1, 30], found {}", o.nb));
  if (use_nc && (o.nc < 0 || o.nc > 30)) throw core::Error(fmt::format("orders: nc must be in [0, 30], found {}", o.nc));
  if (o.nk < 1 || o.nk > 100)
    throw core::Error(fmt::format("orders: the delay nk must be in [1, 100] samples, found {}", o.nk));
  if (data.u.size() != data.y.size())
    throw core::Error(fmt::format("identification data: {} inputs but {} outputs", data.u.size(), data.y.size()));
  if (!data.u.allFinite() || !data.y.allFinite()) throw core::Error("identification data: a value is not finite");
  const Eigen::Index k0 = std::max<Eigen::Index>({o.na, o.nb + o.nk - 1, use_nc ? o.nc : 0});
  const Eigen::Index rows = data.u.size() - k0;
  if (rows < 10 * parameters)
    throw core::Error(fmt::format("identification data: {} samples cannot carry {} parameters (at least {} needed)",
                                  data.u.size(), parameters, k0 + 10 * parameters));
  if ((data.u.array() == data.u[0]).all())
    throw core::Error("identification data: the command never moves; nothing excites the axis");
  return k0;
}

double common_scale(const IdData& data) {
  const double m = std::max(data.u.cwiseAbs().maxCoeff(), data.y.cwiseAbs().maxCoeff());
  return m > 0.0 ? 1.0 / m : 1.0;
}

Eigen::VectorXd least_squares(const Eigen::MatrixXd& phi, const Eigen::VectorXd& rhs) {
  Eigen::VectorXd norms = phi.colwise().norm().transpose();
  for (Eigen::Index j = 0; j < norms.size(); ++j)
    if (!(norms[j] > 0.0)) norms[j] = 1.0;
  const Eigen::MatrixXd scaled = phi * norms.cwiseInverse().asDiagonal();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(scaled);
  return qr.solve(rhs).cwiseQuotient(norms);
}

void arx_regression(const Eigen::VectorXd& u, const Eigen::VectorXd& y, int na, int nb, int nk, Eigen::Index k0,
                    Eigen::MatrixXd& phi, Eigen::VectorXd& rhs) {
  const Eigen::Index n = y.size(), rows = n - k0;
  phi.resize(rows, na + nb);
  rhs = y.segment(k0, rows);
  for (int i = 1; i <= na; ++i) phi.col(i - 1) = -y.segment(k0 - i, rows);
  for (int j = 1; j <= nb; ++j) phi.col(na + j - 1) = u.segment(k0 - nk - j + 1, rows);
}

Eigen::VectorXd reflect_into_unit_circle(const Eigen::VectorXd& p) {
  const auto roots = poles(p);
  bool any = false;
  for (const auto& r : roots) any = any || std::abs(r) >= 1.0;
  if (!any) return p;
  // Rebuild the monic polynomial from the (reflected) roots; conjugate pairs keep it real.
  std::vector<std::complex<double>> c{1.0};
  for (auto r : roots) {
    if (std::abs(r) >= 1.0) r = 1.0 / std::conj(r) * 0.999;  // strictly inside, even for roots on the circle
    std::vector<std::complex<double>> next(c.size() + 1, 0.0);
    for (std::size_t i = 0; i < c.size(); ++i) {
      next[i] += c[i];
      next[i + 1] -= c[i] * r;
    }
    c = next;
  }
  Eigen::VectorXd out(p.size());
  for (Eigen::Index i = 0; i < p.size(); ++i) out[i] = c[static_cast<std::size_t>(i + 1)].real();
  return out;
}

int levenberg_marquardt(const ResidualFn& evaluate, Eigen::Index k0, const SearchOptions& options,
                        Eigen::VectorXd& theta, double& loss, bool& converged) {
  const Eigen::Index p = theta.size();
  Eigen::VectorXd eps, eps_try;
  Eigen::MatrixXd jac;
  converged = false;
  if (!evaluate(theta, eps, &jac)) throw core::Error("identification: the start model is not stable");
  Eigen::Index rows = eps.size() - k0;
  double v = eps.tail(rows).squaredNorm();
  double lambda = 1e-4;
  int it = 0;
  for (; it < options.max_iterations; ++it) {
    const Eigen::MatrixXd j = jac.bottomRows(rows);
    // Damped Gauss-Newton step from the augmented least-squares problem [J; sqrt(lambda) D] d = [-eps; 0] (QR, no
    // normal equations), D the column norms of J (Marquardt's scaling).
    const Eigen::VectorXd d_cols = j.colwise().norm().transpose().cwiseMax(1e-300);
    bool accepted = false;
    for (int tries = 0; tries < 30; ++tries) {
      Eigen::MatrixXd aug(rows + p, p);
      aug.topRows(rows) = j;
      aug.bottomRows(p) = (std::sqrt(lambda) * d_cols).asDiagonal();
      Eigen::VectorXd rhs = Eigen::VectorXd::Zero(rows + p);
      rhs.head(rows) = -eps.tail(rows);
      const Eigen::VectorXd step = least_squares(aug, rhs);
      const Eigen::VectorXd trial = theta + step;
      if (step.allFinite() && evaluate(trial, eps_try, nullptr)) {
        const double v_try = eps_try.tail(rows).squaredNorm();
        if (v_try < v) {
          const double gain = (v - v_try) / std::max(v, 1e-300);
          theta = trial;
          v = v_try;
          lambda = std::max(lambda / 10.0, 1e-12);
          accepted = true;
          evaluate(theta, eps, &jac);
          if (gain < options.relative_tolerance) converged = true;
          break;
        }
      }
      lambda *= 10.0;
      if (lambda > 1e16) break;
    }
    if (!accepted) {  // no step lowers the loss: a minimum at the precision of the data
      converged = true;
      break;
    }
    if (converged) {
      ++it;
      break;
    }
  }
  loss = v / static_cast<double>(rows);
  return it;
}

}  // namespace detail
}  // namespace vmsim::drives
