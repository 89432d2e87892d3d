#pragma once
// A measured scan held against the surface vmsim predicted (what `vmsim compare` reports), as one library call:
// the scan cleaned of spikes, registered to the prediction (robust 6-DoF, optionally on named reference faces
// only), resampled onto the prediction's grid; then the signed deviation and its statistics, the marks in it
// (depth, width across and length along the path), profiles across the deepest marks, and the areal parameters of
// both surfaces on their common area. Against a mesh (an STL part), the deviation is the distance along the
// mesh's normal at the scan's points. And a measured profile held against the line across a predicted surface it
// was measured along.
#include "core/height_grid.hpp"
#include "core/mesh.hpp"
#include "metrology/areal.hpp"
#include "metrology/filter.hpp"
#include "metrology/form.hpp"
#include "metrology/marks.hpp"
#include "metrology/processing.hpp"
#include "metrology/profile.hpp"
#include "metrology/register.hpp"

#include <Eigen/Core>

#include <cmath>
#include <cstddef>
#include <optional>
#include <vector>

namespace vmsim::metrology {

// What a scan is held against: predicted heights, or a part mesh (then `grid` is the top of the mesh rasterised at
// the scan's step, which the registration and the areal parameters use; the deviation is taken to the mesh).
struct Prediction {
  core::HeightGrid grid;
  std::optional<core::TriangleMesh> mesh;
};
Prediction prediction_of_mesh(core::TriangleMesh mesh, double spacing_mm);

struct SurfaceCompareOptions {
  double outlier_sigma = 6.0;                // spikes of the scan masked beyond this many robust sigmas (0: none)
  bool align = true;                         // robust registration; false: the scan as it lies (through `initial`)
  std::optional<RigidTransform> initial;     // the registration's start, or, without `align`, the transform itself
  std::vector<Region> regions;               // align on these areas of the prediction only (reference faces)
  RobustLoss loss = RobustLoss::Tukey;       // Tukey (c = 4.685 sigma, after Huber) or Huber (k = 1.345 sigma)
  SurfaceProcessing processing;              // before the areal parameters of both
  double mark_threshold_mm = 1e-3;           // a mark: |deviation| above this, over at least 3 x 3 nodes
  std::optional<double> path_direction_rad;  // the path direction at the marks; default: the prediction's lay
};

struct DeviationStats {
  std::size_t points = 0;
  double min = NAN, max = NAN, mean = NAN, rms = NAN, mean_abs = NAN;  // mm; NaN without a valid point
};
DeviationStats deviation_stats(const core::HeightGrid& deviation);

enum class PathDirectionFrom { Given, Lay, NoLay };  // NoLay: +x, the prediction's anisotropy under 0.2

// Across the path through a mark, over +-max(3 widths, 30 grid steps, 0.2 mm) every half grid step.
struct MarkProfile {
  Profile deviation;
  Profile measured;   // grid: the aligned scan; mesh: the scan in its own frame
  Profile predicted;  // grid only (empty against a mesh)
};

struct SurfaceComparison {
  core::HeightGrid scan;                           // the measured scan in its own frame, spikes masked
  std::optional<OutlierReport> outliers;           // when outlier_sigma > 0
  std::optional<RegistrationResult> registration;  // with align
  RigidTransform transform;                        // scan frame -> prediction frame
  core::HeightGrid measured_on;                    // the scan carried onto the prediction's grid
  // Grid: measured - predicted, vertical, on the prediction's grid (negative: overcut). Mesh: the signed distance
  // along the mesh's normal (positive outside the part) on the scan's grid, scan frame.
  core::HeightGrid deviation;
  DeviationStats stats;
  double path_direction_rad = 0;
  PathDirectionFrom path_direction_from = PathDirectionFrom::Given;
  double lay_anisotropy = 0;                      // when taken from the lay
  std::vector<Mark> marks;                        // deepest first, at most 10
  std::vector<Eigen::Vector2d> marks_in_part_mm;  // mesh: each mark's x, y carried into the part frame
  std::vector<MarkProfile> mark_profiles;         // the three deepest marks
  // Areal parameters on the nodes where both the aligned scan and the prediction are valid, after `processing`.
  std::optional<FormFit> measured_form;  // the form removed from the measured surface (level > 0)
  ArealParameters measured_areal, predicted_areal;
  struct Seconds {
    double outliers = 0, registration = 0, deviation = 0, marks = 0, areal = 0;
  } seconds;  // wall time of each stage
};

// Throws core::Error when the registration finds too few overlapping points, or when the aligned scan and the
// prediction do not overlap anywhere.
SurfaceComparison compare_surfaces(core::HeightGrid scan, const Prediction& prediction,
                                   const SurfaceCompareOptions& options);

// A measured profile against the line (x0, y0) -> (x1, y1) across `predicted` (compare_profile: registration along
// the line, offset and tilt), and the ISO 21920-2 parameters of both, `how` evaluated, on the samples where both
// are valid.
struct ProfileSurfaceComparison {
  ProfileComparison along;
  EvaluatedProfile measured, predicted;
};
ProfileSurfaceComparison compare_profile_to_surface(const LineScan& measured, const core::HeightGrid& predicted,
                                                    double x0_mm, double y0_mm, double x1_mm, double y1_mm,
                                                    const ProfileAlignmentOptions& alignment,
                                                    const ProfileEvaluation& how);

}  // namespace vmsim::metrology
