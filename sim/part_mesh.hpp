#pragma once
// The part mesh of a height grid simplified where it is flat: blocks of the grid whose heights (and deviations) lie
// within a tolerance of a plane are drawn as a fan about their centre node over their boundary nodes instead of two
// triangles per cell. Every boundary node is kept, so neighbouring blocks share their edges (no T-junctions) and
// the mesh stays a closed solid where removal::heightfield_mesh's is.
#include "core/height_grid.hpp"
#include "core/mesh.hpp"

namespace vmsim::sim {

struct SimplifiedMesh {
  core::TriangleMesh mesh;
  // Largest distance in z between this mesh and the full one (two triangles per cell), and of its "deviation_mm"
  // from the full one's: within a flat block both lie within tolerance of the same plane, so 2 x tolerance.
  double error_bound_mm = 0.0;
  Eigen::Index flat_blocks = 0, blocks = 0;
};

// The number of triangles removal::heightfield_mesh makes of `top` (two per cell whose four nodes are valid, one
// where three are; a grid without invalid nodes is closed by walls and a bottom fan: 3 per boundary node), without
// making it.
Eigen::Index heightfield_mesh_triangles(const core::HeightGrid& top);

// `top`, `bottom_z_mm` and `deviation` as removal::heightfield_mesh; blocks of block_cells x block_cells cells (an
// even number >= 2); a block with an invalid node, or at the grid's far edges where it does not fit whole, keeps
// every cell. Throws core::Error for a tolerance that is not positive or a bad block size.
SimplifiedMesh simplified_heightfield_mesh(const core::HeightGrid& top, double bottom_z_mm,
                                           const core::HeightGrid* deviation, double tolerance_mm, int block_cells = 8);

}  // namespace vmsim::sim
