#include "removal/cut.hpp"

#include "removal/cut_internal.hpp"
#include "removal/row_bounds.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <omp.h>

namespace vmsim::removal {

namespace {

using namespace detail;

constexpr int kBlock = 8;  // rows per work item: a block's rows are one thread's, and one row of tiles

// A block's tiles (kBlock rows x kTileCols columns of rays): per tile, bounds of its material, tested against a
// sweep's bound over the whole tile before any of its rays. Cutting only removes material, so a top (bottom) once
// taken stays an upper (lower) bound however the tile is cut later; `stale` says a cut has happened since, and a
// test the old bound cannot settle reads the tile again.
struct Tiles {
  std::vector<float> top, bottom;
  std::vector<char> stale_top, stale_bottom, skip;
  std::vector<unsigned char> cut_mark;  // tiles a kernel call cut (cleared by the caller)
  std::vector<unsigned char> settled;   // tiles a chunk's bound settled (for its members)
  int jb0 = 0, jb1 = -1;

  int shift = 5;  // columns per tile: 1 << shift
  int cols() const { return 1 << shift; }

  void reset(const DexelGrid& g, int j0, int j1, int tile_shift) {
    shift = tile_shift;
    const std::size_t n = static_cast<std::size_t>((g.nu() + cols() - 1) / cols());
    const float inf = std::numeric_limits<float>::infinity();
    top.assign(n, inf);
    bottom.assign(n, -inf);
    stale_top.assign(n, 1);
    stale_bottom.assign(n, 1);
    skip.assign(n, 0);
    cut_mark.assign(n + 1, 0);  // a kernel's last group of four may mark the tile past the grid's last column
    settled.assign(n, 0);
    jb0 = j0, jb1 = j1;
    skip_several = false;
  }
  void cut(int tc) { stale_top[static_cast<std::size_t>(tc)] = stale_bottom[static_cast<std::size_t>(tc)] = 1; }

  // Rays with several intervals left out of the tops (the order-free pass, which replays them all).
  bool skip_several = false;

