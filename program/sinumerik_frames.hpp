#pragma once
// Programmable frames of the 840D (internal to the Sinumerik reader): TRANS/ATRANS (offsets), ROT/AROT (rotations),
// and the swivel frame CYCLE800 builds from them. A frame maps programmed coordinates to the workpiece frame
// (the settable zero G54.. with its offset): p_workpiece = rotation * p_programmed + offset.
//
// Siemens, NC programming (Fundamentals, "Coordinate transformations (frames)"): TRANS and ROT replace the
// programmable frame, ATRANS and AROT add to it in the coordinates it already defines (each new statement acts in
// the frame the previous ones made). ROT/AROT X.. Y.. Z.. in one block turn in the order Z, Y', X'' (RPY angles);
// RPL=.. turns in the active plane (about the plane's normal). Positive angles turn right-handed.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vmsim::program::sinumerik {

struct Frame {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();

  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return rotation * p + offset; }
  Eigen::Vector3d inverse_apply(const Eigen::Vector3d& p) const { return rotation.transpose() * (p - offset); }
  // This frame followed by `inner` (inner's coordinates are expressed in this frame's).
  Frame then(const Frame& inner) const { return {rotation * inner.rotation, rotation * inner.offset + offset}; }
  bool is_identity() const {
    return (rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-15 &&
           offset.cwiseAbs().maxCoeff() < 1e-15;
  }

  static Frame translation(const Eigen::Vector3d& v) { return {Eigen::Matrix3d::Identity(), v}; }
  // ROT X a Y b Z c: RPY order Z, Y', X'' (angles in degrees).
  static Frame rotation_rpy_deg(double x_deg, double y_deg, double z_deg) {
    constexpr double k = 3.14159265358979323846 / 180.0;
    const Eigen::Matrix3d r = (Eigen::AngleAxisd(z_deg * k, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(y_deg * k, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(x_deg * k, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    return {r, Eigen::Vector3d::Zero()};
  }
  static Frame rotation_about(int axis, double deg) {
    constexpr double k = 3.14159265358979323846 / 180.0;
    return {Eigen::AngleAxisd(deg * k, Eigen::Vector3d::Unit(axis)).toRotationMatrix(), Eigen::Vector3d::Zero()};
  }
};

}  // namespace vmsim::program::sinumerik
