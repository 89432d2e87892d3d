// Compiled with -mavx2 (removal/CMakeLists.txt); called only when the CPU has it.
#include "removal/row_bounds.hpp"
#define ROW_BOUNDS_NAME row_bounds_avx2
#define ROW_PREFILTER_NAME row_prefilter_avx2
#include "removal/row_bounds.inc"
