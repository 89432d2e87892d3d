#pragma once
// Surfaces of a machined part read back from its dexels.
#include "core/height_grid.hpp"
#include "core/mesh.hpp"

namespace vmsim::removal {

// The part as a z-map sees it, as a triangle mesh: the top surface (two triangles per grid cell), and, when every
// node is valid, the side walls down to `bottom_z_mm` and a bottom fanned from its centre, making a closed solid.
// `deviation` (same grid, optional) becomes the per-vertex scalar "deviation_mm" (0 on the walls and bottom).
core::TriangleMesh heightfield_mesh(const core::HeightGrid& top, double bottom_z_mm,
                                    const core::HeightGrid* deviation = nullptr);

}  // namespace vmsim::removal
