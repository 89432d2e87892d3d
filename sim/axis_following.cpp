#include "sim/axis_following.hpp"

#include "core/error.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <utility>

namespace vmsim::sim {

namespace {

// The lanes of Eigen's packet of doubles (1: not vectorised: a plain left-to-right sum).
#ifdef EIGEN_VECTORIZE
constexpr int kLanes =
    Eigen::internal::packet_traits<double>::Vectorizable ? Eigen::internal::packet_traits<double>::size : 1;
#else
constexpr int kLanes = 1;
#endif
static_assert(kLanes == 1 || kLanes == 2 || kLanes == 4, "EigenOrderSum knows Eigen's packets of 2 and 4 doubles");

// Eigen's predux: a packet's lanes added (SSE: a0 + a1; AVX: (a0 + a2) + (a1 + a3)).
double predux(const double* r) {
  if constexpr (kLanes == 2) return r[0] + r[1];
  if constexpr (kLanes == 4) return (r[0] + r[2]) + (r[1] + r[3]);
  return r[0];
}

}  // namespace

void EigenOrderSum::add(double v) {
  ++n_;
  if constexpr (kLanes == 1) {
    r0_[0] = n_ == 1 ? v : r0_[0] + v;
    return;
  }
  pending_[pending_n_++] = v;
  if (pending_n_ < 2 * kLanes) return;
  // A complete group of two packets: the unrolled loop's two accumulators (the first group starts them).
  for (int l = 0; l < kLanes; ++l) {
    r0_[l] = groups_ == 0 ? pending_[l] : r0_[l] + pending_[l];
    r1_[l] = groups_ == 0 ? pending_[kLanes + l] : r1_[l] + pending_[kLanes + l];
  }
  ++groups_;
  pending_n_ = 0;
}

double EigenOrderSum::sum() const {
  if (n_ == 0) return 0.0;
  if constexpr (kLanes == 1) return r0_[0];
  double r[kMaxLanes / 2];
  int tail = 0;  // the first pending value the scalar tail adds
  if (groups_ == 0) {
    if (pending_n_ < kLanes) {  // too short for one packet: left to right
      double s = pending_[0];
      for (int k = 1; k < pending_n_; ++k) s += pending_[k];
      return s;
    }
    for (int l = 0; l < kLanes; ++l) r[l] = pending_[l];
    tail = kLanes;
  } else {
    for (int l = 0; l < kLanes; ++l) r[l] = r0_[l] + r1_[l];
    if (pending_n_ >= kLanes) {
      for (int l = 0; l < kLanes; ++l) r[l] += pending_[l];
      tail = kLanes;
    }
  }
  double s = predux(r);
  for (int k = tail; k < pending_n_; ++k) s += pending_[k];
  return s;
}

AxisFollowing::AxisFollowing(const core::Machine& machine, Eigen::Index samples, const motion::Kinematics* kin,
                             std::function<double(Eigen::Index)> tool_length_offset)
    : machine_(&machine), n_(samples), kin_(kin), tlo_(std::move(tool_length_offset)), axes_(machine.axes.size()) {}

void AxisFollowing::add_axes(Eigen::Index k0, const core::Setpoints& sp, const Eigen::MatrixXd& actual) {
  const double to_deg = 180 / core::units::kPi;
  const Eigen::Index end = std::min(n_, k0 + actual.rows());
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    const auto c = static_cast<Eigen::Index>(i);
    const double scale = machine_->axes[i].kind == core::AxisKind::Rotary ? to_deg : 1.0;
    Axis& a = axes_[i];
    for (Eigen::Index k = k0; k < end; ++k) {
      const double e = (sp.position(k, c) - actual(k - k0, c)) * scale;
      const double ae = std::abs(e);
      if (k == 0 || ae > a.max) a.max = ae, a.at = k;
      a.sum2.add(e * e);
    }
  }
}

void AxisFollowing::add_tool_angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  // Bitwise the same pair: the same angle (compared as bits: a signed zero may change atan2's answer).
  if (!last_valid_ || std::memcmp(a.data(), last_command_.data(), sizeof(double) * 3) != 0 ||
      std::memcmp(b.data(), last_actual_.data(), sizeof(double) * 3) != 0) {
    last_valid_ = true;
    last_command_ = a;
    last_actual_ = b;
    last_angle_deg_ = std::atan2(a.cross(b).norm(), a.dot(b)) * (180 / core::units::kPi);
  }
  const double ang = last_angle_deg_;
  tool_max_ = std::max(tool_max_, ang);
  tool_ss_ += ang * ang;
}

void AxisFollowing::add(Eigen::Index k0, const core::Setpoints& sp, const Eigen::MatrixXd& actual) {
  add_axes(k0, sp, actual);
  if (!kin_) return;
  const Eigen::Index end = std::min(n_, k0 + actual.rows());
  for (Eigen::Index k = k0; k < end; ++k) {
    const double tlo = tlo_(k);
    const Eigen::Vector3d a = kin_->forward(sp.position.row(k).transpose(), tlo).axis;
    const Eigen::Vector3d b = kin_->forward(actual.row(k - k0).transpose(), tlo).axis;
    add_tool_angle(a, b);
  }
}

void AxisFollowing::add(Eigen::Index k0, const core::Setpoints& sp, const Eigen::MatrixXd& actual,
                        const Eigen::Ref<const Eigen::MatrixXd>& command_axis,
                        const Eigen::Ref<const Eigen::MatrixXd>& actual_axis) {
  if (command_axis.rows() != actual.rows() || actual_axis.rows() != actual.rows() || command_axis.cols() != 3 ||
      actual_axis.cols() != 3)
    throw core::Error(fmt::format("axis following: {} x {} commanded and {} x {} actual tool axes for {} rows",
                                  command_axis.rows(), command_axis.cols(), actual_axis.rows(), actual_axis.cols(),
                                  actual.rows()));
  add_axes(k0, sp, actual);
  if (!kin_) return;
  const Eigen::Index end = std::min(n_, k0 + actual.rows());
  for (Eigen::Index k = k0; k < end; ++k)
    add_tool_angle(command_axis.row(k - k0).transpose(), actual_axis.row(k - k0).transpose());
}

nlohmann::json AxisFollowing::json(double period_s) const {
  nlohmann::json out = nlohmann::json::object();
  if (n_ == 0) return out;
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    const bool rotary = machine_->axes[i].kind == core::AxisKind::Rotary;
    const char* u = rotary ? "deg" : "mm";
    const Axis& a = axes_[i];
    out[machine_->axes[i].name] = {{std::string("max_abs_") + u, a.max},
                                   {std::string("rms_") + u, std::sqrt(a.sum2.sum() / static_cast<double>(n_))},
                                   {"max_at_s", static_cast<double>(a.at) * period_s}};
  }
  if (kin_)
    out["tool_axis"] = {{"max_angle_deg", tool_max_}, {"rms_angle_deg", std::sqrt(tool_ss_ / static_cast<double>(n_))}};
  return out;
}

nlohmann::json axis_following_json(const core::Machine& machine, const core::Setpoints& setpoints,
                                   const Eigen::MatrixXd& actual, const motion::Kinematics* kin,
                                   const std::function<double(Eigen::Index)>& tool_length_offset) {
  AxisFollowing f(machine, std::min(setpoints.samples(), actual.rows()), kin, tool_length_offset);
  f.add(0, setpoints, actual);
  return f.json(setpoints.period_s);
}

}  // namespace vmsim::sim
