#pragma once
// The dexel fields of a stock: a z-map (3-axis work seen from above), a tri-dexel field (three orthogonal grids,
// for vertical walls and undercuts), and N-buffer needles; filling them with a box stock, cutting needles, and
// reading surfaces back.
#include "core/height_grid.hpp"
#include "removal/cut.hpp"
#include "removal/dexel_grid.hpp"

#include <Eigen/Core>

namespace vmsim::removal {

struct Box {
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
};

// Rays along +Z from z = region.lo.z, one per node (x0 + i h, y0 + j h) covering the region's x/y extent.
DexelGrid make_zmap(const Box& region, double spacing_mm);

// Three grids whose rays run along X, Y and Z through the region, each at the same spacing.
struct TriDexel {
  DexelGrid x, y, z;
};
TriDexel make_tridexel(const Box& region, double spacing_mm);

// Material wherever a ray passes through the box (replacing what the rays held).
void fill_box(DexelGrid& grid, const Box& stock);
void fill_box(NeedleSet& needles, const Box& stock);

// Cuts the sweeps out of the needles (blocks of needles in parallel; thread-count independent).
CutStats cut(NeedleSet& needles, const std::vector<SweptTool>& sweeps);

// The top surface of a +Z grid as a height grid (NaN where a ray holds no material).
core::HeightGrid height_grid(const DexelGrid& zmap);

}  // namespace vmsim::removal
