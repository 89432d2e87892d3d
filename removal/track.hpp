#pragma once
// From a sampled tool motion (tool poses every Te, from the drives' actual positions, the setpoints or the
// programmed path) to the straight swept volumes the kernel removes.
#include "removal/swept_tool.hpp"

#include <Eigen/Core>

#include <vector>

namespace vmsim::removal {

struct PoseTrack {
  double period_s = 1e-3;
  Eigen::MatrixXd tip_mm;       // samples x 3, workpiece frame
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // tool axis (constant: 3-axis motion)
  // Optional tip velocities (samples x 3, mm/s): between samples the motion is then the cubic Hermite curve
  // through both samples with these velocities, not the chord.
  Eigen::MatrixXd tip_velocity_mm_per_s;
};

struct TrackOptions {
  // Largest distance between the removed motion and the track: half goes to sampling the Hermite curves between
  // samples, half to merging nearly collinear samples into one straight sweep.
  double tolerance_mm = 1e-4;
};

struct TrackSweeps {
  std::vector<SweptTool> sweeps;
  std::size_t points = 0;  // points of the (sub-sampled) track before merging
};

TrackSweeps sweeps_from_track(const Tool& tool, const PoseTrack& track, const TrackOptions& options = {});

}  // namespace vmsim::removal
