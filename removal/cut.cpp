#include "removal/cut.hpp"

#include "removal/cut_internal.hpp"
#include "removal/row_bounds.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vmsim::removal {

namespace {

using namespace detail;

constexpr int kBlock = 8;      // rows per work item: a block's rows are one thread's, and one row of tiles
constexpr int kTileCols = 32;  // columns per tile

// A block's tiles (kBlock rows x kTileCols columns of rays): per tile, bounds of its material, tested against a
// sweep's bound over the whole tile before any of its rays. Cutting only removes material, so a top (bottom) once
// taken stays an upper (lower) bound however the tile is cut later; `stale` says a cut has happened since, and a
// test the old bound cannot settle reads the tile again.
struct Tiles {
  std::vector<float> top, bottom;
  std::vector<char> stale_top, stale_bottom, skip;
  int jb0 = 0, jb1 = -1;

  void reset(const DexelGrid& g, int j0, int j1) {
    const std::size_t n = static_cast<std::size_t>((g.nu() + kTileCols - 1) / kTileCols);
    const float inf = std::numeric_limits<float>::infinity();
    top.assign(n, inf);
    bottom.assign(n, -inf);
    stale_top.assign(n, 1);
    stale_bottom.assign(n, 1);
    skip.assign(n, 0);
    jb0 = j0, jb1 = j1;
  }
  void cut(int tc) { stale_top[static_cast<std::size_t>(tc)] = stale_bottom[static_cast<std::size_t>(tc)] = 1; }

