#pragma once
// The OpenVDB kernel: a part as a narrow-band level set (openvdb::FloatGrid, signed distance in mm, negative
// inside, +-half_width voxels of band), cut by tool sweeps, read back along rays, meshed, and written as .vdb.
// It is the second, independent way to remove material: dexels are exact along their rays and blind between them;
// the level set is isotropic to within its voxel and always gives a closed mesh. Heavy OpenVDB headers stay in the
// .cpp files (removal/vdb_grid.hpp is their private header).
//
// Cutting (VdbPart::cut): the same per-voxel operation as openvdb::tools::csgDifference, phi = max(phi_stock,
// -phi_tool), but with phi_tool the exact signed distance of each sweep (removal/vdb_sweep.hpp) evaluated in place,
// only at the stock's voxels the sweep's band reaches, instead of rasterising tool level sets and merging grids:
//   - a tool's shank and its band outside the stock would dominate a rasterised tool grid (a D10 tool 50 mm long
//     has ~1600 mm^2 of side wall); here only voxels where the stock is not already empty are ever visited;
//   - max() over exact distances is exact in the band (as csgDifference is), independent of the order of the
//     sweeps, so thousands to millions of sweeps need no batching and the result is bit-identical for any
//     thread count: the work is split by OpenVDB's 128^3 internal nodes, each node gets every sweep that reaches
//     it, in program order, on one thread.
// Within a node, 8^3 leaves and then 4^3 blocks are skipped when the sweep's distance at their centre, minus the
// block's half-diagonal, exceeds the band (distances are 1-Lipschitz), and emptied when they lie deeper inside the
// tool than the band.
//
// Reading back: the first zero crossing along a ray is found by OpenVDB's LevelSetRayIntersector (hierarchical DDA)
// and refined by bisection on the trilinear interpolant (BoxSampler) to 1e-6 voxel: exact for the interpolant along
// rays parallel to a grid axis, as z-map rays are.
#include "core/height_grid.hpp"
#include "core/mesh.hpp"
#include "removal/fields.hpp"
#include "removal/swept_tool.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace vmsim::removal {

struct VdbOptions {
  double voxel_mm = 0.05;
  double half_width_voxels = 3.0;  // OpenVDB's LEVEL_SET_HALF_WIDTH: enough for trilinear reads and meshing
};

struct VdbCutStats {
  std::size_t nodes = 0;        // 128^3 internal nodes visited
  std::size_t leaf_tests = 0;   // (sweep, 8^3 leaf) pairs classified
  std::size_t voxel_evals = 0;  // exact distance evaluations at voxels
};

class VdbPart {
 public:
  VdbPart();
  ~VdbPart();
  VdbPart(const VdbPart& other);  // deep copy
  VdbPart& operator=(const VdbPart& other);
  VdbPart(VdbPart&&) noexcept;
  VdbPart& operator=(VdbPart&&) noexcept;

  // A box stock (createLevelSetBox, exact distances to its faces).
  static VdbPart box(const Box& stock, const VdbOptions& options);
  // A closed triangle-mesh stock (meshToLevelSet). Throws core::Error "<source>: ..." when the mesh is not closed
  // and consistently oriented.
  static VdbPart mesh(const core::TriangleMesh& closed_mesh, const VdbOptions& options,
                      const std::string& source = "triangle mesh");
  // A tri-dexel part as a level set (removal/vdb_from_dexels.cpp): one voxel per dexel node.
  static VdbPart from_tridexel(const TriDexel& field, double half_width_voxels = 3.0);

  bool empty() const;
  double voxel_mm() const;
  double half_width_mm() const;
  std::size_t memory_bytes() const;   // openvdb's memUsage
  std::size_t active_voxels() const;  // the band

  // Removes every sweep (see the header comment). Thread-count independent.
  VdbCutStats cut(const std::vector<SweptTool>& sweeps);

  // Distance from o along the unit vector u to the first zero crossing within [0, length] (0 when o is inside the
  // material, NaN when the ray meets no material).
  double first_crossing(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double length) const;
  // The top surface seen along -Z at the nodes of make_zmap(region, spacing) (NaN where there is no material).
  core::HeightGrid height_grid(const Box& region, double spacing_mm) const;
  // The last material point along each needle (NeedleSet's top(): distance from the needle's start; NaN if none).
  std::vector<double> needle_tops(const NeedleSet& needles) const;
  // The level set's value at points (trilinear, mm); NaN beyond the band, where it holds no distance.
  Eigen::VectorXd signed_distance(const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>& points_mm) const;

  // A closed, consistently oriented triangle mesh of the zero level set (volumeToMesh, quads split into two
  // triangles). adaptivity in [0, 1]: 0 keeps one vertex per surface voxel, larger values merge flat regions.
  core::TriangleMesh mesh(double adaptivity = 0.0) const;
  // Volume enclosed by the zero level set (openvdb::tools::levelSetVolume), mm^3.
  double volume_mm3() const;
  // The level set as a .vdb file (grid "part", float distances in mm), written to a temporary name and renamed.
  void write_vdb(const std::filesystem::path& path) const;
  // Reads the first float level-set grid of a .vdb file (one write_vdb wrote, or Houdini's / Blender's). Throws
  // core::Error "<path>: ..." when the file cannot be read or holds no float level set with uniform voxels.
  static VdbPart read_vdb(const std::filesystem::path& path);

  struct Impl;
  Impl& impl() { return *impl_; }
  const Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

// What the memory estimate needs of a surface: its area, and the sum of its projections on the three axis planes
// (sum over facets of area x (|nx| + |ny| + |nz|): equal to the area for faces along the axes, up to sqrt(3) times it).
struct SurfaceArea {
  double area_mm2 = 0;
  double projected_mm2 = 0;
};
SurfaceArea surface_area(const core::TriangleMesh& mesh);
SurfaceArea surface_area(const Box& box);

// Memory (bytes) of a narrow-band level set of a surface at `voxel_mm`: its active voxels are those within half_width
// voxels of it (a slab T = 2 half_width voxels thick), and a node of side n voxels holds some of them when its centre
// lies within (T + n (|nx| + |ny| + |nz|)) / 2 of the surface (the node's width across the slab), so per unit area a
// surface meets (T + n |n|_1) / n^3 nodes per voxel^2: leaves (n = 8, 8^3 floats and the node, 2.1 kB), 128^3
// internal nodes (16^3 tables, 33 kB) and 4096^3 ones (32^3 tables, 264 kB; at least one of each). Exact in the mean
// for planar pieces larger than a node; curvature and edges add a few percent. The narrow band of a cut part is its
// final surface's: for finishing cuts, about the stock's (the cut surface replaces the surface it cuts through);
// pockets, slots and steps add their new walls and floors. tests/removal/vdb_test.cpp checks it against memUsage.
double estimate_level_set_bytes(const SurfaceArea& surface, double voxel_mm, double half_width_voxels = 3.0);
// Memory (bytes) of the part mesh of such a surface: about one vertex and two triangles per surface voxel, in
// OpenVDB's float output and in core::TriangleMesh.
double estimate_mesh_bytes(double area_mm2, double voxel_mm);
// Surface area of a closed triangle mesh (mm^2).
double mesh_area_mm2(const core::TriangleMesh& mesh);

}  // namespace vmsim::removal
