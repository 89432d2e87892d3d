// VdbPart::cut: phi = max(phi, -phi_sweep) at every voxel of the stock a sweep's band reaches (vdb_part.hpp says why
// this rather than rasterised tool grids and openvdb::tools::csgDifference).
#include "removal/vdb_grid.hpp"
#include "removal/vdb_sweep.hpp"

#include "core/error.hpp"

#include <openvdb/tools/Prune.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace vmsim::removal {

namespace {

using Grid = openvdb::FloatGrid;
using Tree = Grid::TreeType;
using Leaf = Tree::LeafNodeType;
using Node1 = Tree::RootNodeType::ChildNodeType::ChildNodeType;  // 128^3 voxels, children are 8^3 leaves
static_assert(Node1::LEVEL == 1 && Leaf::DIM == 8 && Node1::DIM == 128);
constexpr openvdb::Int32 kNodeMask = ~openvdb::Int32(Node1::DIM - 1), kLeafMask = ~openvdb::Int32(Leaf::DIM - 1);

struct Work {
  openvdb::Coord origin;
  Node1* node = nullptr;
  std::vector<std::size_t> sweeps;
};

// Index-space box of the voxels within the band of a sweep, clipped to `clip`.
openvdb::CoordBBox sweep_voxels(const SweptTool& s, const openvdb::math::Transform& xf, double reach_mm,
                                const openvdb::CoordBBox& clip) {
  Eigen::Vector3d lo, hi;
  s.bounds(lo, hi);
  lo.array() -= reach_mm;
  hi.array() += reach_mm;
  const openvdb::Vec3d a = xf.worldToIndex(openvdb::Vec3d(lo.x(), lo.y(), lo.z()));
  const openvdb::Vec3d b = xf.worldToIndex(openvdb::Vec3d(hi.x(), hi.y(), hi.z()));
  openvdb::CoordBBox box(openvdb::Coord::floor(a), openvdb::Coord::ceil(b));
  box.intersect(clip);
  return box;
}

}  // namespace

