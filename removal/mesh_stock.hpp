#pragma once
// Triangle-mesh stocks (STL) turned into dexels: every ray of a grid or needle set is cast against the closed
// mesh with Embree and gets the intervals where it is inside the solid (crossing parity from outside).
//
// How a ray is resolved (mesh_stock.cpp has the details):
//   - Embree (float, relative to the centre of the mesh's bounding box, watertight robust mode) reports every
//     triangle the ray crosses, through an intersection filter that records the triangle and rejects the hit so
//     traversal goes on. Embree's float t is not used.
//   - Each reported crossing is re-evaluated in double precision on the original vertices: the ray parameter is
//     the exact plane intersection t = ((a - o).n) / (d.n), and the ray's distance to the triangle's edge lines
//     decides whether the crossing is clean (inside the triangle by more than tau = 1e-6 x the mesh size).
//   - A ray with a crossing within tau of an edge or vertex, lying in a face's plane, or with an odd number of
//     crossings is degenerate (a shared edge may be reported once or twice, a vertex by any of its triangles, a
//     tangent ray may or may not touch). It is resolved exactly in the plane normal to the ray: a triangle is
//     crossed iff the ray's point lies inside its projection (exact orientation signs), and a ray exactly on an
//     edge or vertex is shifted symbolically (Simulation of Simplicity), infinitesimally, into each of four
//     quadrants around it, so that each shifted ray crosses exactly one triangle of a fan or an edge the surface
//     passes through, whatever the valence. The crossings' t are the original ray's plane intersections with the
//     triangles crossed, and the union of the four results is kept: a ray along the boundary of the solid gets the
//     material it touches (the closed set, as fill_box gives on a box's faces and corners).
// Precision: t is a double-precision plane intersection, then stored as a float offset like every dexel; for a
// box mesh the stored floats equal fill_box's bit for bit. Residual risks are listed in mesh_stock.cpp.
#include "core/mesh.hpp"
#include "removal/dexel_grid.hpp"

#include <memory>
#include <string>

namespace vmsim::removal {

struct MeshFillStats {
  std::size_t rays = 0;        // rays that reach the mesh's bounding box
  std::size_t degenerate = 0;  // rays resolved by symbolic perturbation (through edges/vertices, in face planes)
  std::size_t unresolved = 0;  // degenerate rays left with an odd crossing count in every shift (best effort used)
};

// A closed mesh prepared for ray casting (closedness checked once, Embree scene built once), so that the three
// grids of a tri-dexel field, or several needle sets, are filled without rebuilding it.
class MeshDexelizer {
 public:
  // Throws core::Error "<source>: ..." when the mesh is not closed and consistently oriented (core::check_closed)
  // or has a coordinate beyond +-1e9 mm; `source` names the mesh in messages (the STL file's path, say).
  explicit MeshDexelizer(const core::TriangleMesh& closed_mesh, const std::string& source = "triangle mesh");
  ~MeshDexelizer();
  MeshDexelizer(const MeshDexelizer&) = delete;
  MeshDexelizer& operator=(const MeshDexelizer&) = delete;

  // Material wherever a ray is inside the mesh (replacing what the rays held), clamped to [0, length] as fill_box
  // does. Rows (grid) or blocks of needles in parallel with OpenMP; the result does not depend on the thread count.
  MeshFillStats fill(DexelGrid& grid) const;
  MeshFillStats fill(NeedleSet& needles) const;

  // The inside intervals of one ray o + t d (d unit), t in [0, length], as fill() computes them.
  std::vector<Interval> intervals(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double length) const;

  double tolerance_mm() const;  // tau: crossings closer than this to an edge make a ray degenerate

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// One-shot forms: check, build, fill.
void fill_mesh(DexelGrid& grid, const core::TriangleMesh& closed_mesh, const std::string& source = "triangle mesh");
void fill_mesh(NeedleSet& needles, const core::TriangleMesh& closed_mesh, const std::string& source = "triangle mesh");

}  // namespace vmsim::removal
