#define ROW_BOUNDS_NAME row_bounds_generic
#include "removal/row_bounds.inc"
