#include "metrology/processing.hpp"

namespace vmsim::metrology {

core::HeightGrid process_surface(const core::HeightGrid& grid, const SurfaceProcessing& how, FormFit* fit) {
  core::HeightGrid s = how.level > 0 ? remove_form(grid, how.level, fit) : grid;
  for (const SurfaceFilter& f : how.filters)
    s = f.kind == 'S' ? gaussian_lowpass(s, f.cutoff_mm) : gaussian_highpass(s, f.cutoff_mm);
  return s;
}

ProfileEvaluation profile_evaluation(const SurfaceProcessing& how) {
  ProfileEvaluation e;
  e.level = how.level;
  for (const SurfaceFilter& f : how.filters) e.filters.push_back({f.kind, f.cutoff_mm});
  return e;
}

SurfaceAnalysis analyse_surface(core::HeightGrid grid, const SurfaceProcessing& how, double outlier_sigma) {
  SurfaceAnalysis a;
  if (outlier_sigma > 0) {
    OutlierOptions oo;
    oo.k_sigma = outlier_sigma;
    a.outliers = mask_outliers(grid, oo);
  }
  FormFit fit;
  const core::HeightGrid s = process_surface(grid, how, &fit);
  if (how.level > 0) a.form = fit;
  a.areal = areal_parameters(s);
  return a;
}

}  // namespace vmsim::metrology
