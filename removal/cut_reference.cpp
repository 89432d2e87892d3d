#include "removal/cut_reference.hpp"

#include "removal/cut_internal.hpp"
#include "removal/fields.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::removal {

namespace {

using namespace detail;

std::size_t cut_row_axial_ball(DexelGrid& g, const AxialBall& b, int j, int i0, int i1) {
  int ia, ib;
  if (!axial_ball_columns(g, b, j, i0, i1, ia, ib)) return 0;
  const double qv = g.v_of(j) - b.cv;
  const RowCutParams p = row_params(g, b);
  constexpr int kChunk = 256;
  double lbs[kChunk], t0s[kChunk], t1s[kChunk];
  int idx[kChunk];
  const bool avx2 = use_avx2();
  for (int c0 = ia; c0 <= ib; c0 += kChunk) {
    const int n = std::min(kChunk, ib - c0 + 1);
    const Interval* head = g.head_row(j) + c0;
    // Keep the rays whose material the sweep may reach (a NaN in place, several intervals: kept), then the exact cut.
    (avx2 ? row_prefilter_avx2 : row_prefilter_generic)(p, qv, c0, n, lbs);
    int m = 0;
    for (int k = 0; k < n; ++k) {
      idx[m] = k;
      m += !(lbs[k] >= head[k].hi);
    }
    if (m == 0) continue;
    (avx2 ? row_bounds_avx2 : row_bounds_generic)(p, qv, c0, idx, m, t0s, t1s);
    for (int q = 0; q < m; ++q) {
      const int k = idx[q];
      if (t0s[q] >= head[k].hi) continue;  // false for NaN: such rays are read properly below
      const int i = c0 + k;
      const double t0 = t0s[q], top = g.top(i, j);
      if (t0 >= top || t0 >= g.length()) continue;
      double t1 = t1s[q];
      if (t1 < top) {
        t1 = axial_ball_top(b, qv, i * g.du() - b.cu);  // material above the tool's lowest top: the exact end
      } else {
        t1 = std::max(top, g.length()) + 1.0;  // past the material: the cut takes everything above t0
      }
      if (t1 <= 0) continue;
      g.subtract(i, j, t0, t1);
    }
  }
  return static_cast<std::size_t>(ib - ia + 1);
}

}  // namespace

CutStats cut_reference(DexelGrid& grid, const std::vector<SweptTool>& sweeps) {
  constexpr int kBlock = 8;  // rows per work item
  const int nblocks = (grid.nv() + kBlock - 1) / kBlock;
  std::vector<Footprint> fp(sweeps.size());
  std::vector<std::pair<double, double>> wext(sweeps.size());
  std::vector<std::vector<int>> bins(static_cast<std::size_t>(nblocks));
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    const Footprint f = footprint(grid, sweeps[k]);
    wext[k] = widened_extent(f.w0, f.w1);
    fp[k] = f;
    if (f.empty()) continue;
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
      AxialBall ab;
      if (axial_ball(grid, sw, ab)) {
        for (int j = std::max(jb0, f.j0); j <= std::min(jb1, f.j1); ++j) tests += cut_row_axial_ball(grid, ab, j, f.i0, f.i1);
        continue;
      }
      const GeneralRows rows = general_rows(grid, sw);
      for (int j = std::max(jb0, f.j0); j <= std::min(jb1, f.j1); ++j) {
        int ia, ib;
        general_row_range(grid, rows, j, f.i0, f.i1, ia, ib);
        const Interval* head = grid.head_row(j);
        for (int i = ia; i <= ib; ++i) {
          const Interval h = head[i];
          const auto [w0, w1] = wext[static_cast<std::size_t>(k)];
          if (!std::isnan(h.lo) && (!(h.lo <= h.hi) || w1 <= h.lo || w0 >= h.hi)) continue;
          double t0, t1;
          ++tests;
          if (!ray_interval(sw, grid.ray_origin(i, j), W, t0, t1)) continue;
          if (t1 <= 0 || t0 >= grid.length() || t1 - t0 <= 1e-9) continue;  // zero-width contacts cut nothing
          grid.subtract(i, j, t0, t1);
          ++cuts;
        }
      }
    }
  }
  CutStats s;
  s.ray_tests = tests;
  s.cuts = cuts;
  return s;
}

CutStats cut_reference(NeedleSet& n, const std::vector<SweptTool>& sweeps) {
  const std::size_t nblocks = (n.size() + NeedleSet::kBlock - 1) / NeedleSet::kBlock;
  std::vector<Box> sb(sweeps.size());
  std::vector<std::size_t> order(sweeps.size());
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    sweeps[k].bounds(sb[k].lo, sb[k].hi);
    order[k] = k;
  }
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return sb[a].lo.x() < sb[b].lo.x(); });
  double max_width = 0;
  for (const Box& b : sb) max_width = std::max(max_width, b.hi.x() - b.lo.x());
  std::size_t tests = 0, cuts = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : tests, cuts)
  for (std::ptrdiff_t bi = 0; bi < static_cast<std::ptrdiff_t>(nblocks); ++bi) {
    const std::size_t k0 = static_cast<std::size_t>(bi) * NeedleSet::kBlock, k1 = std::min(n.size(), k0 + NeedleSet::kBlock);
    Box bb{Eigen::Vector3d::Constant(1e300), Eigen::Vector3d::Constant(-1e300)};
    for (std::size_t k = k0; k < k1; ++k) {
      const Eigen::Vector3d a = n.origin(k), e = a + n.length(k) * n.direction(k);
      bb.lo = bb.lo.cwiseMin(a.cwiseMin(e));
      bb.hi = bb.hi.cwiseMax(a.cwiseMax(e));
    }
    auto first = std::lower_bound(order.begin(), order.end(), bb.lo.x() - max_width,
                                  [&](std::size_t s, double v) { return sb[s].lo.x() < v; });
    std::vector<std::size_t> cand;
    for (auto it = first; it != order.end() && sb[*it].lo.x() <= bb.hi.x(); ++it) {
      const Box& s = sb[*it];
      if ((s.hi.array() >= bb.lo.array()).all() && (s.lo.array() <= bb.hi.array()).all()) cand.push_back(*it);
    }
    std::sort(cand.begin(), cand.end());
    for (std::size_t k = k0; k < k1; ++k) {
      for (std::size_t s : cand) {
        double t0, t1;
        ++tests;
        if (!ray_interval(sweeps[s], n.origin(k), n.direction(k), t0, t1)) continue;
        if (t1 <= 0 || t0 >= n.length(k) || t1 - t0 <= 1e-9) continue;
        n.store().subtract(k, t0, t1);
        ++cuts;
      }
    }
  }
  CutStats s;
  s.ray_tests = tests;
  s.cuts = cuts;
  return s;
}

}  // namespace vmsim::removal