  // Reads tile tc's highest top (all the ball kernel needs) and, with both, its lowest bottom.
  void read(const DexelGrid& g, int tc, bool both) {
    const int c0 = tc * cols(), n = std::min(cols(), g.nu() - c0);
    const auto k = static_cast<std::size_t>(tc);
    stale_top[k] = 0;
    float t;
    if (!both && (use_avx2() ? tile_top_avx2 : tile_top_generic)(g.head_row(jb0) + c0, static_cast<std::size_t>(g.nu()),
                                                                 jb1 - jb0 + 1, n, skip_several, t)) {
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
// where [s0, s1] is the range of l* over it (perp el = qu ev - qv eu and l* ee = qu eu + qv ev are linear and
// separable: their ranges add the ranges of the qu and qv terms); the second is convex in l, least at the clamped
// stationary point. The qv terms are the same for every tile of a sweep's block: TileBound holds them.
struct TileBound {
  const AxialBall& b;
  double cr_v0, cr_v1, s_v0, s_v1;  // ranges of -qv eu and qv ev over [qv0, qv1]
  double shift, half_inv_r;
  TileBound(const AxialBall& ball, double qv0, double qv1) : b(ball) {
    cr_v0 = std::min(-qv0 * b.eu, -qv1 * b.eu), cr_v1 = std::max(-qv0 * b.eu, -qv1 * b.eu);
    s_v0 = std::min(qv0 * b.ev, qv1 * b.ev), s_v1 = std::max(qv0 * b.ev, qv1 * b.ev);
    shift = b.delta * b.R * b.inv_ee, half_inv_r = 0.5 / b.R;
    k8 = 1 / (8 * b.R * b.R * b.R), k16 = k8 / (2 * b.R * b.R);
  }
  // The section's height R - sqrt(R^2 - r^2) is r^2/2R + r^4/8R^3 + r^6/16R^5 + ... (all terms positive), and r^2 >=
  // p, the least squared distance across the move: p^2/8R^3 + p^3/16R^5 added keep a lower bound, a little tighter.
  double k8, k16;
  double operator()(double qu0, double qu1) const {
    const double cr0 = std::min(qu0 * b.ev, qu1 * b.ev) + cr_v0, cr1 = std::max(qu0 * b.ev, qu1 * b.ev) + cr_v1;
    const double s0 = (std::min(qu0 * b.eu, qu1 * b.eu) + s_v0) * b.inv_ee;
    const double s1 = (std::max(qu0 * b.eu, qu1 * b.eu) + s_v1) * b.inv_ee;
    const double c = cr0 > 0 ? cr0 : (cr1 < 0 ? -cr1 : 0.0);
    const double l = std::clamp(b.delta >= 0 ? s0 - shift : s1 - shift, 0.0, 1.0);
    const double d = l < s0 ? s0 - l : (l > s1 ? l - s1 : 0.0);
    const double p = c * c * b.inv_ee;  // the least squared distance across the move over the rectangle
    return (b.cw - b.R) + b.delta * l + (p + b.ee * d * d) * half_inv_r + p * p * (k8 + p * k16);
  }
};

struct Counts {
  std::size_t tests = 0, cuts = 0, tile = 0, bound = 0, nothing = 0, blocks = 0, replayed = 0, chunk_skipped = 0;
};

// A ray of a block the order-free pass must leave to the replay in program order (row j, column i).
struct Flagged {
  int j, i;
  bool operator<(const Flagged& o) const { return j != o.j ? j < o.j : i < o.i; }
  bool operator==(const Flagged& o) const { return j == o.j && i == o.i; }
};

// cut_reference's steps for one sweep on the rays [s0, s1] of row j, in place; a ray cut sets its tile's cut_tiles.
void cut_segment(DexelGrid& g, const AxialBall& b, const RowCutParams& p, int j, int s0, int s1,
                 unsigned char* cut_tiles, int tile_shift, RowFallback* fb, Counts& c) {
  const double qv = g.v_of(j) - b.cv;
  RowCutCounts rc;
  const int nfb = (use_avx2() ? row_cut_avx2 : row_cut_generic)(p, qv, s0, s1, g.head_row(j), g.length(), cut_tiles,
                                                                tile_shift, fb, rc);
  c.bound += static_cast<std::size_t>(rc.bound_skipped);
  c.nothing += static_cast<std::size_t>(rc.exact_nothing);
  c.cuts += static_cast<std::size_t>(rc.cut);
  // The scalar steps for the rays left over (several intervals, or material above the tool's lowest top).
  for (int q = 0; q < nfb; ++q) {
    const int i = fb[q].i;
    const double t0 = fb[q].t0, top = g.top(i, j);
    if (t0 >= top || t0 >= g.length()) {
      ++c.nothing;
      continue;
    }
    double t1 = fb[q].t1;
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
    cut_tiles[i >> tile_shift] = 1;
  }
}

// A float between t0 (exclusive) and lb (inclusive): only then can a ray's top lie where the reference's bound skips a
// cut (lb >= top) that t0 < top would make, so that its order of sweeps matters.
bool float_between(double t0, double lb) {
  float f = static_cast<float>(lb);
  if (static_cast<double>(f) > lb) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return static_cast<double>(f) > t0;
}

// Consecutive ball sweeps of a run (bin entries [q0, q1), sweeps k, k + 1, ...): their balls' centres stay within dev
// of the chord from the first one's start to the last one's end, so a ball of radius R + dev moving along the chord
// holds each of their balls, and its bound over a tile bounds all of theirs: one test settles a tile for the chunk.
struct Chunk {
  std::size_t q0 = 0, q1 = 0;
  bool fat_ok = false;  // the fat sweep is usable (a chord across the rays, a deviation below R)
  AxialBall fat;
  double margin = 0;                     // the members' largest margin (cut_block_axial_ball)
  int i0 = 0, i1 = -1, j0 = 0, j1 = -1;  // the members' footprint in the block
  double key = 0;                        // the bound over that footprint: chunks run lowest first
};
constexpr std::size_t kChunk = 16;

double sweep_margin(const AxialBall& b) { return 1e-6 * (1 + std::sqrt(b.R * (b.el + 2 * b.R))); }

// Distance from p to the segment a + t d, t in [0, 1] (d.d = dd > 0).
double to_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& d, double dd) {
  const double t = std::clamp((p - a).dot(d) / dd, 0.0, 1.0);
  return (a + t * d - p).norm();
}

void make_chunk(const DexelGrid& g, const std::vector<Footprint>& fp, const std::vector<int>& bin,
                const std::vector<AxialBall>& balls, int jb0, int jb1, Chunk& c) {
  double key = std::numeric_limits<double>::infinity();
  c.i0 = g.nu(), c.i1 = -1, c.j0 = jb1, c.j1 = jb0;
  double rmax = 0;
  c.margin = 0;
  for (std::size_t q = c.q0; q < c.q1; ++q) {
    const AxialBall& b = balls[q];
    const Footprint& f = fp[static_cast<std::size_t>(bin[q])];
    const TileBound bound(b, g.v_of(std::max(jb0, f.j0)) - b.cv, g.v_of(std::min(jb1, f.j1)) - b.cv);
    key = std::min(key, bound(f.i0 * g.du() - b.cu, f.i1 * g.du() - b.cu));
    c.i0 = std::min(c.i0, f.i0), c.i1 = std::max(c.i1, f.i1);
    c.j0 = std::min(c.j0, std::max(jb0, f.j0)), c.j1 = std::max(c.j1, std::min(jb1, f.j1));
    rmax = std::max(rmax, b.R);
    c.margin = std::max(c.margin, sweep_margin(b));
  }
  c.key = key;
  c.fat_ok = false;
  if (c.q1 - c.q0 < 2) return;
  const AxialBall& first = balls[c.q0];
  const AxialBall& last = balls[c.q1 - 1];
  const Eigen::Vector3d a(first.cu, first.cv, first.cw);
  const Eigen::Vector3d d = Eigen::Vector3d(last.cu + last.eu, last.cv + last.ev, last.cw + last.delta) - a;
  const double ee = d.x() * d.x() + d.y() * d.y();
  if (ee < 1e-12) return;
  double dev = 0;
  for (std::size_t q = c.q0; q < c.q1; ++q) {
    const AxialBall& b = balls[q];
    const Eigen::Vector3d s(b.cu, b.cv, b.cw);
    dev = std::max({dev, to_segment(s, a, d, d.squaredNorm()),
                    to_segment(s + Eigen::Vector3d(b.eu, b.ev, b.delta), a, d, d.squaredNorm())});
  }
  if (dev > 0.5 * rmax) return;  // a chunk round a corner: its fat ball would settle little
  AxialBall& f = c.fat;
  // Round-off of dev and of the chord (coordinates to ~1e3 mm): far below this slack.
  f.R = rmax + dev + 1e-9 * (1 + a.lpNorm<Eigen::Infinity>() + d.lpNorm<Eigen::Infinity>());
  f.L = first.L;
  f.cu = a.x(), f.cv = a.y(), f.cw = a.z();
  f.eu = d.x(), f.ev = d.y(), f.delta = d.z();
  f.ee = ee, f.el = std::sqrt(ee), f.inv_ee = 1 / ee;
  const double m = f.delta / f.el;
  f.kk = m / std::sqrt(1 + m * m);
  c.fat_ok = true;
  const TileBound bound(f, g.v_of(c.j0) - f.cv, g.v_of(c.j1) - f.cv);
  c.key = bound(c.i0 * g.du() - f.cu, c.i1 * g.du() - f.cu);
}

// Whether a run of consecutive ball sweeps along the rays (bin[q0, q1), set up in balls) may cut a block in any order
// (see cut()): the lowest point of each one's top over its move ((cw - R) + min(0, delta) + (L - R): a floating-point
// lower bound of every t1 the kernel computes, since delta l >= min(0, delta) for l in [0, 1] and rounding is
// monotone) at or above the block's highest material. Fills the chunks (lowest first; ties in program order) and the
// rays holding several intervals: the order-free pass leaves them alone, the replay cuts them.
bool order_free(const DexelGrid& g, const std::vector<Footprint>& fp, const std::vector<int>& bin, std::size_t q0,
                std::size_t q1, int jb0, int jb1, const std::vector<AxialBall>& balls, std::vector<Chunk>& chunks,
                std::vector<Flagged>& several) {
  if (q1 < q0 + 2 || program_order_only()) return false;
  double lowest_top = std::numeric_limits<double>::infinity();
  for (std::size_t q = q0; q < q1; ++q) {
    const AxialBall& b = balls[q];
    lowest_top = std::min(lowest_top, ((b.cw - b.R) + std::min(0.0, b.delta)) + (b.L - b.R));
  }
  float top;
  several.clear();
  if (!(use_avx2() ? tile_top_avx2 : tile_top_generic)(g.head_row(jb0), static_cast<std::size_t>(g.nu()), jb1 - jb0 + 1,
                                                       g.nu(), false, top)) {
    top = -std::numeric_limits<float>::infinity();  // rays with several intervals: their tops too
    for (int j = jb0; j <= jb1; ++j)
      for (int i = 0; i < g.nu(); ++i) {
        if (const double t = g.top(i, j); t > top) top = static_cast<float>(t);
        if (std::isnan(g.head_row(j)[i].lo)) several.push_back({j, i});
      }
  }
  if (!(lowest_top >= top)) return false;
  chunks.clear();
  for (std::size_t q = q0; q < q1;) {
    Chunk c;
    c.q0 = q;
    for (++q; q < q1 && q - c.q0 < kChunk && bin[q] == bin[q - 1] + 1; ++q) {
    }
    c.q1 = q;
    make_chunk(g, fp, bin, balls, jb0, jb1, c);
    chunks.push_back(c);
  }
  std::stable_sort(chunks.begin(), chunks.end(), [](const Chunk& x, const Chunk& y) { return x.key < y.key; });
  return true;
}

// One ball sweep along the rays on the rows [j0, j1] of a block. Pure: the order-free form (see cut()), which
// appends to `flagged` the rays the replay must redo.
void cut_block_axial_ball(DexelGrid& g, const AxialBall& b, const Footprint& f, int j0, int j1, Tiles& tiles,
                          std::vector<RowFallback>& fb, Counts& c, bool pure, std::vector<Flagged>& flagged,
                          const unsigned char* settled = nullptr) {
  int ia[kBlock], ib[kBlock];
  int umin = g.nu(), umax = -1, r0 = -1, r1 = -1;
  // The shadow's columns on the block's rows (axial_ball_columns' operations, the rows side by side).
  double qv[kBlock];
  for (int j = j0; j <= j1; ++j) qv[j - j0] = g.v_of(j) - b.cv;
  const BallColumns bc{b.eu, b.ev, b.ee, b.cu, g.du(), b.R * b.el, f.i0, f.i1};
  (use_avx2() ? row_columns_avx2 : row_columns_generic)(bc, qv, j1 - j0 + 1, ia, ib);
  for (int j = j0; j <= j1; ++j) {
    int& a = ia[j - j0];
    int& e = ib[j - j0];
    if (a > e) {
      a = 1, e = 0;
      continue;
    }
    c.tests += static_cast<std::size_t>(e - a + 1);
    umin = std::min(umin, a), umax = std::max(umax, e);
    if (r0 < 0) r0 = j;
    r1 = j;
  }
  if (umax < 0) return;
  // The round-off of the kernel's t0 near a ray's rim (a square root of a difference of squares of |q| <= el + R for
  // the rays of the shadow): below 1e-5 mm for a 1 m move; the bounds below keep this margin.
  const double margin = sweep_margin(b);
  // Tiles first (those its chunk has not settled): the bound over a tile against its highest top; then the runs of
  // tiles it did not settle.
  const TileBound bound(b, g.v_of(r0) - b.cv, g.v_of(r1) - b.cv);
  const int shift = tiles.shift, cols = tiles.cols();
  const int tc0 = umin >> shift, tc1 = umax >> shift;
  int runs[2 * 64], nruns = 0;  // [first, last] column of each run (at most 64 runs: beyond, cut per tile)
  for (int tc = tc0; tc <= tc1; ++tc) {
    const auto k = static_cast<std::size_t>(tc);
    const int c0 = std::max(umin, tc * cols), c1 = std::min(umax, tc * cols + cols - 1);
    if (settled && settled[k]) continue;
    const double lb = bound(c0 * g.du() - b.cu, c1 * g.du() - b.cu) - margin;
    bool skip = lb >= tiles.top[k];
    if (!skip && tiles.stale_top[k]) {
      tiles.read(g, tc, false);
      skip = lb >= tiles.top[k];
    }
    if (skip) continue;
    if (nruns > 0 && runs[2 * nruns - 1] == c0 - 1) {
      runs[2 * nruns - 1] = c1;
    } else if (nruns < 64) {
      runs[2 * nruns] = c0, runs[2 * nruns + 1] = c1, ++nruns;
    } else {
      runs[2 * nruns - 1] = c1;  // the last run stretches over settled tiles: cut them too (still exact)
    }
  }
  const RowCutParams p = row_params(g, b);
  unsigned char* cut_tiles = tiles.cut_mark.data();
  // The order-free form: every row's runs in one kernel call (its constants set once), then the fallbacks.
  RowSegment segs[kBlock * 64];
  int nsegs = 0;
  for (int j = j0; j <= j1; ++j) {
    const int a = ia[j - j0], e = ib[j - j0];
    if (a > e) continue;
    if (pure && replay_every_ray())
      for (int i = a; i <= e; ++i) flagged.push_back({j, i});
    std::size_t done = 0;
    for (int r = 0; r < nruns; ++r) {
      const int s0 = std::max(a, runs[2 * r]), s1 = std::min(e, runs[2 * r + 1]);
      if (s0 > s1) continue;
      done += static_cast<std::size_t>(s1 - s0 + 1);
      if (!pure) {
        cut_segment(g, b, p, j, s0, s1, cut_tiles, shift, fb.data(), c);
        continue;
      }
      segs[nsegs++] = RowSegment{g.head_row(j), g.v_of(j) - b.cv, s0, s1, j};
    }
    c.tile += static_cast<std::size_t>(e - a + 1) - done;
  }
  if (nsegs > 0) {
    RowCutCounts rc;
    const int nfb = (use_avx2() ? row_cut_pure_rows_avx2 : row_cut_pure_rows_generic)(
        p, segs, nsegs, g.nu(), g.length(), margin, cut_tiles, shift, fb.data(), rc);
    c.bound += static_cast<std::size_t>(rc.bound_skipped);
    c.nothing += static_cast<std::size_t>(rc.exact_nothing);
    c.cuts += static_cast<std::size_t>(rc.cut);
    for (int q = 0; q < nfb; ++q) {
      const RowFallback& rf = fb[static_cast<std::size_t>(q)];
      const Interval h = g.head_row(rf.j)[rf.i];
      // Several intervals, a cut that would not go through the top (neither happens when cut() chose this form),
      // or a bound above t0 with a float between them: the replay redoes the ray in program order.
      const bool anomaly = std::isfinite(rf.t0) && rf.lb > rf.t0 && float_between(rf.t0, rf.lb);
      if (std::isnan(h.lo) || (h.lo <= h.hi && rf.t1 < h.hi) || anomaly) flagged.push_back({rf.j, rf.i});
    }
  }
  // Tiles a cut touched: their tops may have fallen.
  for (int tc = tc0; tc <= tc1 + 1 && tc < static_cast<int>(tiles.top.size()); ++tc)
    if (cut_tiles[tc]) cut_tiles[tc] = 0, tiles.cut(tc);
}

// A lower bound of where any sweep's body starts along a ray (its entry t0), for every tool and axis: the body lies
// within R of the parallelogram its core segment sweeps, P(s, l) = c + s A + l D with the segment [tip + rc a,
// tip + (L - rc) a] (which holds disk(R - rc) + ball(rc) within R) and the move D, so a body point on the ray through
// q lies at w >= P_w - sqrt(R^2 - r^2) >= P_w - R + r^2 / 2R, r the distance from q to P across the rays: the least of
// a convex quadratic over the unit square (an interior stationary point or an edge's least), about 60 flops where
// ray_interval takes hundreds. The z-map's ball kernel has the same bound in closed form (row_bounds.inc).
struct CoreBound {
  double cu, cv, cw, au, av, aw, du, dv, dw, k, R, AA, AD, DD, det;
  CoreBound(const DexelGrid& g, const SweptTool& s) {
    const double rc = s.tool.corner_radius_mm;
    const Eigen::Vector3d c = s.tip0 + rc * s.axis - g.origin(), A = std::max(0.0, s.tool.length_mm - 2 * rc) * s.axis;
    cu = c.dot(g.U()), cv = c.dot(g.V()), cw = c.dot(g.W());
    au = A.dot(g.U()), av = A.dot(g.V()), aw = A.dot(g.W());
    du = s.d.dot(g.U()), dv = s.d.dot(g.V()), dw = s.d.dot(g.W());
    R = s.tool.radius_mm, k = 0.5 / R;
    AA = au * au + av * av, AD = au * du + av * dv, DD = du * du + dv * dv;
    det = AA * DD - AD * AD;
  }
  // The least of c0 + c1 t + c2 t^2 over [0, 1] (c2 >= 0).
  static double least(double c0, double c1, double c2) {
    const double t = c2 > 0 ? std::clamp(-c1 / (2 * c2), 0.0, 1.0) : (c1 >= 0 ? 0.0 : 1.0);
    return c0 + t * (c1 + t * c2);
  }
  double operator()(double qu, double qv) const {
    const double eu = cu - qu, ev = cv - qv, ee = eu * eu + ev * ev, Ae = au * eu + av * ev, De = du * eu + dv * ev;
    double m = std::min({least(cw + k * ee, dw + 2 * k * De, k * DD),                                // s = 0
                         least(cw + aw + k * (ee + 2 * Ae + AA), dw + 2 * k * (De + AD), k * DD),    // s = 1
                         least(cw + k * ee, aw + 2 * k * Ae, k * AA),                                // l = 0
                         least(cw + dw + k * (ee + 2 * De + DD), aw + 2 * k * (Ae + AD), k * AA)});  // l = 1
    if (det > 1e-12 * AA * DD) {  // the stationary point, when the quadratic is strictly convex
      const double gs = -(aw + 2 * k * Ae) / (2 * k), gl = -(dw + 2 * k * De) / (2 * k);
      const double s = (DD * gs - AD * gl) / det, l = (AA * gl - AD * gs) / det;
      if (s >= 0 && s <= 1 && l >= 0 && l <= 1) {
        const double ru = eu + s * au + l * du, rv = ev + s * av + l * dv;
        m = std::min(m, cw + s * aw + l * dw + k * (ru * ru + rv * rv));
      }
    }
    return m - R;
  }
};

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
  const int cols = tiles.cols();
  for (int tc = umin / cols; tc <= umax / cols; ++tc) {
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
  const CoreBound bound(g, sw);
  // The solvers' entry points lie within ~1e-9 mm of the body (their slack): far inside this margin.
  const double margin = 1e-5 * (1 + bound.R);
  for (int j = j0; j <= j1; ++j) {
    const int a = ia[j - j0], e = ib[j - j0];
    const Interval* head = g.head_row(j);
    const double qv = g.v_of(j);
    for (int tc = a / cols; a <= e && tc <= e / cols; ++tc) {
      const auto k = static_cast<std::size_t>(tc);
      if (tiles.skip[k]) continue;
      bool changed = false;
      for (int i = std::max(a, tc * cols); i <= std::min(e, tc * cols + cols - 1); ++i) {
        // A ray whose material lies wholly before or after the sweep's extent along it is left as it is (subtract
        // would not change it): no exact test. Most rays across a tool's shank run through air.
        const Interval h = head[i];
        if (!std::isnan(h.lo) && (!(h.lo <= h.hi) || w1 <= h.lo || w0 >= h.hi)) continue;
        double t0, t1;
        ++c.tests;
        // All its material below where the body can start on it: the sweep leaves it as it is.
        if (bound(i * g.du(), qv) - margin >= (std::isnan(h.lo) ? g.top(i, j) : double(h.hi))) {
          ++c.bound;
          continue;
        }
        // The ray's material [bottom, top]: a bull-nose's end beyond it needs no refinement (swept_tool.hpp).
        if (reference_bull_solver()
                ? !ray_interval_reference(sw, g.ray_origin(i, j), W, t0, t1)
                : !ray_interval_within(sw, g.ray_origin(i, j), W, std::isnan(h.lo) ? g.bottom(i, j) : double(h.lo),
                                       std::isnan(h.lo) ? g.top(i, j) : double(h.hi), t0, t1))
          continue;
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

CutStats cut(DexelGrid& grid, const std::vector<SweptTool>& sweeps) { return cut(grid, sweeps, nullptr, 0); }

CutStats cut(DexelGrid& grid, const std::vector<SweptTool>& sweeps, core::Progress* progress, double done) {
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
    for (int b = f.j0 / kBlock; b <= f.j1 / kBlock; ++b)
      bins[static_cast<std::size_t>(b)].push_back(static_cast<int>(k));
  }
  // Tiles about a fraction of the smallest tool radius wide (powers of two, 4 to 32 columns): wider ones hold more of a
  // sloped surface than a sweep's bound clears, narrower ones cost more tests than they settle.
  double r_min = 1e300;
  for (const SweptTool& s : sweeps) r_min = std::min(r_min, s.tool.radius_mm);
  const int tile_shift =
      sweeps.empty() ? 5 : std::clamp(static_cast<int>(std::lround(std::log2(r_min / (2 * grid.du())))), 2, 5);
  std::size_t tests = 0, cuts = 0, tile = 0, bound = 0, nothing = 0, blocks = 0, replayed = 0, chunked = 0;
  // With a progress, the blocks in bands of about a sixteenth of the grid (at least a few blocks per thread, so that
  // the threads stay busy between reports), each band its own parallel region: progress.update() is called between
  // them, on the calling thread (it may throw). Blocks are independent, so the bands change nothing in the result.
  const int band = progress ? std::max(4 * omp_get_max_threads(), (nblocks + 15) / 16) : std::max(nblocks, 1);
  for (int band0 = 0; band0 < nblocks; band0 += band) {
    const int band1 = std::min(nblocks, band0 + band);
#pragma omp parallel reduction(+ : tests, cuts, tile, bound, nothing, blocks, replayed, chunked)
    {
      Tiles tiles;
      // A kernel call's fallbacks: at most one per ray of a block's rows.
      std::vector<RowFallback> fb(static_cast<std::size_t>(kBlock) * static_cast<std::size_t>(grid.nu()) + 4);
      Counts c;
      std::vector<AxialBall> balls;
      std::vector<char> is_ball;
      std::vector<Chunk> chunks;
      std::vector<Interval> before;
      std::vector<Flagged> flagged;
#pragma omp for schedule(dynamic, 1)
      for (int b = band0; b < band1; ++b) {
        const int jb0 = b * kBlock, jb1 = std::min(grid.nv() - 1, jb0 + kBlock - 1);
        const std::vector<int>& bin = bins[static_cast<std::size_t>(b)];
        tiles.reset(grid, jb0, jb1, tile_shift);
        balls.resize(bin.size());
        is_ball.resize(bin.size());
        for (std::size_t q = 0; q < bin.size(); ++q)
          is_ball[q] = axial_ball(grid, sweeps[static_cast<std::size_t>(bin[q])], balls[q]);
        // Runs of consecutive ball sweeps along the rays, each followed by one other sweep (or the bin's end).
        for (std::size_t q0 = 0; q0 < bin.size();) {
          std::size_t q1 = q0;
          while (q1 < bin.size() && is_ball[q1]) ++q1;
          if (order_free(grid, fp, bin, q0, q1, jb0, jb1, balls, chunks, flagged)) {
            // Every sweep of the run is a ball along the rays whose lowest top lies above all the block's material:
            // each cut of a ray holding one interval takes its material above the cut's start t0, so such a ray ends
            // the run as [lo, float(min t0)] (or empty) whatever the order, as long as the reference's bound never
            // skipped a cut (it may only where a float lies between t0 and the bound above it; the kernel lists those
            // rays). The sweeps run lowest first, in chunks: those that decide the surface cut it, and the tiles'
            // bounds settle most of the rest, a chunk at a time where its fat ball's bound does.
            const std::size_t nb = static_cast<std::size_t>(jb1 - jb0 + 1) * static_cast<std::size_t>(grid.nu());
            before.assign(grid.head_row(jb0), grid.head_row(jb0) + nb);
            tiles.skip_several = true;  // rays with several intervals: flagged (order_free), replayed, not in the tops
            for (const Chunk& ch : chunks) {
              const unsigned char* settled = nullptr;
              int tc0 = 0, tc1 = -1;
              if (ch.fat_ok) {
                const TileBound bound(ch.fat, grid.v_of(ch.j0) - ch.fat.cv, grid.v_of(ch.j1) - ch.fat.cv);
                const int shift = tiles.shift, cols = tiles.cols();
                tc0 = ch.i0 >> shift, tc1 = ch.i1 >> shift;
                bool all = true;
                for (int tc = tc0; tc <= tc1; ++tc) {
                  const auto k = static_cast<std::size_t>(tc);
                  const int c0 = std::max(ch.i0, tc * cols), c1 = std::min(ch.i1, tc * cols + cols - 1);
                  const double lb = bound(c0 * grid.du() - ch.fat.cu, c1 * grid.du() - ch.fat.cu) - ch.margin;
                  bool skip = lb >= tiles.top[k];
                  if (!skip && tiles.stale_top[k]) {
                    tiles.read(grid, tc, false);
                    skip = lb >= tiles.top[k];
                  }
                  tiles.settled[k] = skip;
                  all = all && skip;
                }
                if (all) {
                  c.chunk_skipped += ch.q1 - ch.q0;
                  for (int tc = tc0; tc <= tc1; ++tc) tiles.settled[static_cast<std::size_t>(tc)] = 0;
                  continue;
                }
                settled = tiles.settled.data();
              }
              for (std::size_t q = ch.q0; q < ch.q1; ++q) {
                const Footprint& f = fp[static_cast<std::size_t>(bin[q])];
                cut_block_axial_ball(grid, balls[q], f, std::max(jb0, f.j0), std::min(jb1, f.j1), tiles, fb, c, true,
                                     flagged, settled);
              }
              for (int tc = tc0; tc <= tc1; ++tc) tiles.settled[static_cast<std::size_t>(tc)] = 0;
            }
            // The flagged rays again from the run's start, its sweeps in program order (the reference's steps).
            std::sort(flagged.begin(), flagged.end());
            flagged.erase(std::unique(flagged.begin(), flagged.end()), flagged.end());
            for (const Flagged& r : flagged) {
              grid.head_row(r.j)[r.i] =
                  before[static_cast<std::size_t>(r.j - jb0) * static_cast<std::size_t>(grid.nu()) +
                         static_cast<std::size_t>(r.i)];
              for (std::size_t q = q0; q < q1; ++q) {
                const AxialBall& ab = balls[q];
                const Footprint& f = fp[static_cast<std::size_t>(bin[q])];
                int ia, ib;
                if (r.j < f.j0 || r.j > f.j1 || !axial_ball_columns(grid, ab, r.j, f.i0, f.i1, ia, ib) || r.i < ia ||
                    r.i > ib)
                  continue;
                Counts scratch;
                cut_segment(grid, ab, row_params(grid, ab), r.j, r.i, r.i, tiles.cut_mark.data(), tiles.shift,
                            fb.data(), scratch);
              }
            }
            c.replayed += flagged.size();
            ++c.blocks;
            tiles.reset(grid, jb0, jb1,
                        tile_shift);  // the replay may have raised tops the pass had lowered; and rays left out
          } else {
            for (std::size_t q = q0; q < q1; ++q) {
              const Footprint& f = fp[static_cast<std::size_t>(bin[q])];
              cut_block_axial_ball(grid, balls[q], f, std::max(jb0, f.j0), std::min(jb1, f.j1), tiles, fb, c, false,
                                   flagged);
            }
          }
          if (q1 < bin.size()) {
            const int k = bin[q1];
            const Footprint& f = fp[static_cast<std::size_t>(k)];
            cut_block_general(grid, sweeps[static_cast<std::size_t>(k)], f, wext[static_cast<std::size_t>(k)],
                              std::max(jb0, f.j0), std::min(jb1, f.j1), tiles, c);
          }
          q0 = q1 + 1;
        }
      }
      tests += c.tests, cuts += c.cuts, tile += c.tile, bound += c.bound, nothing += c.nothing, blocks += c.blocks,
          replayed += c.replayed, chunked += c.chunk_skipped;
    }
    if (progress) progress->update(done + static_cast<double>(sweeps.size()) * band1 / nblocks);
  }
  CutStats s;
  s.ray_tests = tests;
  s.cuts = cuts;
  s.tile_skipped = tile;
  s.bound_skipped = bound;
  s.exact_nothing = nothing;
  s.order_free_blocks = blocks;
  s.replayed = replayed;
  s.chunk_skipped = chunked;
  return s;
}

}  // namespace vmsim::removal
