#pragma once
// Internals shared by the estimators of drives/sysid (not part of the module's interface).
#include "sysid/sysid.hpp"

#include <Eigen/Core>

#include <functional>

namespace vmsim::sysid::detail {

// The polynomial 1 + tail(0) q^-1 + ...: the monic denominators (A, C, D, F) from their free coefficients.
inline Eigen::VectorXd monic(const Eigen::VectorXd& tail) {
  Eigen::VectorXd p(tail.size() + 1);
  p << 1.0, tail;
  return p;
}

// Checks the data and orders; returns the first sample the criteria sum from (every regressor defined).
Eigen::Index check_problem(const IdData& data, const ModelOrders& orders, int parameters, bool use_nc);

// Common scale 1 / max(|u|, |y|) (1 when both are zero): applied to u and y together it leaves the coefficients of
// any of the three structures unchanged and keeps the regressors near 1.
double common_scale(const IdData& data);

// The experiments of an IdData and the rows the criteria sum (every regressor inside one experiment: k >= start + k0).
// Filters, delays and simulations run per experiment from rest.
class Segments {
 public:
  Segments(const IdData& data, Eigen::Index k0);
  Eigen::Index samples() const { return n_; }
  Eigen::Index rows() const { return static_cast<Eigen::Index>(valid_.size()); }
  Eigen::VectorXd delayed(const Eigen::VectorXd& x, Eigen::Index shift) const;  // x(k - shift), 0 before a start
  Eigen::VectorXd filter(const Eigen::VectorXd& num, const Eigen::VectorXd& den, const Eigen::VectorXd& x) const;
  Eigen::VectorXd simulate(const drives::DiscreteTf& g, const Eigen::VectorXd& u) const;
  Eigen::VectorXd gather(const Eigen::VectorXd& x) const;  // x at the summed rows
  // Zeroes eps (and the Jacobian's rows) outside the summed rows: those rows then add nothing to a least-squares step.
  void mask(Eigen::VectorXd& eps, Eigen::MatrixXd* jac) const;
  // An experiment that does not start at rest (IdData::initial_state_estimated): its simulated output differs from
  // the zero-state one by a free response of 1/F (F monic) and a constant output offset. The free responses are
  // those of 1/F to unit pulses at the experiment's first n_free samples (n_free = max(nf, nb + nk - 1): every
  // unknown sample before the start enters there). Removes from eps (and the Jacobian's columns: the variable-
  // projection step of Kaufman, 1975, dropping the derivative of the basis) its least-squares fit on that basis and
  // the constant, per experiment, over the summed rows. Call after mask().
  void project_out_initial_state(const Eigen::VectorXd& f_monic, int n_free, Eigen::VectorXd& eps,
                                 Eigen::MatrixXd* jac) const;
  // The equation-error counterparts for such experiments: a constant c per experiment in A y = B u + c (+ C e).
  // Removes each experiment's mean from a gathered vector (rows(): a column of the ARX regression or its right-hand
  // side; Frisch-Waugh: the least squares with the constants then need no columns for them), and from eps (and the
  // Jacobian's columns) its least-squares fit on c / C, i.e. the constant filtered by 1/C from the experiment's start.
  void demean_gathered(Eigen::VectorXd& gathered) const;
  void project_out_offset(const Eigen::VectorXd& c_monic, Eigen::VectorXd& eps, Eigen::MatrixXd* jac) const;

 private:
  Eigen::Index n_ = 0;
  std::vector<Eigen::Index> bounds_;      // starts, then n
  std::vector<Eigen::Index> row_bounds_;  // each experiment's first summed row (index into valid_), then rows()
  std::vector<Eigen::Index> valid_;
  std::vector<char> is_valid_;
};

// Least squares min |phi theta - rhs| by column-pivoted Householder QR on columns scaled to unit norm.
Eigen::VectorXd least_squares(const Eigen::MatrixXd& phi, const Eigen::VectorXd& rhs);

// The ARX regression of y on [-y(k-1..k-na), u(k-nk..k-nk-nb+1)] over the summed rows of each experiment.
void arx_regression(const Eigen::VectorXd& u, const Eigen::VectorXd& y, int na, int nb, int nk, const Segments& seg,
                    Eigen::MatrixXd& phi, Eigen::VectorXd& rhs);

// Monic polynomial 1 + p1 q^-1 + ... with every root outside the unit circle reflected to 1/conj(root): the same
// magnitude response up to a constant, and a stable (minimum-phase) filter (Ljung section 10.1, for C and F).
Eigen::VectorXd reflect_into_unit_circle(const Eigen::VectorXd& p);

// Levenberg-Marquardt on sum(eps^2) over rows k >= k0 (several experiments: evaluate masks the rows it must not sum,
// Segments::mask, and k0 = 0). `evaluate(theta, eps, jac)` fills eps (N) and, when jac is not
// null, d eps / d theta (N x p); it returns false when theta is not admissible (an unstable filter). Returns the
// iterations used; theta holds the best parameters found, loss their mean squared error over the rows.
using ResidualFn = std::function<bool(const Eigen::VectorXd& theta, Eigen::VectorXd& eps, Eigen::MatrixXd* jac)>;
int levenberg_marquardt(const ResidualFn& evaluate, Eigen::Index k0, const SearchOptions& options,
                        Eigen::VectorXd& theta, double& loss, bool& converged);

}  // namespace vmsim::sysid::detail
