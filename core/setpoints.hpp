#pragma once
// Setpoints: the axis commands the interpolator sends to the drives, one sample every period_s.
#include <Eigen/Core>

#include <string>
#include <vector>

namespace vmsim::core {

struct Setpoints {
  double period_s = 1e-3;               // Te; sample k is at t = k * period_s
  std::vector<std::string> axis_names;  // machine axes, in the machine file's order
  Eigen::MatrixXd position;             // samples x axes, axis units (mm, rad)
  Eigen::ArrayXd path_speed_mm_per_s;   // speed of the programmed point along the (smoothed) path
  Eigen::ArrayXd path_length_mm;        // distance travelled along the (smoothed) path
  Eigen::ArrayXi move_index;            // ToolPath move each sample lies on (nearest move inside a blend)

  Eigen::Index samples() const { return position.rows(); }
  double duration_s() const { return samples() > 0 ? (samples() - 1) * period_s : 0.0; }
};

// Largest |velocity|, |acceleration| and |jerk| per axis (axis units per s, s^2, s^3), by backward finite
// differences of the setpoints as the drives receive them, with the axes at rest before the first sample and
// after the last.
struct AxisPeaks {
  Eigen::ArrayXd velocity, acceleration, jerk;
};
AxisPeaks finite_difference_peaks(const Setpoints& setpoints);

}  // namespace vmsim::core
