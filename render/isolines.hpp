#pragma once
// Iso-lines of a field sampled on a rectilinear grid of nodes (a height grid's deviation), by marching squares on the
// grid's cells (VTK's vtkFlyingEdges2D) rather than by contouring the two triangles of each cell: the same crossings
// on every grid edge, a fraction of the work (no triangle cells built, one pass per value over the nodes).
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace vmsim::render {

struct IsoLines {
  Eigen::MatrixX3d points_mm;                         // one row per point
  std::vector<std::array<std::int32_t, 2>> segments;  // rows of points_mm
};

// Lines where `values` crosses each of `levels`. Nodes (i, j) at (x_mm[i], y_mm[j]), both ascending (the steps may
// differ); values and z_mm row-major, index j * nx + i. A point lies on a grid edge where the values cross the level,
// linearly interpolated along it (x, y and z_mm alike), as a contour of the cell's triangles puts it; only inside a
// cell, where the line crosses it, may the two differ (by less than a cell). A NaN value (a hole, a node without
// deviation) takes no part: no segment ends on an edge of it. Throws core::Error for mismatched sizes, fewer than
// 2 x 2 nodes or coordinates not ascending.
IsoLines grid_isolines(std::span<const double> x_mm, std::span<const double> y_mm, std::span<const float> values,
                       std::span<const float> z_mm, std::span<const double> levels);

}  // namespace vmsim::render
