#include "removal/row_bounds.hpp"
#define ROW_BOUNDS_NAME row_bounds_generic
#define ROW_PREFILTER_NAME row_prefilter_generic
#define ROW_CUT_NAME row_cut_generic
#define ROW_CUT_PURE_NAME row_cut_pure_generic
#define ROW_CUT_PURE_ROWS_NAME row_cut_pure_rows_generic
#define TILE_TOP_NAME tile_top_generic
#define CHORD_DIST2_NAME chord_dist2_generic
#define ROW_COLUMNS_NAME row_columns_generic
#define HERMITE_BOW_NAME hermite_bow_generic
#define MERGE_RUNS_NAME merge_runs_generic
#include "removal/row_bounds.inc"
#include "removal/row_cut.inc"
#include "removal/track_kernel.inc"
