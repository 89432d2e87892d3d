#pragma once
// Setpoints: the axis commands the interpolator sends to the drives, one sample every period_s.
#include <Eigen/Core>

#include <string>
#include <vector>

namespace vmsim::core {

struct Setpoints {
  double period_s = 1e-3;                // Te; sample k is at t = k * period_s
  std::vector<std::string> axis_names;   // machine axes, in the machine file's order
  Eigen::MatrixXd position;              // samples x axes, axis units (mm, rad)
  Eigen::ArrayXd path_speed_mm_per_s;    // speed of the programmed point along the (smoothed) path
  Eigen::ArrayXd path_length_mm;         // distance travelled along the (smoothed) path
  Eigen::ArrayXi move_index;             // ToolPath move each sample lies on (nearest move inside a blend)

  Eigen::Index samples() const { return position.rows(); }
  double duration_s() const { return samples() > 0 ? (samples() - 1) * period_s : 0.0; }
};

}  // namespace vmsim::core
