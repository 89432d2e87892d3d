// Compiled with -mavx2 (removal/CMakeLists.txt); called only when the CPU has it.
#define ROW_BOUNDS_NAME row_bounds_avx2
#include "removal/row_bounds.inc"
