#include "removal/cut.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::removal {

CutStats cut(DexelGrid& grid, const std::vector<SweptTool>& sweeps) {
  constexpr int kBlock = 8;  // rows per work item
  const int nblocks = (grid.nv() + kBlock - 1) / kBlock;
  // Each sweep's footprint on the grid (the rays whose line can meet its bounding box), binned by row block.
  struct Footprint {
    int i0, i1, j0, j1;
  };
  std::vector<Footprint> fp(sweeps.size());
  std::vector<std::vector<int>> bins(static_cast<std::size_t>(nblocks));
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    Eigen::Vector3d lo, hi;
    sweeps[k].bounds(lo, hi);
    double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d p((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
      const Eigen::Vector3d q = p - grid.origin();
      umin = std::min(umin, q.dot(grid.U())), umax = std::max(umax, q.dot(grid.U()));
      vmin = std::min(vmin, q.dot(grid.V())), vmax = std::max(vmax, q.dot(grid.V()));
    }
    Footprint f;
    f.i0 = std::max(0, static_cast<int>(std::ceil(umin / grid.du())));
    f.i1 = std::min(grid.nu() - 1, static_cast<int>(std::floor(umax / grid.du())));
    f.j0 = std::max(0, static_cast<int>(std::ceil(vmin / grid.dv())));
    f.j1 = std::min(grid.nv() - 1, static_cast<int>(std::floor(vmax / grid.dv())));
    fp[k] = f;
    if (f.i0 > f.i1 || f.j0 > f.j1) continue;
    for (int b = f.j0 / kBlock; b <= f.j1 / kBlock; ++b) bins[static_cast<std::size_t>(b)].push_back(static_cast<int>(k));
  }
  std::size_t tests = 0, cuts = 0;
  const Eigen::Vector3d W = grid.W();
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : tests, cuts)
  for (int b = 0; b < nblocks; ++b) {
    const int jb0 = b * kBlock, jb1 = std::min(grid.nv() - 1, jb0 + kBlock - 1);
    for (int k : bins[static_cast<std::size_t>(b)]) {
      const Footprint& f = fp[static_cast<std::size_t>(k)];
      const SweptTool& sw = sweeps[static_cast<std::size_t>(k)];
      for (int j = std::max(jb0, f.j0); j <= std::min(jb1, f.j1); ++j) {
        for (int i = f.i0; i <= f.i1; ++i) {
          double t0, t1;
          ++tests;
          if (!ray_interval(sw, grid.ray_origin(i, j), W, t0, t1)) continue;
          if (t1 <= 0 || t0 >= grid.length()) continue;
          grid.subtract(i, j, t0, t1);
          ++cuts;
        }
      }
    }
  }
  return {tests, cuts};
}

}  // namespace vmsim::removal
