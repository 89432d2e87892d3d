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

// The slope beyond which a surface is a steep wall (deg). At 60 deg a vertical height difference is twice the
// distance along the normal (1 / cos 60), a lateral error shows 1.7 times its size in height (tan 60), and a height
// field samples the surface at twice its spacing along the slope: beyond it, vertical figures stop meaning depth.
inline constexpr double kSteepWallSlopeDeg = 60.0;

// The reference surface's inclination at each node (rad from horizontal, 0 .. pi/2) and its normal factor
// 1 / sqrt(1 + |grad r|^2) = cos(slope), from central differences (one-sided beside an invalid node or the edge;
// 0 slope where neither neighbour along an axis is valid). NaN where the reference is invalid.
struct Slope {
  core::HeightGrid slope_rad;
  core::HeightGrid normal_factor;
};
Slope slope_of(const core::HeightGrid& reference);

// The deviation along the reference's normal: vertical deviation dz times cos(slope), to first order. Exact for a
// locally plane reference; on a reference of curvature k the error is about k dz_n^2 tan^2(slope) / 2 (a cylinder
// of radius R offset by d: d - d^2 tan^2(slope) / (2R)). Where the reference's height changes by more than a few
// spacings between neighbours (a wall the spacing does not resolve), the gradient is the secant's, and the normal
// figure is only bounded: |dz| cos(slope) <= 2 spacing |dz| / step, i.e. about the spacing at most on such a wall.
// Throws core::Error when the grids differ.
core::HeightGrid normal_deviation(const core::HeightGrid& vertical, const Slope& slope);

// The reference's steep part: its valid nodes steeper than `slope_deg`, and their fraction of its valid nodes.
struct SteepWalls {
  std::size_t nodes = 0;
  double fraction = 0.0;
};
SteepWalls steep_walls(const Slope& reference_slope, double slope_deg = kSteepWallSlopeDeg);

// The largest height step between neighbouring nodes of `surface` that is steeper than `slope_deg` (0 without
// one): a mesh through the height field's nodes interpolates straight across such a step, so its faces can be up
// to that far from the true wall - the mesh's error bound between nodes on walls.
double wall_step_max_mm(const core::HeightGrid& surface, double slope_deg = kSteepWallSlopeDeg);

struct Mark {
  double depth_mm = 0.0;                        // largest |deviation| in the mark (> 0); along the normal in a run
  bool overcut = true;                          // below the reference (material removed that should not be)
  double x_mm = 0.0, y_mm = 0.0;                // where the largest |deviation| is
  double x_extent_mm = 0.0, y_extent_mm = 0.0;  // extent of the region deeper than half the depth
  double area_mm2 = 0.0;
  // Along and across the path direction (when one is given): the extent of the half-depth region along the path
  // and its width across it (the full width at half depth), and the direction used (rad from +x, in (-pi/2, pi/2]).
  double along_mm = 0.0, width_mm = 0.0;
  double direction_rad = std::numeric_limits<double>::quiet_NaN();
  // Where the deviation is the normal one (add_vertical): the vertical deviation at the deepest point, the
  // reference's slope there, and whether that slope exceeds kSteepWallSlopeDeg.
  double depth_vertical_mm = std::numeric_limits<double>::quiet_NaN();
  double slope_rad = std::numeric_limits<double>::quiet_NaN();
  bool steep_wall = false;
};

// Connected regions whose |deviation| exceeds `threshold_mm`, each reported with its deepest point and the extent
// of the part deeper than half its depth; deepest first, at most `max_marks`. With a path direction (rad, the
// direction the tool moved at the mark), also the extent along it and the width across it. Regions of fewer than
// `min_nodes` nodes are left out (on measured deviations, noise lifts isolated nodes over the threshold).
std::vector<Mark> find_marks(const core::HeightGrid& dev, double threshold_mm, std::size_t max_marks = 10,
                             double path_direction_rad = std::numeric_limits<double>::quiet_NaN(),
                             std::size_t min_nodes = 1);

// Marks found on a normal deviation, each given the vertical deviation and the slope at its deepest node.
void add_vertical(std::vector<Mark>& marks, const core::HeightGrid& vertical, const Slope& slope);

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
