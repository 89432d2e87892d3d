// Compiled with -mavx2 (removal/CMakeLists.txt); called only when the CPU has it.
#include "removal/row_bounds.hpp"
#define ROW_BOUNDS_NAME row_bounds_avx2
#define ROW_PREFILTER_NAME row_prefilter_avx2
#define ROW_CUT_NAME row_cut_avx2
#define ROW_CUT_PURE_NAME row_cut_pure_avx2
#define ROW_CUT_PURE_ROWS_NAME row_cut_pure_rows_avx2
#define TILE_TOP_NAME tile_top_avx2
#define CHORD_DIST2_NAME chord_dist2_avx2
#define ROW_COLUMNS_NAME row_columns_avx2
#define HERMITE_BOW_NAME hermite_bow_avx2
#define MERGE_RUNS_NAME merge_runs_avx2
#include "removal/row_bounds.inc"
#include "removal/row_cut.inc"
#include "removal/track_kernel.inc"
