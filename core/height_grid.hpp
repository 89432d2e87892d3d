#pragma once
// A height grid: z over a regular x/y grid, as a z-map or a confocal scan gives it. Shared by removal (predicted
// surfaces) and metrology (measured scans). Invalid points (not measured, outside the part) are NaN, never 0.
#include <Eigen/Core>

#include <cmath>
#include <string>

namespace vmsim::core {

// Row-major: row j (y), column i (x), x varying fastest in memory as in X3P files.
using HeightArray = Eigen::Array<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct HeightGrid {
  double x0_mm = 0.0, y0_mm = 0.0;  // position of node (0, 0)
  double dx_mm = 1.0, dy_mm = 1.0;  // spacing, > 0
  HeightArray z_mm;                 // ny x nx; NaN = invalid

  Eigen::Index nx() const { return z_mm.cols(); }
  Eigen::Index ny() const { return z_mm.rows(); }
  double x(Eigen::Index i) const { return x0_mm + static_cast<double>(i) * dx_mm; }
  double y(Eigen::Index j) const { return y0_mm + static_cast<double>(j) * dy_mm; }
  bool valid(Eigen::Index j, Eigen::Index i) const { return std::isfinite(z_mm(j, i)); }
};

}  // namespace vmsim::core
