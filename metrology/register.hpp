#pragma once
// Registration of a measured scan to a predicted surface: the rigid transform (rotation R, translation t) that
// carries the scan's points onto the prediction, found by robust Gauss-Newton on point-to-surface distances, and
// the scan resampled onto the prediction's grid through that transform.
#include "core/height_grid.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::metrology {

struct RigidTransform {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return R * p + t; }
  RigidTransform inverse() const { return {R.transpose(), -(R.transpose() * t)}; }
  // Rotation vector (axis times angle, rad) and the small-angle rotations about x, y, z it amounts to.
  Eigen::Vector3d rotation_vector() const;
  // R = Rz(rz) Ry(ry) Rx(rx) (angles in rad).
  static RigidTransform from_xyz_rxyz(double x, double y, double z, double rx, double ry, double rz);
};

// An axis-aligned rectangle in the predicted surface's frame (mm): the areas to align on (unmachined reference
// faces), named by the user.
struct Region {
  double x_min = 0, x_max = 0, y_min = 0, y_max = 0;
  bool contains(double x, double y) const { return x >= x_min && x <= x_max && y >= y_min && y <= y_max; }
};

enum class RobustLoss { None, Huber, Tukey };

struct RegistrationOptions {
  RobustLoss loss = RobustLoss::Tukey;
  double tuning = 4.685;                  // Tukey's c (or Huber's k, 1.345) in robust standard deviations
  std::vector<Region> regions;            // if any: only scan points that land in one of them take part
  std::optional<RigidTransform> initial;  // else the automatic guess (see register_scan)
  std::size_t max_points = 200000;        // scan points used (a regular subsample of the valid nodes)
  int max_iterations = 60;                // per level
  bool coarse_to_fine = true;             // first on Gaussian-smoothed surfaces, to widen the capture range
};

struct RegistrationResult {
  RigidTransform transform;    // scan frame -> predicted frame
  double rms_mm = 0;           // RMS point-to-surface distance of the inliers at the end
  double mean_mm = 0;          // mean signed distance of the inliers (scan above prediction > 0)
  double robust_sigma_mm = 0;  // 1.4826 MAD of the distances
  std::size_t points = 0;      // scan points that overlapped the prediction (and the regions)
  std::size_t inliers = 0;     // of which had a non-zero weight
  int iterations = 0;
  bool converged = false;
  std::string initial_guess;  // how the start was found
  // Directions the surface does not constrain (a flat face leaves x, y translation and rotation about z free):
  // held at the initial guess by damping and named here, e.g. "translation x".
  std::vector<std::string> weak_directions;
};

// Aligns `scan` (its own frame) to `predicted`. Points: the scan's valid nodes (subsampled to max_points);
// distances: from each transformed point to the predicted surface along its normal, the surface interpolated
// bilinearly (heights and central-difference gradients), normal distance ~ (z - f(x, y)) / sqrt(1 + |grad f|^2).
// Method: Gauss-Newton (point-to-plane linearisation, rotation increments about the points' centroid, composed
// on the left), iteratively reweighted: Huber weights until the first convergence, then the chosen loss, with the
// scale re-estimated each iteration as 1.4826 MAD. Coarse to fine: both surfaces Gaussian-filtered with cut-offs
// of 32 and 8 grid steps, then raw. Initial guess (when none is given): the rotation that makes the scan's
// least-squares plane parallel to the prediction's, x/y unchanged when the scan's footprint lies mostly inside the
// prediction (else its centre moved onto the prediction's centre), z from the median height difference.
// Throws core::Error when fewer than 6 points overlap the prediction (and the regions).
RegistrationResult register_scan(const core::HeightGrid& scan, const core::HeightGrid& predicted,
                                 const RegistrationOptions& options = {});

// Heights of the scan, carried through `scan_to_predicted`, at the nodes of `target` (its geometry only): for each
// node (X, Y) the scan point whose transformed position lies above it, found by Newton steps on the bilinear scan
// surface. Nodes the scan does not cover, or where its cell has an invalid corner, are invalid.
core::HeightGrid resample_scan(const core::HeightGrid& scan, const RigidTransform& scan_to_predicted,
                               const core::HeightGrid& target);

// Bilinear height (and, with gx/gy, gradient of the bilinear patch) at (x, y); false outside the grid or where a
// corner of the cell is invalid.
bool sample_bilinear(const core::HeightGrid& g, double x, double y, double& z, double* gx = nullptr,
                     double* gy = nullptr);

}  // namespace vmsim::metrology
