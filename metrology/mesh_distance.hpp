#pragma once
// Signed distances from points to a triangle mesh (a predicted part from `vmsim run`, part.stl), as CloudCompare's
// cloud-to-mesh (C2M) distance computes them: the exact distance to the closest point of the closest triangle,
// positive on the side that triangle's normal points to (outside the part: above a machined top surface).
#include "core/height_grid.hpp"
#include "core/mesh.hpp"
#include "metrology/register.hpp"

#include <Eigen/Core>

#include <memory>
#include <vector>

namespace vmsim::metrology {

class MeshDistance {
 public:
  // Builds a bounding-volume hierarchy over the triangles (median splits, 4 triangles per leaf), in double.
  // Throws core::Error for an empty mesh or indices out of range.
  explicit MeshDistance(const core::TriangleMesh& mesh);
  ~MeshDistance();
  MeshDistance(const MeshDistance&) = delete;
  MeshDistance& operator=(const MeshDistance&) = delete;

  struct Hit {
    double distance = 0;  // signed
    Eigen::Vector3d closest = Eigen::Vector3d::Zero();
    int triangle = -1;
  };
  Hit closest(const Eigen::Vector3d& p) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Signed distance of each point (rows, mm). OpenMP over points; each result is independent of the others.
Eigen::VectorXd signed_distances(const Eigen::Matrix<double, Eigen::Dynamic, 3>& points,
                                 const core::TriangleMesh& mesh);

// The deviation of a point grid (a scan) from a predicted mesh: at each valid node, the signed distance of the
// node's point, carried through `scan_to_part`, to the mesh. Same geometry as the scan (its own frame).
core::HeightGrid mesh_deviation(const core::HeightGrid& scan, const RigidTransform& scan_to_part,
                                const core::TriangleMesh& mesh);

// The mesh's upper surface sampled on a grid of `spacing_mm` over its x/y extent: at each node the highest point
// of the triangles facing up (normal z > 0) above it; nodes no such triangle covers are invalid. For registering a
// scan to a predicted mesh (the distances themselves are then taken to the mesh).
core::HeightGrid rasterize_top(const core::TriangleMesh& mesh, double spacing_mm);

// The top surface of a height grid as a mesh: two triangles per cell whose four corners are valid, normals up.
core::TriangleMesh grid_surface_mesh(const core::HeightGrid& grid);

}  // namespace vmsim::metrology
