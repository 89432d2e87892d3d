#pragma once
// Surfaces of a machined part read back from its dexels.
#include "core/height_grid.hpp"
#include "core/mesh.hpp"

#include <Eigen/Core>

#include <vector>

namespace vmsim::removal {

// The part as a z-map sees it, as a triangle mesh: the top surface (two triangles per grid cell), and, when every
// node is valid, the side walls down to `bottom_z_mm` and a bottom fanned from its centre, making a closed solid.
// `deviation` (same grid, optional) becomes the per-vertex scalar "deviation_mm" (0 on the walls and bottom).
core::TriangleMesh heightfield_mesh(const core::HeightGrid& top, double bottom_z_mm,
                                    const core::HeightGrid* deviation = nullptr);

// A height-field top made into a mesh (heightfield_mesh, sim/part_mesh's simplified one): when `closed`, adds the
// bottom at bottom_z_mm (the boundary nodes' copies fanned about an off-node centre) and the walls between the top's
// boundary nodes and their copies; every boundary node must have a vertex. id: each grid node's vertex (j * nx + i),
// -1 where it has none. The deviation (0 on walls and bottom) becomes "deviation_mm" when with_deviation.
core::TriangleMesh close_heightfield_top(const core::HeightGrid& grid, double bottom_z_mm, const std::vector<int>& id,
                                         std::vector<Eigen::Vector3d> vertices, std::vector<double> deviation,
                                         std::vector<Eigen::Vector3i> triangles, bool closed, bool with_deviation);

}  // namespace vmsim::removal
