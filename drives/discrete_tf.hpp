#pragma once
// A discrete transfer function from an axis's position command u to its encoder position y (the predictive-compensation
// paper eq. 4-5):
//     A(q) y(k) = B(q) u(k - nk),  A = 1 + a1 q^-1 + ... + a_na q^-na,  B = b1 + b2 q^-1 + ... + b_nb q^-(nb-1),
// i.e. y(k) = -a1 y(k-1) - ... + b1 u(k-nk) + ... + b_nb u(k-nk-nb+1). q^-1 is one period Te. Signals are
// deviations from the rest point the axis starts from (sysid.hpp says why), so the model runs from zero state.
#include <Eigen/Core>

#include <complex>
#include <vector>

namespace vmsim::drives {

struct DiscreteTf {
  Eigen::VectorXd a;  // a1 .. a_na (the leading 1 of A is implied)
  Eigen::VectorXd b;  // b1 .. b_nb
  int nk = 1;         // input delay in samples (>= 1: row k+1 of a simulation may use setpoints up to k)
  double period_s = 1e-3;

  int na() const { return static_cast<int>(a.size()); }
  int nb() const { return static_cast<int>(b.size()); }
  // B(1) / A(1): the static gain (1 for a position loop with integral action or a type-1 loop).
  double static_gain() const;
};

// Roots of A (the poles, z-plane). Stable when all lie strictly inside the unit circle.
std::vector<std::complex<double>> poles(const Eigen::VectorXd& a);
double spectral_radius(const Eigen::VectorXd& a);  // largest |pole|; 0 for na = 0

// y = B q^-nk / A u from zero initial conditions (u and y deviations, u(k) = 0 for k < 0).
Eigen::VectorXd simulate_tf(const DiscreteTf& tf, const Eigen::VectorXd& u);

// y = filter(num, den, x) with den[0] = 1 (num, den: full polynomials in q^-1), zero initial conditions.
Eigen::VectorXd filter_q(const Eigen::VectorXd& num, const Eigen::VectorXd& den, const Eigen::VectorXd& x);

}  // namespace vmsim::drives
