#pragma once
// Private to the OpenVDB kernel's .cpp files (removal/vdb_*.cpp): the grid behind VdbPart. Including it costs an
// OpenVDB translation unit (STACK.md P11); nothing outside removal/vdb_* includes it.
#include "removal/vdb_part.hpp"

#include <openvdb/openvdb.h>

namespace vmsim::removal {

struct VdbPart::Impl {
  openvdb::FloatGrid::Ptr grid;  // level set: world units mm, background = half width in mm
};

// openvdb::initialize(), once per process (grid type registry for I/O).
void vdb_initialize();

// Voxel centres at origin + (i, j, k) voxel_mm.
openvdb::math::Transform::Ptr vdb_transform(double voxel_mm, const Eigen::Vector3d& origin_mm);

// Marks a grid as a level set and wraps it.
VdbPart vdb_wrap(openvdb::FloatGrid::Ptr grid);

}  // namespace vmsim::removal
