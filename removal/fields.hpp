#pragma once
// The dexel fields of a stock: a z-map (3-axis work seen from above), a tri-dexel field (three orthogonal grids,
// for vertical walls and undercuts), and N-buffer needles; filling them with a box stock, cutting needles, and
// reading surfaces back.
#include "core/height_grid.hpp"
#include "removal/cut.hpp"
#include "removal/dexel_grid.hpp"

#include <Eigen/Core>

#include <utility>
#include <vector>

namespace vmsim::removal {

struct Box {
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
};

// A share of a stock's rays for one process of a tiled run: tile `index` of `count` holds a contiguous range of
// every grid's rows (rows are a DexelGrid's unit of storage and of parallel work, so no ray is ever split).
struct Tile {
  int index = 0, count = 1;
  bool whole() const { return count == 1; }
};
// The rows [first, end) of a grid of `rows` rows that a tile holds (an even split). Throws when the tile would be
// empty (more tiles than rows).
std::pair<int, int> tile_rows(int rows, const Tile& tile);

// Rays along +Z from z = region.lo.z, one per node (x0 + i h, y0 + j h) covering the region's x/y extent (rows
// along x; a tile holds a band of rows, y0 + j h for j in tile_rows).
DexelGrid make_zmap(const Box& region, double spacing_mm, const Tile& tile = {});

// Three grids whose rays run along X, Y and Z through the region, each at the same spacing (rows: x grid along y
// at one z, y grid along z at one x, z grid along x at one y; a tile holds a band of each).
struct TriDexel {
  DexelGrid x, y, z;
};
TriDexel make_tridexel(const Box& region, double spacing_mm, const Tile& tile = {});

// The rays (nu x nv) of each grid of a field over the region, without making it (memory plans): a z-map's one grid,
// or a tri-dexel's x, y and z grids, as make_zmap / make_tridexel make them.
struct GridShape {
  int nu = 0, nv = 0;
};
std::vector<GridShape> field_shape(const Box& region, double spacing_mm, bool tridexel);

// Material wherever a ray passes through the box (replacing what the rays held).
void fill_box(DexelGrid& grid, const Box& stock);
void fill_box(NeedleSet& needles, const Box& stock);

// Cuts the sweeps out of the needles (blocks of needles in parallel; thread-count independent).
CutStats cut(NeedleSet& needles, const std::vector<SweptTool>& sweeps);

// The top surface of a +Z grid as a height grid (NaN where a ray holds no material; a window of rows gives its band).
core::HeightGrid height_grid(const DexelGrid& zmap);

}  // namespace vmsim::removal
