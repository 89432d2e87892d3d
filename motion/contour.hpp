#pragma once
// Contour error: the shortest distance from the actual tool position to the commanded path, signed
// (Duong et al. section III.B eq. 1-2, the predictive-compensation paper section 4).
#include <Eigen/Core>

#include <optional>

namespace vmsim::motion {

struct ContourOptions {
  // Search window (command samples) around the previous foot point; it bounds the cost and keeps the foot
  // point from jumping to a neighbouring raster pass. <= 0: chosen from the largest tracking error.
  int window_samples = 0;
  // Planar profiles: the sign follows the in-plane normal n = plane_normal x tangent (Duong et al.'s XZ profile:
  // plane_normal = +Y). Without it the sign follows the principal normal of the command path.
  std::optional<Eigen::Vector3d> plane_normal;
};

struct ContourError {
  Eigen::ArrayXd signed_mm;     // per actual sample
  Eigen::ArrayXi foot_segment;  // command segment [i, i+1] holding the foot point
  double max_abs_mm = 0.0, rms_mm = 0.0, mse_um2 = 0.0;
  int window_samples = 0;  // the search window used (the option, or the default chosen from the data)
};

// command, actual: samples x 3 (mm), the same sampling instants (actual may have extra settling rows; the
// command's last point is held). Per actual sample: the nearest command sample near the previous foot point, then
// the exact distance to its two adjacent segments. Sign: sign(n . E), E = foot point - actual (command minus
// actual, as Duong et al.'s E = X_d - X_a); n = plane_normal x tangent, or the principal normal of the command path
// (carried over straight stretches). Positive: the actual lies on the -n side (outside a curve). contour.cpp
// says how the search keeps to the pass being followed. Throws core::Error for non-finite or non-3D input.
ContourError contour_error(const Eigen::MatrixXd& command, const Eigen::MatrixXd& actual,
                           const ContourOptions& options = {});
// The same, releasing the command's memory (it is left empty) as soon as the search no longer needs it, before the
// result's arrays are made: a long run's peak then holds the command once, in the merged path.
ContourError contour_error(Eigen::MatrixXd&& command, const Eigen::MatrixXd& actual,
                           const ContourOptions& options = {});

}  // namespace vmsim::motion
