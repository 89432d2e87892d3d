#include "removal/row_bounds.hpp"
#define ROW_BOUNDS_NAME row_bounds_generic
#define ROW_PREFILTER_NAME row_prefilter_generic
#include "removal/row_bounds.inc"
