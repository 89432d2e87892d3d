#pragma once
// Signed deviation of a surface from a reference on the same grid, and the marks in it: where the predicted
// surface departs from the reference, how deep, how wide and how long.
#include "core/height_grid.hpp"

#include <vector>

namespace vmsim::metrology {

// a - b node by node (NaN where either is invalid). Throws core::Error when the grids differ.
core::HeightGrid deviation(const core::HeightGrid& a, const core::HeightGrid& b);

struct Mark {
  double depth_mm = 0.0;            // largest |deviation| in the mark (> 0)
  bool overcut = true;              // below the reference (material removed that should not be)
  double x_mm = 0.0, y_mm = 0.0;    // where the largest |deviation| is
  double x_extent_mm = 0.0, y_extent_mm = 0.0;  // extent of the region deeper than half the depth
  double area_mm2 = 0.0;
};

// Connected regions whose |deviation| exceeds `threshold_mm`, each reported with its deepest point and the extent
// of the part deeper than half its depth; deepest first, at most `max_marks`.
std::vector<Mark> find_marks(const core::HeightGrid& dev, double threshold_mm, std::size_t max_marks = 10);

}  // namespace vmsim::metrology
