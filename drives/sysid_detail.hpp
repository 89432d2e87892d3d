#pragma once
// Internals shared by the estimators of drives/sysid (not part of the module's interface).
#include "drives/sysid.hpp"

#include <Eigen/Core>

#include <functional>

namespace vmsim::drives::detail {

// Checks the data and orders; returns the first sample the criteria sum from (every regressor defined).
Eigen::Index check_problem(const IdData& data, const ModelOrders& orders, int parameters, bool use_nc);

// Common scale 1 / max(|u|, |y|) (1 when both are zero): applied to u and y together it leaves the coefficients of
// any of the three structures unchanged and keeps the regressors near 1.
double common_scale(const IdData& data);

// Least squares min |phi theta - rhs| by column-pivoted Householder QR on columns scaled to unit norm.
Eigen::VectorXd least_squares(const Eigen::MatrixXd& phi, const Eigen::VectorXd& rhs);

// The ARX regression of y on [-y(k-1..k-na), u(k-nk..k-nk-nb+1)] over rows k >= k0.
void arx_regression(const Eigen::VectorXd& u, const Eigen::VectorXd& y, int na, int nb, int nk, Eigen::Index k0,
                    Eigen::MatrixXd& phi, Eigen::VectorXd& rhs);

// Monic polynomial 1 + p1 q^-1 + ... with every root outside the unit circle reflected to 1/conj(root): the same
// magnitude response up to a constant, and a stable (minimum-phase) filter (Ljung section 10.1, for C and F).
Eigen::VectorXd reflect_into_unit_circle(const Eigen::VectorXd& p);

// Levenberg-Marquardt on sum(eps^2) over rows k >= k0. `evaluate(theta, eps, jac)` fills eps (N) and, when jac is not
// null, d eps / d theta (N x p); it returns false when theta is not admissible (an unstable filter). Returns the
// iterations used; theta holds the best parameters found, loss their mean squared error over the rows.
using ResidualFn = std::function<bool(const Eigen::VectorXd& theta, Eigen::VectorXd& eps, Eigen::MatrixXd* jac)>;
int levenberg_marquardt(const ResidualFn& evaluate, Eigen::Index k0, const SearchOptions& options,
                        Eigen::VectorXd& theta, double& loss, bool& converged);

}  // namespace vmsim::drives::detail