  // Reads tile tc's highest top (all the ball kernel needs) and, with both, its lowest bottom.
  void read(const DexelGrid& g, int tc, bool both) {
    const int c0 = tc * kTileCols, n = std::min(kTileCols, g.nu() - c0);
    const auto k = static_cast<std::size_t>(tc);
    stale_top[k] = 0;
    float t;
    if (!both && (use_avx2() ? tile_top_avx2 : tile_top_generic)(g.head_row(jb0) + c0, static_cast<std::size_t>(g.nu()),
                                                                   jb1 - jb0 + 1, n, t)) {
      top[k] = t;
      return;
    }
    const float inf = std::numeric_limits<float>::infinity();
    float hi = -inf, lo = inf;
    for (int j = jb0; j <= jb1; ++j) {
      const Interval* h = g.head_row(j) + c0;
      for (int i = 0; i < n; ++i) {
        if (std::isnan(h[i].lo)) {  // several intervals
          hi = std::max(hi, static_cast<float>(g.top(c0 + i, j)));
          lo = std::min(lo, static_cast<float>(g.bottom(c0 + i, j)));
        } else if (h[i].lo <= h[i].hi) {
          hi = std::max(hi, h[i].hi);
          lo = std::min(lo, h[i].lo);
        }
      }
    }
    top[k] = hi;
    if (both) bottom[k] = lo, stale_bottom[k] = 0;
  }
};

// A lower bound of the ball sweep's lowest point on every ray of the rectangle qu in [qu0, qu1], qv in [qv0, qv1]
// (relative to the centre's start): the ray kernel's bound min over l of delta l + r(l)^2 / 2R, with r^2 = perp^2 +
// ee (l - l*)^2, split into its least perp over the rectangle and the least of delta l + ee dist(l, [s0, s1])^2 / 2R,
// where [s0, s1] is the range of l* over it (both linear in q, so their ranges are at the corners); the second is
// convex in l, least at the clamped stationary point.
double tile_lower_bound(const AxialBall& b, double qu0, double qu1, double qv0, double qv1) {
  double cr0 = 1e300, cr1 = -1e300, s0 = 1e300, s1 = -1e300;
  for (const double qu : {qu0, qu1}) {
    for (const double qv : {qv0, qv1}) {
      const double cr = qu * b.ev - qv * b.eu, s = (qu * b.eu + qv * b.ev) * b.inv_ee;
      cr0 = std::min(cr0, cr), cr1 = std::max(cr1, cr), s0 = std::min(s0, s), s1 = std::max(s1, s);
    }
  }
  const double c = cr0 > 0 ? cr0 : (cr1 < 0 ? -cr1 : 0.0);
  const double shift = b.delta * b.R * b.inv_ee;
  const double l = std::clamp(b.delta >= 0 ? s0 - shift : s1 - shift, 0.0, 1.0);
  const double d = l < s0 ? s0 - l : (l > s1 ? l - s1 : 0.0);
  return (b.cw - b.R) + b.delta * l + (c * c * b.inv_ee + b.ee * d * d) * (0.5 / b.R);
}

struct Counts {
  std::size_t tests = 0, cuts = 0, tile = 0, bound = 0, nothing = 0;
};

// One ball sweep along the rays on the rows [j0, j1] of a block.
void cut_block_axial_ball(DexelGrid& g, const AxialBall& b, const Footprint& f, int j0, int j1, Tiles& tiles,
                          std::vector<RowFallback>& fb, Counts& c) {
  int ia[kBlock], ib[kBlock];
  int umin = g.nu(), umax = -1, r0 = -1, r1 = -1;
  for (int j = j0; j <= j1; ++j) {
    int& a = ia[j - j0];
    int& e = ib[j - j0];
    if (!axial_ball_columns(g, b, j, f.i0, f.i1, a, e)) {
      a = 1, e = 0;
      continue;
    }
    c.tests += static_cast<std::size_t>(e - a + 1);
    umin = std::min(umin, a), umax = std::max(umax, e);
    if (r0 < 0) r0 = j;
    r1 = j;
  }
  if (umax < 0) return;
  // Tiles first: the bound over a tile against its highest top. The margin covers the round-off of the kernel's t0
  // near a ray's rim (a square root of a difference of squares of |q| ~ the sweep's length; 1e-5 mm for 1 m moves).
  const double qv0 = g.v_of(r0) - b.cv, qv1 = g.v_of(r1) - b.cv;
  for (int tc = umin / kTileCols; tc <= umax / kTileCols; ++tc) {
    const auto k = static_cast<std::size_t>(tc);
    const int c0 = std::max(umin, tc * kTileCols), c1 = std::min(umax, tc * kTileCols + kTileCols - 1);
    const double qu0 = c0 * g.du() - b.cu, qu1 = c1 * g.du() - b.cu;
    const double qmax = std::max({std::abs(qu0), std::abs(qu1), std::abs(qv0), std::abs(qv1)}) + b.el;
    const double lb = tile_lower_bound(b, qu0, qu1, qv0, qv1) - 1e-6 * (1 + std::sqrt(b.R * (qmax + b.R)));
    bool skip = lb >= tiles.top[k];
    if (!skip && tiles.stale_top[k]) {
      tiles.read(g, tc, false);
      skip = lb >= tiles.top[k];
    }
    tiles.skip[k] = skip;
  }
  const RowCutParams p = row_params(g, b);
  const bool avx2 = use_avx2();
  for (int j = j0; j <= j1; ++j) {
    const int a = ia[j - j0], e = ib[j - j0];
    if (a > e) continue;
    const double qv = g.v_of(j) - b.cv;
    Interval* head = g.head_row(j);
    for (int tc = a / kTileCols; tc <= e / kTileCols; ++tc) {
      const auto k = static_cast<std::size_t>(tc);
      const int s0 = std::max(a, tc * kTileCols), s1 = std::min(e, tc * kTileCols + kTileCols - 1);
      if (tiles.skip[k]) {
        c.tile += static_cast<std::size_t>(s1 - s0 + 1);
        continue;
      }
      RowCutCounts rc;
      const int nfb = (avx2 ? row_cut_avx2 : row_cut_generic)(p, qv, s0, s1, head, g.length(), fb.data(), rc);
      c.bound += static_cast<std::size_t>(rc.bound_skipped);
      c.nothing += static_cast<std::size_t>(rc.exact_nothing);
      c.cuts += static_cast<std::size_t>(rc.cut);
      bool changed = rc.cut > 0;
      // cut_reference's scalar steps for the rays left over.
      for (int q = 0; q < nfb; ++q) {
        const int i = fb[static_cast<std::size_t>(q)].i;
        const double t0 = fb[static_cast<std::size_t>(q)].t0, top = g.top(i, j);
        if (t0 >= top || t0 >= g.length()) {
          ++c.nothing;
          continue;
        }
        double t1 = fb[static_cast<std::size_t>(q)].t1;
        if (t1 < top) {
          t1 = axial_ball_top(b, qv, i * g.du() - b.cu);  // material above the tool's lowest top: the exact end
        } else {
          t1 = std::max(top, g.length()) + 1.0;  // past the material: the cut takes everything above t0
        }
        if (t1 <= 0) {
          ++c.nothing;
          continue;
        }
        g.subtract(i, j, t0, t1);
        ++c.cuts;
        changed = true;
      }
      if (changed) tiles.cut(tc);
    }
  }
}

// Any other sweep on the rows [j0, j1] of a block: the general ray test on the rays whose material meets the sweep's
// extent along them, tiles first.
void cut_block_general(DexelGrid& g, const SweptTool& sw, const Footprint& f, std::pair<double, double> wext, int j0,
                       int j1, Tiles& tiles, Counts& c) {
  const GeneralRows rows = general_rows(g, sw);
  int ia[kBlock], ib[kBlock];
  int umin = g.nu(), umax = -1;
  for (int j = j0; j <= j1; ++j) {
    general_row_range(g, rows, j, f.i0, f.i1, ia[j - j0], ib[j - j0]);
    if (ia[j - j0] > ib[j - j0]) continue;
    umin = std::min(umin, ia[j - j0]), umax = std::max(umax, ib[j - j0]);
  }
  if (umax < 0) return;
  const auto [w0, w1] = wext;
  // A tile whose material lies wholly before or after the sweep's extent along the rays is left as it is (each of its
  // rays would be, below).
  for (int tc = umin / kTileCols; tc <= umax / kTileCols; ++tc) {
    const auto k = static_cast<std::size_t>(tc);
    auto outside = [&] { return w1 <= tiles.bottom[k] || w0 >= tiles.top[k]; };
    bool skip = outside();
    if (!skip && (tiles.stale_top[k] || tiles.stale_bottom[k])) {
      tiles.read(g, tc, true);
      skip = outside();
    }
    tiles.skip[k] = skip;
  }
  const Eigen::Vector3d W = g.W();
  for (int j = j0; j <= j1; ++j) {
    const int a = ia[j - j0], e = ib[j - j0];
    const Interval* head = g.head_row(j);
    for (int tc = a / kTileCols; a <= e && tc <= e / kTileCols; ++tc) {
      const auto k = static_cast<std::size_t>(tc);
      if (tiles.skip[k]) continue;
      bool changed = false;
      for (int i = std::max(a, tc * kTileCols); i <= std::min(e, tc * kTileCols + kTileCols - 1); ++i) {
        // A ray whose material lies wholly before or after the sweep's extent along it is left as it is (subtract
        // would not change it): no exact test. Most rays across a tool's shank run through air.
        const Interval h = head[i];
        if (!std::isnan(h.lo) && (!(h.lo <= h.hi) || w1 <= h.lo || w0 >= h.hi)) continue;
        double t0, t1;
        ++c.tests;
        if (!ray_interval(sw, g.ray_origin(i, j), W, t0, t1)) continue;
        if (t1 <= 0 || t0 >= g.length() || t1 - t0 <= 1e-9) continue;  // zero-width contacts cut nothing
        g.subtract(i, j, t0, t1);
        ++c.cuts;
        changed = true;
      }
      if (changed) tiles.cut(tc);
    }
  }
}

}  // namespace

