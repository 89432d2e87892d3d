#pragma once
// Internal to removal/cut.cpp: the vectorised row kernel of a ball-end sweep on a z-map (removal/row_bounds.inc,
// removal/row_cut.inc), each built twice: plain and for AVX2 (chosen at run time; both give the same bits).
#include "removal/dexel_grid.hpp"

namespace vmsim::removal {

struct RowCutParams {
  double R, L;                                       // ball radius, tool length
  double cu, eu, ev, ee, inv_ee, inv_el, delta, kk;  // see AxialBall in cut_internal.hpp
  double base_w;                                     // the tip's ray coordinate at the sweep's start
  double du;                                         // column spacing
};

// The reference kernel's two steps (cut_reference.cpp): the square-root-free lower bound of the cut's start on rays
// ia .. ia + n - 1, and the exact cut on the rays ia + idx[k].
void row_prefilter_generic(const RowCutParams& p, double qv, int ia, int n, double* lb);
void row_prefilter_avx2(const RowCutParams& p, double qv, int ia, int n, double* lb);
void row_bounds_generic(const RowCutParams& p, double qv, int ia, const int* idx, int m, double* t0, double* t1);
void row_bounds_avx2(const RowCutParams& p, double qv, int ia, const int* idx, int m, double* t0, double* t1);

// A ray row_cut leaves to its caller (several intervals, or material above the tool's lowest top), with the exact
// start of the cut t0 and the lower bound t1 of its end, as row_bounds gives them.
struct RowFallback {
  int i;
  int j = 0;          // the ray's row (row_cut_pure_rows: the segment's `row`)
  double t0, t1, lb;  // lb: the ray's square-root-free bound
};
struct RowCutCounts {
  long long bound_skipped = 0;  // rays the square-root-free bound settled
  long long exact_nothing = 0;  // rays cut exactly that the sweep leaves unchanged
  long long cut = 0;            // rays cut in place
};
// Both steps fused, four rays at a time, on the rays [i0, i1] of one row (head: the row's in-place intervals, indexed
// by column), and the cut applied in place where the ray holds one interval and loses everything above t0; a ray cut
// in place sets cut_tiles[column >> tile_shift]. Returns the number of rays written to fb (at most i1 - i0 + 1) for
// the caller to finish as cut_reference does.
int row_cut_generic(const RowCutParams& p, double qv, int i0, int i1, Interval* head, double length,
                    unsigned char* cut_tiles, int tile_shift, RowFallback* fb, RowCutCounts& count);
int row_cut_avx2(const RowCutParams& p, double qv, int i0, int i1, Interval* head, double length,
                 unsigned char* cut_tiles, int tile_shift, RowFallback* fb, RowCutCounts& count);
// The order-free form (removal/cut.cpp, a run of sweeps that all cut through the top of every ray): skips a ray only
// when its bound less `margin` is at or above its top (so t0 is too), cuts wherever t0 < top, and lists in fb the rays
// where the reference's own skip could have differed (bound > t0), any ray with several intervals and any ray the
// cut would not take through its top (t1 < top), for the caller to check or replay.
int row_cut_pure_generic(const RowCutParams& p, double qv, int i0, int i1, Interval* head, double length, double margin,
                         unsigned char* cut_tiles, int tile_shift, RowFallback* fb, RowCutCounts& count);
int row_cut_pure_avx2(const RowCutParams& p, double qv, int i0, int i1, Interval* head, double length, double margin,
                      unsigned char* cut_tiles, int tile_shift, RowFallback* fb, RowCutCounts& count);

// The rays [i0, i1] of one row for row_cut_pure_rows: the row's in-place intervals (head, indexed by column, nu of them
// in memory), its offset qv from the ball centre's start, its row number (copied to the fallbacks).
struct RowSegment {
  Interval* head;
  double qv;
  int i0, i1, row;
};
// row_cut_pure on several segments (a sweep's rows and runs in a block) in one call: the constants set once, a
// segment's last group read whole from its row where the row holds it (lanes past the segment masked, left as they
// are). The same bits and counts as row_cut_pure on each segment in turn; fallbacks carry their row.
int row_cut_pure_rows_generic(const RowCutParams& p, const RowSegment* segs, int nsegs, int nu, double length,
                              double margin, unsigned char* cut_tiles, int tile_shift, RowFallback* fb,
                              RowCutCounts& count);
int row_cut_pure_rows_avx2(const RowCutParams& p, const RowSegment* segs, int nsegs, int nu, double length,
                           double margin, unsigned char* cut_tiles, int tile_shift, RowFallback* fb,
                           RowCutCounts& count);

// The highest top of the rays in `rows` rows x n columns from head (rows `stride` intervals apart), or false when one
// of them holds several intervals (unless skip_several: then the top of the others).
bool tile_top_generic(const Interval* head, std::size_t stride, int rows, int n, bool skip_several, float& top);
bool tile_top_avx2(const Interval* head, std::size_t stride, int rows, int n, bool skip_several, float& top);

// What axial_ball_columns (removal/cut_internal.hpp) needs of a ball sweep along the rays, for a row range of columns
// [i0, i1]: the move across the grid (eu, ev, ee), the ball centre's column offset cu, R el, the column spacing.
struct BallColumns {
  double eu, ev, ee, cu, du, Rel;
  int i0, i1;
};
// axial_ball_columns on the rows whose offsets from the ball centre's start are qv[0..n): columns [ia[k], ib[k]] of
// row k (ia > ib: the shadow misses it), bit for bit the scalar function's.
void row_columns_generic(const BallColumns& c, const double* qv, int n, int* ia, int* ib);
void row_columns_avx2(const BallColumns& c, const double* qv, int n, int* ia, int* ib);

// The largest squared distance from the points (px, py, pz)[k], k in [k0, k1), to the segment from a along d
// (inv = 1 / d.d, or 0 when d = 0): the track's merge (removal/track.cpp), vectorised.
double chord_dist2_generic(const double* px, const double* py, const double* pz, std::size_t k0, std::size_t k1,
                           double ax, double ay, double az, double dx, double dy, double dz, double inv);
double chord_dist2_avx2(const double* px, const double* py, const double* pz, std::size_t k0, std::size_t k1, double ax,
                        double ay, double az, double dx, double dy, double dz, double inv);

// sweeps_from_track's merge for a track with a constant axis (removal/track.cpp), from point a on: the greedy runs'
// last points, written to ends[0..) until `cap` of them or the track's last point, and their tips' largest squared
// distance to the run's chord (chord_dist2's) to max_d2[0..); returns how many. far(ctx, k, s, e): the exact test,
// whether tip k lies farther than eps from the chord s -> e (for tips within round-off of eps).
using MergeExactTest = bool (*)(const void* ctx, std::size_t k, std::size_t s, std::size_t e);
std::size_t merge_runs_generic(const double* px, const double* py, const double* pz, std::size_t np, double eps,
                               MergeExactTest far, const void* ctx, std::size_t a, std::size_t* ends, double* max_d2,
                               std::size_t cap);
std::size_t merge_runs_avx2(const double* px, const double* py, const double* pz, std::size_t np, double eps,
                            MergeExactTest far, const void* ctx, std::size_t a, std::size_t* ends, double* max_d2,
                            std::size_t cap);

// hermite_substeps' |p''|max and sqrt(|p''|max / (8 eps)) of the track intervals k -> k + 1, k in [k0, k1) (tips t, tip
// velocities v, columns of the track), written to a[k - k0], r[k - k0] (removal/track.cpp).
void hermite_bow_generic(const double* tx, const double* ty, const double* tz, const double* vx, const double* vy,
                         const double* vz, std::size_t k0, std::size_t k1, double period_s, double eps, double* a,
                         double* r);
void hermite_bow_avx2(const double* tx, const double* ty, const double* tz, const double* vx, const double* vy,
                      const double* vz, std::size_t k0, std::size_t k1, double period_s, double eps, double* a,
                      double* r);

}  // namespace vmsim::removal
