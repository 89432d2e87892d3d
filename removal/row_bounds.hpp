#pragma once
// Internal to removal/cut.cpp: the vectorised row kernel of a ball-end sweep on a z-map (removal/row_bounds.inc).
namespace vmsim::removal {

struct RowCutParams {
  double R, L;                    // ball radius, tool length
  double cu, eu, ev, ee, inv_ee, inv_el, delta, kk;  // see AxialBall in cut.cpp
  double base_w;                  // the tip's ray coordinate at the sweep's start
  double du;                      // column spacing
};

void row_prefilter_generic(const RowCutParams& p, double qv, int ia, int n, double* lb);
void row_prefilter_avx2(const RowCutParams& p, double qv, int ia, int n, double* lb);
void row_bounds_generic(const RowCutParams& p, double qv, int ia, const int* idx, int m, double* t0, double* t1);
void row_bounds_avx2(const RowCutParams& p, double qv, int ia, const int* idx, int m, double* t0, double* t1);

}  // namespace vmsim::removal
