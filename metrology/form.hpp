#pragma once
// Form removal: the least-squares plane or polynomial surface through the valid points, subtracted. Invalid points
// stay invalid; they take no part in the fit.
#include "core/height_grid.hpp"

#include <Eigen/Core>

#include <cstddef>

namespace vmsim::metrology {

struct FormFit {
  int degree = 1;  // total degree: 1 plane, 2 quadric, ...
  // z = sum c_ab P_a(u) P_b(v), a + b <= degree, with Legendre polynomials P and u, v the node coordinates
  // scaled to [-1, 1] over the grid (a basis that stays well conditioned at any degree on a full grid).
  Eigen::VectorXd coefficients;
  double x_centre_mm = 0, y_centre_mm = 0, x_half_mm = 1, y_half_mm = 1;
  // The plane part in plain units: height at the grid centre, and slopes dz/dx, dz/dy (exact for degree 1).
  double z_centre_mm = 0, slope_x = 0, slope_y = 0;
  double rms_residual_mm = 0;
  std::size_t points = 0;
  double evaluate(double x_mm, double y_mm) const;
};

// Fits the form to the valid points (or, with `use`, to those valid points whose `use` value is non-zero; same
// shape as the grid) and returns the grid minus the form. Throws core::Error when there are fewer valid points
// than terms, or the points do not determine the form (all on one line, say).
core::HeightGrid remove_form(
    const core::HeightGrid& grid, int degree, FormFit* fit = nullptr,
    const Eigen::Array<std::uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>* use = nullptr);
FormFit fit_form(const core::HeightGrid& grid, int degree,
                 const Eigen::Array<std::uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>* use = nullptr);

}  // namespace vmsim::metrology