Footprint footprint(const DexelGrid& grid, const SweptTool& sweep) {
  Eigen::Vector3d lo, hi;
  sweep.bounds(lo, hi);
  double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300, wmin = 1e300, wmax = -1e300;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d p((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d q = p - grid.origin();
    umin = std::min(umin, q.dot(grid.U())), umax = std::max(umax, q.dot(grid.U()));
    vmin = std::min(vmin, q.dot(grid.V())), vmax = std::max(vmax, q.dot(grid.V()));
    wmin = std::min(wmin, q.dot(grid.W())), wmax = std::max(wmax, q.dot(grid.W()));
  }
  // Lattice rows first (a window's rows are the lattice's from v_first on), clamped in double so far-away sweeps
  // cannot overflow an int.
  const double lattice_j0 = std::ceil(vmin / grid.dv()), lattice_j1 = std::floor(vmax / grid.dv());
  Footprint f;
  f.i0 = std::max(0, static_cast<int>(std::ceil(umin / grid.du())));
  f.i1 = std::min(grid.nu() - 1, static_cast<int>(std::floor(umax / grid.du())));
  f.j0 = static_cast<int>(std::clamp(lattice_j0 - grid.v_first(), 0.0, double(grid.nv())));
  f.j1 = static_cast<int>(std::clamp(lattice_j1 - grid.v_first(), -1.0, double(grid.nv() - 1)));
  f.w0 = wmin, f.w1 = wmax;
  return f;
}

std::vector<SweptTool> sweeps_reaching(const DexelGrid& grid, const std::vector<SweptTool>& sweeps) {
  std::vector<SweptTool> out;
  for (const SweptTool& s : sweeps)
    if (!footprint(grid, s).empty()) out.push_back(s);
  return out;
}

CutStats cut(DexelGrid& grid, const std::vector<SweptTool>& sweeps) {
  const int nblocks = (grid.nv() + kBlock - 1) / kBlock;
  // Each sweep's footprint on the grid (the rays whose line can meet its bounding box), binned by row block.
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
  std::size_t tests = 0, cuts = 0, tile = 0, bound = 0, nothing = 0;
#pragma omp parallel reduction(+ : tests, cuts, tile, bound, nothing)
  {
    Tiles tiles;
    std::vector<RowFallback> fb(kTileCols);
    Counts c;
#pragma omp for schedule(dynamic, 1)
    for (int b = 0; b < nblocks; ++b) {
      const int jb0 = b * kBlock, jb1 = std::min(grid.nv() - 1, jb0 + kBlock - 1);
      tiles.reset(grid, jb0, jb1);
      for (int k : bins[static_cast<std::size_t>(b)]) {
        const Footprint& f = fp[static_cast<std::size_t>(k)];
        const SweptTool& sw = sweeps[static_cast<std::size_t>(k)];
        const int j0 = std::max(jb0, f.j0), j1 = std::min(jb1, f.j1);
        AxialBall ab;
        if (axial_ball(grid, sw, ab)) {
          cut_block_axial_ball(grid, ab, f, j0, j1, tiles, fb, c);
        } else {
          cut_block_general(grid, sw, f, wext[static_cast<std::size_t>(k)], j0, j1, tiles, c);
        }
      }
    }
    tests += c.tests, cuts += c.cuts, tile += c.tile, bound += c.bound, nothing += c.nothing;
  }
  CutStats s;
  s.ray_tests = tests;
  s.cuts = cuts;
  s.tile_skipped = tile;
  s.bound_skipped = bound;
  s.exact_nothing = nothing;
  return s;
}

}  // namespace vmsim::removal
