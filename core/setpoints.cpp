#include "core/setpoints.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::core {

AxisPeaks finite_difference_peaks(const Setpoints& sp) {
  const Eigen::Index n = sp.samples(), na = sp.position.cols();
  AxisPeaks p;
  p.velocity = Eigen::ArrayXd::Zero(na);
  p.acceleration = Eigen::ArrayXd::Zero(na);
  p.jerk = Eigen::ArrayXd::Zero(na);
  if (n == 0) return p;
  const double te = sp.period_s;
  for (Eigen::Index a = 0; a < na; ++a) {
    auto x = [&](Eigen::Index k) { return sp.position(std::clamp<Eigen::Index>(k, 0, n - 1), a); };
    for (Eigen::Index k = 1; k < n + 3; ++k) {
      p.velocity[a] = std::max(p.velocity[a], std::abs(x(k) - x(k - 1)) / te);
      p.acceleration[a] = std::max(p.acceleration[a], std::abs(x(k) - 2 * x(k - 1) + x(k - 2)) / (te * te));
      p.jerk[a] = std::max(p.jerk[a], std::abs(x(k) - 3 * x(k - 1) + 3 * x(k - 2) - x(k - 3)) / (te * te * te));
    }
  }
  return p;
}

}  // namespace vmsim::core
