// Shared pieces of the estimators: checks, scaling, QR least squares, pole reflection, Levenberg-Marquardt.
#include "core/error.hpp"
#include "sysid/sysid_detail.hpp"

#include <Eigen/QR>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <complex>

namespace vmsim::sysid {

const char* structure_name(ModelStructure s) {
  switch (s) {
    case ModelStructure::Arx:
      return "arx";
    case ModelStructure::Armax:
      return "armax";
    case ModelStructure::Oe:
      return "oe";
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
    case ModelStructure::Arx:
      return identify_arx(data, orders);
    case ModelStructure::Armax:
      return identify_armax(data, orders, options);
    case ModelStructure::Oe:
      return identify_oe(data, orders, options);
  }
  throw core::Error("identify: unknown model structure");
}

IdData concatenate(const std::vector<IdData>& experiments) {
  IdData out;
  if (experiments.empty()) return out;
  Eigen::Index n = 0;
  for (const auto& e : experiments) n += e.u.size();
  out.u.resize(n);
  out.y.resize(n);
  out.period_s = experiments.front().period_s;
  Eigen::Index at = 0;
  for (const auto& e : experiments) {
    if (e.u.size() != e.y.size())
      throw core::Error(fmt::format("identification data: {} inputs but {} outputs", e.u.size(), e.y.size()));
    out.starts.push_back(at);
    out.initial_state_estimated = out.initial_state_estimated || e.initial_state_estimated;
    out.u.segment(at, e.u.size()) = e.u;
    out.y.segment(at, e.y.size()) = e.y;
    at += e.u.size();
  }
  return out;
}

namespace detail {

Eigen::Index check_problem(const IdData& data, const ModelOrders& o, int parameters, bool use_nc) {
  if (o.na < 0 || o.na > 30) throw core::Error(fmt::format("orders: na must be in [0, 30], found {}", o.na));
  if (o.nb < 1 || o.nb > 30) throw core::Error(fmt::format("orders: nb must be in [1, 30], found {}", o.nb));
  if (use_nc && (o.nc < 0 || o.nc > 30))
    throw core::Error(fmt::format("orders: nc must be in [0, 30], found {}", o.nc));
  if (o.nk < 1 || o.nk > 100)
    throw core::Error(fmt::format("orders: the delay nk must be in [1, 100] samples, found {}", o.nk));
  if (data.u.size() != data.y.size())
    throw core::Error(fmt::format("identification data: {} inputs but {} outputs", data.u.size(), data.y.size()));
  if (!data.u.allFinite() || !data.y.allFinite()) throw core::Error("identification data: a value is not finite");
  const Eigen::Index k0 = std::max<Eigen::Index>({o.na, o.nb + o.nk - 1, use_nc ? o.nc : 0});
  Eigen::Index rows = data.u.size() - k0;
  if (!data.starts.empty()) {
    if (data.starts.front() != 0) throw core::Error("identification data: the first experiment must start at sample 0");
    rows = 0;
    for (std::size_t i = 0; i < data.starts.size(); ++i) {
      const Eigen::Index b = i + 1 < data.starts.size() ? data.starts[i + 1] : data.u.size();
      if (b <= data.starts[i] + k0)
        throw core::Error(
            fmt::format("identification data: experiment {} has {} samples, fewer than the {} the orders "
                        "need before a row can be formed",
                        i + 1, b - data.starts[i], k0 + 1));
      rows += b - data.starts[i] - k0;
    }
  }
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

Segments::Segments(const IdData& data, Eigen::Index k0) : n_(data.u.size()) {
  bounds_ = data.starts.empty() ? std::vector<Eigen::Index>{0} : data.starts;
  bounds_.push_back(n_);
  is_valid_.assign(static_cast<std::size_t>(n_), 0);
  for (std::size_t s = 0; s + 1 < bounds_.size(); ++s) {
    row_bounds_.push_back(static_cast<Eigen::Index>(valid_.size()));
    for (Eigen::Index k = bounds_[s] + k0; k < bounds_[s + 1]; ++k) {
      valid_.push_back(k);
      is_valid_[static_cast<std::size_t>(k)] = 1;
    }
  }
  row_bounds_.push_back(static_cast<Eigen::Index>(valid_.size()));
}

void Segments::demean_gathered(Eigen::VectorXd& g) const {
  for (std::size_t s = 0; s + 1 < row_bounds_.size(); ++s) {
    const Eigen::Index a = row_bounds_[s], len = row_bounds_[s + 1] - a;
    if (len > 0) g.segment(a, len).array() -= g.segment(a, len).mean();
  }
}

void Segments::project_out_offset(const Eigen::VectorXd& c_monic, Eigen::VectorXd& eps, Eigen::MatrixXd* jac) const {
  for (std::size_t s = 0; s + 1 < bounds_.size(); ++s) {
    const Eigen::Index a = bounds_[s], len = bounds_[s + 1] - a;
    Eigen::VectorXd basis = drives::filter_q(Eigen::VectorXd::Ones(1), c_monic, Eigen::VectorXd::Ones(len));
    for (Eigen::Index k = 0; k < len; ++k)
      if (!is_valid_[static_cast<std::size_t>(a + k)]) basis[k] = 0.0;
    const double norm = basis.norm();
    if (!(norm > 0.0)) continue;
    basis /= norm;
    const auto project = [&](auto&& v) { v -= basis * basis.dot(v); };
    project(eps.segment(a, len));
    if (jac)
      for (Eigen::Index c = 0; c < jac->cols(); ++c) project(jac->col(c).segment(a, len));
  }
}

Eigen::VectorXd Segments::delayed(const Eigen::VectorXd& x, Eigen::Index shift) const {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(x.size());
  for (std::size_t s = 0; s + 1 < bounds_.size(); ++s) {
    const Eigen::Index a = bounds_[s], len = bounds_[s + 1] - a;
    if (shift < len) out.segment(a + shift, len - shift) = x.segment(a, len - shift);
  }
  return out;
}

Eigen::VectorXd Segments::filter(const Eigen::VectorXd& num, const Eigen::VectorXd& den,
                                 const Eigen::VectorXd& x) const {
  if (bounds_.size() == 2) return drives::filter_q(num, den, x);
  Eigen::VectorXd out(x.size());
  for (std::size_t s = 0; s + 1 < bounds_.size(); ++s) {
    const Eigen::Index a = bounds_[s], len = bounds_[s + 1] - a;
    out.segment(a, len) = drives::filter_q(num, den, Eigen::VectorXd(x.segment(a, len)));
  }
  return out;
}

Eigen::VectorXd Segments::simulate(const drives::DiscreteTf& g, const Eigen::VectorXd& u) const {
  if (bounds_.size() == 2) return drives::simulate_tf(g, u);
  Eigen::VectorXd out(u.size());
  for (std::size_t s = 0; s + 1 < bounds_.size(); ++s) {
    const Eigen::Index a = bounds_[s], len = bounds_[s + 1] - a;
    out.segment(a, len) = drives::simulate_tf(g, Eigen::VectorXd(u.segment(a, len)));
  }
  return out;
}

Eigen::VectorXd Segments::gather(const Eigen::VectorXd& x) const {
  Eigen::VectorXd out(rows());
  for (Eigen::Index i = 0; i < rows(); ++i) out[i] = x[valid_[static_cast<std::size_t>(i)]];
  return out;
}

void Segments::mask(Eigen::VectorXd& eps, Eigen::MatrixXd* jac) const {
  for (Eigen::Index k = 0; k < eps.size(); ++k)
    if (!is_valid_[static_cast<std::size_t>(k)]) {
      eps[k] = 0.0;
      if (jac) jac->row(k).setZero();
    }
}

void Segments::project_out_initial_state(const Eigen::VectorXd& f_monic, int n_free, Eigen::VectorXd& eps,
                                         Eigen::MatrixXd* jac) const {
  for (std::size_t s = 0; s + 1 < bounds_.size(); ++s) {
    const Eigen::Index a = bounds_[s], len = bounds_[s + 1] - a;
    const Eigen::Index m = std::min<Eigen::Index>(n_free + 1, len);
    Eigen::MatrixXd basis = Eigen::MatrixXd::Zero(len, m);
    basis.col(0).setOnes();
    for (Eigen::Index j = 1; j < m; ++j) {
      Eigen::VectorXd pulse = Eigen::VectorXd::Zero(len);
      pulse[j - 1] = 1.0;
      basis.col(j) = drives::filter_q(Eigen::VectorXd::Ones(1), f_monic, pulse);
    }
    for (Eigen::Index k = 0; k < len; ++k)
      if (!is_valid_[static_cast<std::size_t>(a + k)]) basis.row(k).setZero();
    // Orthonormal basis of the span (rank-revealing: a pulse whose response lies entirely in masked rows adds none).
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(basis);
    const Eigen::Index r = qr.rank();
    if (r == 0) continue;
    const Eigen::MatrixXd q = qr.householderQ() * Eigen::MatrixXd::Identity(len, r);
    const auto project = [&](auto&& v) { v -= q * (q.transpose() * v); };
    project(eps.segment(a, len));
    if (jac)
      for (Eigen::Index c = 0; c < jac->cols(); ++c) project(jac->col(c).segment(a, len));
  }
}

void arx_regression(const Eigen::VectorXd& u, const Eigen::VectorXd& y, int na, int nb, int nk, const Segments& seg,
                    Eigen::MatrixXd& phi, Eigen::VectorXd& rhs) {
  phi.resize(seg.rows(), na + nb);
  rhs = seg.gather(y);
  for (int i = 1; i <= na; ++i) phi.col(i - 1) = -seg.gather(seg.delayed(y, i));
  for (int j = 1; j <= nb; ++j) phi.col(na + j - 1) = seg.gather(seg.delayed(u, nk + j - 1));
}

Eigen::VectorXd reflect_into_unit_circle(const Eigen::VectorXd& p) {
  const auto roots = drives::poles(p);
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
}  // namespace vmsim::sysid