VdbCutStats VdbPart::cut(const std::vector<SweptTool>& sweeps) {
  if (empty()) throw core::Error("vdb: cut on an empty part");
  Grid& grid = *impl_->grid;
  Tree& tree = grid.tree();
  const openvdb::math::Transform& xf = grid.transform();
  const double h = grid.voxelSize()[0];
  const float bg = tree.background();
  VdbCutStats stats;
  // Every voxel inside the material lies within the band's bounding box (the band encloses the interior).
  openvdb::CoordBBox material;
  if (!tree.evalActiveVoxelBoundingBox(material)) return stats;

  // 1. Bin the sweeps by the 128^3 nodes their band can reach (program order within each bin).
  std::map<openvdb::Coord, std::vector<std::size_t>> bins;
  const double reach = bg + h;
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    const openvdb::CoordBBox box = sweep_voxels(sweeps[k], xf, reach, material);
    if (box.empty()) continue;
    const openvdb::Coord n0 = box.min() & kNodeMask, n1 = box.max() & kNodeMask;
    for (int x = n0.x(); x <= n1.x(); x += Node1::DIM)
      for (int y = n0.y(); y <= n1.y(); y += Node1::DIM)
        for (int z = n0.z(); z <= n1.z(); z += Node1::DIM) bins[openvdb::Coord(x, y, z)].push_back(k);
  }

  // 2. Serially, give every bin a node of its own: regions outside the material are dropped (a difference never
  //    adds material), tiles inside it are expanded. After this, threads only touch their own node's children.
  std::vector<Work> work;
  work.reserve(bins.size());
  for (auto& [origin, list] : bins) {
    Node1* node = tree.probeNode<Node1>(origin);
    if (!node) {
      float v;
      tree.probeValue(origin, v);
      if (v > 0) continue;
      tree.touchLeaf(origin);
      node = tree.probeNode<Node1>(origin);
    }
    work.push_back({origin, node, std::move(list)});
  }
  stats.nodes = work.size();

  // 3. Each node, on one thread: its sweeps in program order, leaf by leaf, 4^3 block by block.
  const double leaf_r = 3.5 * std::sqrt(3.0) * h, block_r = 1.5 * std::sqrt(3.0) * h;
  std::size_t leaf_tests = 0, voxel_evals = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : leaf_tests, voxel_evals)
  for (std::ptrdiff_t wi = 0; wi < static_cast<std::ptrdiff_t>(work.size()); ++wi) {
    Work& w = work[static_cast<std::size_t>(wi)];
    const openvdb::CoordBBox node_box(w.origin, w.origin.offsetBy(Node1::DIM - 1));
    for (std::size_t k : w.sweeps) {
      const SweepDistance sd(sweeps[k]);
      openvdb::CoordBBox box = sweep_voxels(sweeps[k], xf, reach, material);
      box.intersect(node_box);
      if (box.empty()) continue;
      const openvdb::Coord l0 = box.min() & kLeafMask, l1 = box.max() & kLeafMask;
      for (int lx = l0.x(); lx <= l1.x(); lx += Leaf::DIM)
        for (int ly = l0.y(); ly <= l1.y(); ly += Leaf::DIM)
          for (int lz = l0.z(); lz <= l1.z(); lz += Leaf::DIM) {
            const openvdb::Coord lo(lx, ly, lz);
            const openvdb::Vec3d c = xf.indexToWorld(lo.asVec3d() + openvdb::Vec3d(3.5));
            const double phi = sd(Eigen::Vector3d(c.x(), c.y(), c.z()));
            ++leaf_tests;
            if (phi - leaf_r >= bg) continue;  // the sweep's band misses the leaf
            // The child or, without one, the tile value straight from the node's table. (Node1::getValue(lo)
            // after a null probeLeaf made GCC 12 inline the child branch too, with a null child, and warn
            // -Wstringop-overflow about the leaf's delayed-load mutex; reading the table has no such branch.)
            const openvdb::Index slot = Node1::coordToOffset(lo);
            Leaf* leaf = w.node->isChildMaskOn(slot) ? w.node->probeLeaf(lo) : nullptr;
            if (!leaf && w.node->getTable()[slot].getValue() > 0) continue;  // already empty
            if (phi + leaf_r <= -bg) {
              w.node->addTile(1, lo, bg, false);  // deeper inside the tool than the band: empty
              continue;
            }
            if (!leaf) leaf = w.node->touchLeaf(lo);  // inside tile: a leaf of -bg to carve
            // 4^3 blocks, then voxels.
            for (int b = 0; b < 8; ++b) {
              const openvdb::Coord bo = lo + openvdb::Coord((b & 1) * 4, ((b >> 1) & 1) * 4, ((b >> 2) & 1) * 4);
              const openvdb::Vec3d bc = xf.indexToWorld(bo.asVec3d() + openvdb::Vec3d(1.5));
              const double pb = sd(Eigen::Vector3d(bc.x(), bc.y(), bc.z()));
              if (pb - block_r >= bg) continue;
              const bool deep = pb + block_r <= -bg;
              for (int i = 0; i < 4; ++i)
                for (int j = 0; j < 4; ++j)
                  for (int kk = 0; kk < 4; ++kk) {
                    const openvdb::Coord ijk = bo.offsetBy(i, j, kk);
                    const openvdb::Index n = Leaf::coordToOffset(ijk);
                    const float v = leaf->getValue(n);
                    if (v >= bg) continue;  // empty already
                    // sd >= pb - block_r at every voxel of the block (1-Lipschitz), so -sd cannot exceed v: skip
                    // the exact evaluation (most voxels, where consecutive sweeps overlap).
                    if (!deep && v >= block_r - pb) continue;
                    float nv = bg;
                    if (!deep) {
                      const openvdb::Vec3d p = xf.indexToWorld(ijk);
                      ++voxel_evals;
                      const double cand = -sd(Eigen::Vector3d(p.x(), p.y(), p.z()));
                      if (!(cand > v)) continue;
                      nv = static_cast<float>(std::min<double>(cand, bg));
                    }
                    leaf->setValueOnly(n, nv);
                    leaf->setActiveState(n, nv < bg && nv > -bg);
                  }
            }
          }
    }
  }
  stats.leaf_tests = leaf_tests;
  stats.voxel_evals = voxel_evals;
  // Leaves left uniformly empty or full become tiles again (deterministic, whatever the thread count).
  openvdb::tools::pruneLevelSet(tree);
  return stats;
}

}  // namespace vmsim::removal
