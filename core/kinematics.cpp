#include "core/kinematics.hpp"

#include "core/error.hpp"

namespace vmsim::core {

namespace {
void require_xyz(const Machine& machine) {
  if (machine.kinematics != "xyz")
    throw Error(machine.source_file + ": kinematics \"" + machine.kinematics + "\" is not supported here");
}
class CartesianXyz final : public Kinematics {
 public:
  explicit CartesianXyz(const Machine& m) : x_(m.axis_index(kX)), y_(m.axis_index(kY)), z_(m.axis_index(kZ)) {}
  ToolPose forward(const Eigen::VectorXd& axes, double tlo) const override {
    ToolPose p;
    p.tip_mm = Eigen::Vector3d(axes[x_], axes[y_], axes[z_] - tlo);
    return p;
  }
  Eigen::VectorXd inverse(const ToolPose& pose, double tlo, const Eigen::VectorXd& near) const override {
    Eigen::VectorXd a = near;
    a[x_] = pose.tip_mm.x();
    a[y_] = pose.tip_mm.y();
    a[z_] = pose.tip_mm.z() + tlo;
    return a;
  }

 private:
  int x_, y_, z_;
};

}  // namespace

std::unique_ptr<Kinematics> make_kinematics(const Machine& machine) {
  require_xyz(machine);
  return std::make_unique<CartesianXyz>(machine);
}

Vec6 axes_from_tip(const Vec6& tip, double tool_length_offset_mm, const Machine& machine) {
  require_xyz(machine);
  Vec6 a = tip;
  a[kZ] += tool_length_offset_mm;
  return a;
}

Vec6 tip_from_axes(const Vec6& axes, double tool_length_offset_mm, const Machine& machine) {
  require_xyz(machine);
  Vec6 t = axes;
  t[kZ] -= tool_length_offset_mm;
  return t;
}

ToolPath toolpath_in_axis_space(const ToolPath& path, const Machine& machine) {
  require_xyz(machine);
  ToolPath out = path;
  out.initial_position = axes_from_tip(path.initial_position, 0.0, machine);
  for (Move& m : out.moves) {
    const double tlo = m.tool_length_offset_mm;
    m.start = axes_from_tip(m.start, tlo, machine);
    m.end = axes_from_tip(m.end, tlo, machine);
    // Arc centres are in the plane's coordinates; Z is the first of ZX and the second of YZ.
    if (m.kind == MotionKind::Arc) {
      if (m.plane == ArcPlane::ZX) m.centre_mm[0] += tlo;
      if (m.plane == ArcPlane::YZ) m.centre_mm[1] += tlo;
    }
    m.tool_length_offset_mm = 0.0;
  }
  return out;
}

}  // namespace vmsim::core
