#pragma once
// Signed deviation of a surface from a reference on the same grid, and the marks in it: where the surface departs
// from the reference, how deep, how wide across the tool path and how long along it.
#include "core/height_grid.hpp"

#include <Eigen/Core>

#include <cmath>
#include <limits>
#include <vector>

namespace vmsim::metrology {

// a - b node by node (NaN where either is invalid). Throws core::Error when the grids differ.
core::HeightGrid deviation(const core::HeightGrid& a, const core::HeightGrid& b);

struct Mark {
  double depth_mm = 0.0;                        // largest |deviation| in the mark (> 0)
  bool overcut = true;                          // below the reference (material removed that should not be)
  double x_mm = 0.0, y_mm = 0.0;                // where the largest |deviation| is
  double x_extent_mm = 0.0, y_extent_mm = 0.0;  // extent of the region deeper than half the depth
  double area_mm2 = 0.0;
  // Along and across the path direction (when one is given): the extent of the half-depth region along the path
  // and its width across it (the full width at half depth), and the direction used (rad from +x, in (-pi/2, pi/2]).
  double along_mm = 0.0, width_mm = 0.0;
  double direction_rad = std::numeric_limits<double>::quiet_NaN();
};

// Connected regions whose |deviation| exceeds `threshold_mm`, each reported with its deepest point and the extent
// of the part deeper than half its depth; deepest first, at most `max_marks`. With a path direction (rad, the
// direction the tool moved at the mark), also the extent along it and the width across it. Regions of fewer than
// `min_nodes` nodes are left out (on measured deviations, noise lifts isolated nodes over the threshold).
std::vector<Mark> find_marks(const core::HeightGrid& dev, double threshold_mm, std::size_t max_marks = 10,
                             double path_direction_rad = std::numeric_limits<double>::quiet_NaN(),
                             std::size_t min_nodes = 1);

// The lay of a machined surface: the direction the tool marks run in (rad, in (-pi/2, pi/2], 0 = along +x), from
// the structure tensor of its gradients (the marks run across the dominant gradient), and how strongly the texture
// is oriented (0 isotropic .. 1 all gradients parallel). For a raster-milled surface the lay is the feed direction.
struct Lay {
  double direction_rad = 0.0;
  double anisotropy = 0.0;
};
Lay lay_of(const core::HeightGrid& surface);

// Heights along a line through (x, y) in direction `direction_rad`, from -half_length to +half_length (mm), every
// `step_mm`, bilinear; NaN off the grid or in invalid cells. For profiles across a mark: direction = path + pi/2.
struct Profile {
  Eigen::ArrayXd s_mm, z_mm;
};
Profile profile(const core::HeightGrid& g, double x_mm, double y_mm, double direction_rad, double half_length_mm,
                double step_mm);

}  // namespace vmsim::metrology
