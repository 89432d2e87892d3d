#include "sim/axis_following.hpp"

#include "core/units.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace vmsim::sim {

nlohmann::json axis_following_json(const core::Machine& machine, const core::Setpoints& setpoints,
                                   const Eigen::MatrixXd& actual, const motion::Kinematics* kin,
                                   const std::function<double(Eigen::Index)>& tool_length_offset) {
  const Eigen::Index n = std::min(setpoints.samples(), actual.rows());
  nlohmann::json out = nlohmann::json::object();
  if (n == 0) return out;
  const double to_deg = 180 / core::units::kPi;
  for (std::size_t i = 0; i < machine.axes.size(); ++i) {
    const auto c = static_cast<Eigen::Index>(i);
    const bool rotary = machine.axes[i].kind == core::AxisKind::Rotary;
    const double scale = rotary ? to_deg : 1.0;
    const Eigen::ArrayXd e = (setpoints.position.col(c).head(n) - actual.col(c).head(n)).array() * scale;
    Eigen::Index at = 0;
    const double mx = e.abs().maxCoeff(&at);
    const double rms = std::sqrt(e.square().mean());
    const char* u = rotary ? "deg" : "mm";
    out[machine.axes[i].name] = {{std::string("max_abs_") + u, mx},
                                 {std::string("rms_") + u, rms},
                                 {"max_at_s", static_cast<double>(at) * setpoints.period_s}};
  }
  if (kin) {
    double mx = 0, ss = 0;
    for (Eigen::Index k = 0; k < n; ++k) {
      const double tlo = tool_length_offset(k);
      const Eigen::Vector3d a = kin->forward(setpoints.position.row(k).transpose(), tlo).axis;
      const Eigen::Vector3d b = kin->forward(actual.row(k).transpose(), tlo).axis;
      const double ang = std::atan2(a.cross(b).norm(), a.dot(b)) * to_deg;
      mx = std::max(mx, ang);
      ss += ang * ang;
    }
    out["tool_axis"] = {{"max_angle_deg", mx}, {"rms_angle_deg", std::sqrt(ss / static_cast<double>(n))}};
  }
  return out;
}

}  // namespace vmsim::sim
