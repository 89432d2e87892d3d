#pragma once
// The quintic Hermite polynomial through (P0, V0, A0) at u = 0 and (P1, V1, A1) at u = 1, as monomial coefficients
// (column k multiplies u^k): the blends of motion/smooth_path and the pieces that approximate a NURBS (motion/nurbs).
#include "core/toolpath.hpp"

#include <Eigen/Core>

namespace vmsim::motion {

inline Eigen::Matrix<double, 6, 6> quintic_hermite(const core::Vec6& P0, const core::Vec6& V0, const core::Vec6& A0,
                                                   const core::Vec6& P1, const core::Vec6& V1, const core::Vec6& A1) {
  Eigen::Matrix<double, 6, 6> c;
  c.col(0) = P0;
  c.col(1) = V0;
  c.col(2) = 0.5 * A0;
  c.col(3) = -10 * P0 - 6 * V0 - 1.5 * A0 + 0.5 * A1 - 4 * V1 + 10 * P1;
  c.col(4) = 15 * P0 + 8 * V0 + 1.5 * A0 - A1 + 7 * V1 - 15 * P1;
  c.col(5) = -6 * P0 - 3 * V0 - 0.5 * A0 + 0.5 * A1 - 3 * V1 + 6 * P1;
  return c;
}

}  // namespace vmsim::motion
