#pragma once
// The processing a surface's parameters are evaluated after, as one value: the form removed (none, the
// least-squares plane or a polynomial) and then Gaussian filters in the order given; and a surface's areal
// parameters after spike masking and that processing (what `vmsim stats` prints).
#include "core/height_grid.hpp"
#include "metrology/areal.hpp"
#include "metrology/filter.hpp"
#include "metrology/form.hpp"
#include "metrology/profile.hpp"

#include <optional>
#include <vector>

namespace vmsim::metrology {

// S: keeps the mean surface, removes the shorter wavelengths (low-pass); L: removes the mean surface, keeps the
// roughness (high-pass). Gaussian, ISO 16610-61, edges renormalised over the valid points (ISO 16610-28).
struct SurfaceFilter {
  char kind = 'L';
  double cutoff_mm = 0.8;
};
struct SurfaceProcessing {
  int level = 1;  // form removed first: 0 none, 1 plane, N polynomial of degree N
  std::vector<SurfaceFilter> filters;
};

// Form removal then the filters; `fit` receives the form removed (untouched when level is 0).
core::HeightGrid process_surface(const core::HeightGrid& grid, const SurfaceProcessing& how, FormFit* fit = nullptr);

// The same level and filters for a profile (ISO 21920: the least-squares line for a plane, the ISO 16610-21 filters).
ProfileEvaluation profile_evaluation(const SurfaceProcessing& how);

struct SurfaceAnalysis {
  std::optional<OutlierReport> outliers;  // when spikes were masked
  std::optional<FormFit> form;            // when a form was removed
  ArealParameters areal;                  // ISO 25178-2, of the processed surface
};
// Spikes masked first when outlier_sigma > 0 (mask_outliers at that many robust sigmas), then process_surface,
// then the areal parameters. Throws core::Error when no valid point is left.
SurfaceAnalysis analyse_surface(core::HeightGrid grid, const SurfaceProcessing& how, double outlier_sigma);

}  // namespace vmsim::metrology
