#include "motion/kinematics.hpp"

#include "core/arc.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <Eigen/Dense>
#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vmsim::motion {

const char* family_name(KinematicFamily family) {
  switch (family) {
    case KinematicFamily::Cartesian:
      return "cartesian";
    case KinematicFamily::TableTable:
      return "table-table";
    case KinematicFamily::HeadTable:
      return "head-table";
    case KinematicFamily::HeadHead:
      return "head-head";
    case KinematicFamily::ForwardOnly:
      return "forward only";
  }
  return "?";
}

namespace {

using core::units::kTwoPi;
const char* const kAxisNames[] = {"X", "Y", "Z", "A", "B", "C"};

void require_xyz(const core::Machine& machine) {
  if (machine.kinematics != "xyz")
    throw core::Error(machine.source_file + ": kinematics \"" + machine.kinematics + "\" is not supported here");
}

void require_size(const Eigen::VectorXd& v, std::size_t n, const char* what) {
  if (static_cast<std::size_t>(v.size()) != n)
    throw core::Error(fmt::format("kinematics: {} has {} entries, the machine has {} axes", what, v.size(), n));
}

// The shapes forward_rows and tip_velocity_rows take (axis_rows, axis_cols: the axes wanted, or 0 x 0).
void require_rows(Eigen::Index rows, Eigen::Index axes, std::size_t n, Eigen::Index tlo, Eigen::Index out_rows,
                  Eigen::Index out_cols, Eigen::Index axis_rows = 0, Eigen::Index axis_cols = 0) {
  if (static_cast<std::size_t>(axes) != n)
    throw core::Error(fmt::format("kinematics: rows of {} axes, the machine has {} axes", axes, n));
  const bool axis_ok = (axis_rows == 0 && axis_cols == 0) || (axis_rows == rows && axis_cols == 3);
  if (tlo != rows || out_rows != rows || out_cols != 3 || !axis_ok)
    throw core::Error(fmt::format("kinematics: {} axis rows with {} tool length offsets and {} x {} outputs", rows, tlo,
                                  out_rows, out_cols));
}

// tip_velocity_rows: one velocity row per position row, of the same axes.
void require_velocity_rows(const Eigen::Ref<const Eigen::MatrixXd>& q, const Eigen::Ref<const Eigen::MatrixXd>& qd) {
  if (qd.rows() != q.rows() || qd.cols() != q.cols())
    throw core::Error(fmt::format("kinematics: {} x {} axis velocities for {} x {} axis positions", qd.rows(), qd.cols(),
                                  q.rows(), q.cols()));
}

class CartesianXyz final : public Kinematics {
 public:
  explicit CartesianXyz(const core::Machine& m)
      : x_(m.axis_index(core::kX)), y_(m.axis_index(core::kY)), z_(m.axis_index(core::kZ)), n_(m.axes.size()) {}
  ToolPose forward(const Eigen::VectorXd& axes, double tlo) const override {
    ToolPose p;
    p.tip_mm = Eigen::Vector3d(axes[x_], axes[y_], axes[z_] - tlo);
    return p;
  }
  Eigen::VectorXd inverse(const ToolPose& pose, double tlo, const Eigen::VectorXd& near) const override {
    return place_tip(pose.tip_mm, tlo, near);
  }
  Eigen::VectorXd place_tip(const Eigen::Vector3d& tip, double tlo, const Eigen::VectorXd& axes) const override {
    require_size(axes, n_, "the axis vector");
    Eigen::VectorXd a = axes;
    a[x_] = tip.x();
    a[y_] = tip.y();
    a[z_] = tip.z() + tlo;
    return a;
  }
  Eigen::Vector3d tip_velocity(const Eigen::VectorXd&, const Eigen::VectorXd& v, double) const override {
    return {v[x_], v[y_], v[z_]};
  }
  // forward() and tip_velocity() of every row, column by column (the same values: copies and Z - tlo).
  void forward_rows(const Eigen::Ref<const Eigen::MatrixXd>& q, const Eigen::Ref<const Eigen::VectorXd>& tlo,
                    Eigen::Ref<Eigen::MatrixXd> tip, Eigen::Ref<Eigen::MatrixXd> axis) const override {
    require_rows(q.rows(), q.cols(), n_, tlo.size(), tip.rows(), tip.cols(), axis.rows(), axis.cols());
    tip.col(0) = q.col(x_);
    tip.col(1) = q.col(y_);
    tip.col(2) = q.col(z_) - tlo;
    if (axis.size() > 0) axis.rowwise() = Eigen::RowVector3d(0.0, 0.0, 1.0);
  }
  void tip_velocity_rows(const Eigen::Ref<const Eigen::MatrixXd>& q, const Eigen::Ref<const Eigen::MatrixXd>& qd,
                         const Eigen::Ref<const Eigen::VectorXd>& tlo, Eigen::Ref<Eigen::MatrixXd> out) const override {
    require_rows(q.rows(), q.cols(), n_, tlo.size(), out.rows(), out.cols());
    require_velocity_rows(q, qd);
    out.col(0) = qd.col(x_);
    out.col(1) = qd.col(y_);
    out.col(2) = qd.col(z_);
  }
  KinematicFamily family() const override { return KinematicFamily::Cartesian; }

 private:
  int x_, y_, z_;
  std::size_t n_;
};

// Rodrigues' rotation of x about the unit vector u by the angle whose cosine and sine are c and s.
inline Eigen::Vector3d rotate(const Eigen::Vector3d& u, double c, double s, const Eigen::Vector3d& x) {
  return x * c + u.cross(x) * s + u * (u.dot(x) * (1 - c));
}

// The angle that turns p onto q about the unit vector u (Paden-Kahan subproblem 1: Murray, Li & Sastry, A
// Mathematical Introduction to Robotic Manipulation, 1994, section 3.2.2), from the parts of p and q normal to u.
// Only meaningful when those parts are not zero and have the same length.
double angle_about(const Eigen::Vector3d& u, const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
  const Eigen::Vector3d pp = p - u * u.dot(p), qq = q - u * u.dot(q);
  return std::atan2(u.dot(pp.cross(qq)), pp.dot(qq));
}

double deg(double rad) { return rad * core::units::kRadToDeg; }

// Kinematic chains: machine file [kinematics]. Every joint is described in the base frame with all joints at zero
// (product of exponentials): a joint at value q maps a point x of the bodies it carries to x + q u (linear) or to
// p + Rot(u, q) (x - p) (rotary), so the pose of a chain's last body is exp(j1 q1) ... exp(jn qn) applied to its pose
// at zero. The tool's tip in the workpiece frame is then Workpiece(q)^-1 Tool(q) (gauge - L d), with L the tool
// length offset and d the tool direction at zero (tip -> spindle), minus the workpiece origin.
class ChainKinematics final : public Kinematics {
 public:
  explicit ChainKinematics(const core::Machine& m) : file_(m.source_file), name_(m.name), n_(m.axes.size()) {
    if (!m.chain) throw core::Error(m.source_file + ": kinematics \"chain\" without its [kinematics] table");
    const core::KinematicChain& ch = *m.chain;
    origin_ = ch.workpiece_origin_mm;
    gauge_ = ch.gauge_point_mm;
    d_ = ch.tool_direction.normalized();
    auto take = [&](const std::vector<core::ChainJoint>& src, std::vector<Joint>& dst) {
      for (const core::ChainJoint& cj : src) {
        Joint j;
        j.index = m.axis_index(cj.program_axis);
        if (j.index < 0)
          throw core::Error(fmt::format("{}: the chain's joint {} names axis {}, which the machine has no [[axes]] for",
                                        cj.where.empty() ? m.source_file : cj.where, kAxisNames[cj.program_axis],
                                        kAxisNames[cj.program_axis]));
        j.program_axis = cj.program_axis;
        j.rotary = cj.kind == core::AxisKind::Rotary;
        j.u = cj.direction.normalized();
        j.p = cj.point_mm;
        j.where = cj.where.empty() ? m.source_file : cj.where;
        const core::MachineAxis& ax = m.axes[static_cast<std::size_t>(j.index)];
        j.continuous = ax.continuous;
        j.lo = ax.travel_min;
        j.hi = ax.travel_max;
        dst.push_back(j);
      }
    };
    take(ch.workpiece, wp_);
    take(ch.tool, tool_);
    for (const auto* chain : {&wp_, &tool_})
      for (const Joint& j : *chain)
        if (!j.rotary && j.program_axis < 3) lin_[j.program_axis] = j.index;
    for (int k = 0; k < 3; ++k)
      if (lin_[k] < 0) throw core::Error(fmt::format("{}: the chain has no joint for axis {}", file_, kAxisNames[k]));
    classify();
    for (const Joint& j : tool_) tool_linear_ = tool_linear_ && !j.rotary;
  }
  // rot_, ja_ and jb_ point into wp_ and tool_.
  ChainKinematics(const ChainKinematics&) = delete;
  ChainKinematics& operator=(const ChainKinematics&) = delete;

  ToolPose forward(const Eigen::VectorXd& q, double tlo) const override {
    require_size(q, n_, "the axis vector");
    Trig fresh[6];  // one per joint: at most six (each of X Y Z A B C once, core/machine.cpp; as tip_velocity's)
    return pose_at(q, tlo, fresh);
  }

  Eigen::VectorXd place_tip(const Eigen::Vector3d& tip, double tlo, const Eigen::VectorXd& axes) const override {
    require_size(axes, n_, "the axis vector");
    Eigen::VectorXd q = axes;
    for (int k = 0; k < 3; ++k) q[lin_[k]] = 0.0;
    const Eigen::Vector3d b = forward(q, tlo).tip_mm;
    const Eigen::Matrix3d m = linear_map(q);
    const double det = m.determinant();
    if (!(std::abs(det) > 1e-9))
      throw core::Error(
          fmt::format("{}: the linear axes cannot place the tip here: their directions do not span space in "
                      "this pose (determinant {:.3g})",
                      file_, det));
    const Eigen::Vector3d lin = m.inverse() * (tip - b);
    for (int k = 0; k < 3; ++k) q[lin_[k]] = lin[k];
    return q;
  }

  Eigen::Vector3d tip_velocity(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, double tlo) const override {
    require_size(q, n_, "the axis vector");
    require_size(qd, n_, "the axis velocity vector");
    // Spatial velocities (Murray, Li & Sastry section 3.4): each joint, where the joints before it in its chain have
    // moved it (axis u', point p'), adds qd * (u' x (x - p')) (rotary) or qd * u' (linear) to the velocity of a point
    // x of the bodies it carries. Tool chain first (it also gives the tip), then the workpiece point under the tip.
    Eigen::Vector3d u_moved[6], p_moved[6];
    Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < tool_.size(); ++i) {
      u_moved[i] = r * tool_[i].u;
      p_moved[i] = r * tool_[i].p + t;
      step(tool_[i], q[tool_[i].index], r, t);
    }
    const Eigen::Vector3d tip_b = r * (gauge_ - tlo * d_) + t;
    Eigen::Vector3d v_rel = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < tool_.size(); ++i)
      v_rel += qd[tool_[i].index] * point_velocity(tool_[i].rotary, u_moved[i], p_moved[i], tip_b);
    r.setIdentity();
    t.setZero();
    for (const Joint& j : wp_) {
      v_rel -= qd[j.index] * point_velocity(j.rotary, r * j.u, r * j.p + t, tip_b);
      step(j, q[j.index], r, t);
    }
    return r.transpose() * v_rel;
  }

  // forward() row by row, each rotary joint's cosine and sine kept while its angle repeats.
  void forward_rows(const Eigen::Ref<const Eigen::MatrixXd>& q, const Eigen::Ref<const Eigen::VectorXd>& tlo,
                    Eigen::Ref<Eigen::MatrixXd> tip, Eigen::Ref<Eigen::MatrixXd> axis) const override {
    require_rows(q.rows(), q.cols(), n_, tlo.size(), tip.rows(), tip.cols(), axis.rows(), axis.cols());
    const bool axes_wanted = axis.size() > 0;
    std::vector<Trig> trig(tool_.size() + wp_.size());
    const Eigen::Index n = q.rows();
    for (Eigen::Index k = 0; k < n;) {
      // A run of rows whose rotary joints all stand at zero (a three-axis program on a five-axis machine): every
      // rotary apply() returns at once there, so the rows go column by column through the linear joints' sums alone.
      Eigen::Index e = k;
      while (e < n && rotaries_at_zero(q, e)) ++e;
      if (e - k >= kMinRun) {
        forward_linear_rows(q, tlo, k, e, tip, axis);
        k = e;
        continue;
      }
      for (e = std::max(e, k + 1); k < e; ++k) {
        const ToolPose pose = pose_at(q.row(k), tlo[k], trig.data());
        tip.row(k) = pose.tip_mm.transpose();
        if (axes_wanted) axis.row(k) = pose.axis.transpose();
      }
    }
  }

  // tip_velocity() row by row, each rotary joint's rotation kept while its angle repeats.
  void tip_velocity_rows(const Eigen::Ref<const Eigen::MatrixXd>& q, const Eigen::Ref<const Eigen::MatrixXd>& qd,
                         const Eigen::Ref<const Eigen::VectorXd>& tlo, Eigen::Ref<Eigen::MatrixXd> out) const override {
    require_rows(q.rows(), q.cols(), n_, tlo.size(), out.rows(), out.cols());
    require_velocity_rows(q, qd);
    std::vector<Rotation> rot(tool_.size() + wp_.size());
    Eigen::Vector3d u_moved[6], p_moved[6];
    // The workpiece chain's moved axes and points and its rotation depend on its own joints only: kept while their
    // values repeat bit for bit (a three-axis program on a table-table machine: always).
    bool wp_valid = false;
    std::vector<std::uint64_t> wp_bits(wp_.size());
    std::vector<Eigen::Vector3d> wp_u(wp_.size()), wp_p(wp_.size());
    Eigen::Matrix3d wp_r;
    const Eigen::Index n = q.rows();
    Eigen::Index run_end = 0;  // rows before it were checked for a run of the linear tool chain's path
    for (Eigen::Index k = 0; k < n; ++k) {
      if (tool_linear_ && wp_valid && k >= run_end) {
        // A run of rows with the workpiece chain's values of the row before (its cached rotation) and finite linear
        // tool joints and offsets: column by column (tip_velocity_linear_rows); shorter runs row by row below.
        Eigen::Index e = k;
        while (e < n && wp_same(q, e, wp_bits) && linear_finite(q, tlo, e)) ++e;
        run_end = e;
        if (e - k >= kMinRun) {
          tip_velocity_linear_rows(q, qd, tlo, k, e, wp_u, wp_p, wp_r, out);
          k = e - 1;
          continue;
        }
      }
      Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
      Eigen::Vector3d t = Eigen::Vector3d::Zero();
      for (std::size_t i = 0; i < tool_.size(); ++i) {
        u_moved[i] = r * tool_[i].u;
        p_moved[i] = r * tool_[i].p + t;
        step(tool_[i], q(k, tool_[i].index), r, t, rot[i]);
      }
      const Eigen::Vector3d tip_b = r * (gauge_ - tlo[k] * d_) + t;
      Eigen::Vector3d v_rel = Eigen::Vector3d::Zero();
      for (std::size_t i = 0; i < tool_.size(); ++i)
        v_rel += qd(k, tool_[i].index) * point_velocity(tool_[i].rotary, u_moved[i], p_moved[i], tip_b);
      bool same = wp_valid;
      for (std::size_t i = 0; same && i < wp_.size(); ++i)
        same = std::bit_cast<std::uint64_t>(q(k, wp_[i].index)) == wp_bits[i];
      if (!same) {
        r.setIdentity();
        t.setZero();
        for (std::size_t i = 0; i < wp_.size(); ++i) {
          const Joint& j = wp_[i];
          wp_bits[i] = std::bit_cast<std::uint64_t>(q(k, j.index));
          wp_u[i] = r * j.u;
          wp_p[i] = r * j.p + t;
          step(j, q(k, j.index), r, t, rot[tool_.size() + i]);
        }
        wp_r = r;
        wp_valid = true;
      }
      for (std::size_t i = 0; i < wp_.size(); ++i)
        v_rel -= qd(k, wp_[i].index) * point_velocity(wp_[i].rotary, wp_u[i], wp_p[i], tip_b);
      out.row(k) = (wp_r.transpose() * v_rel).transpose();
    }
  }

  KinematicFamily family() const override { return family_; }

  Eigen::VectorXd inverse(const ToolPose& pose, double tlo, const Eigen::VectorXd& near) const override {
    std::vector<std::string> reasons;
    std::vector<Eigen::VectorXd> all = solutions(pose, tlo, near, reasons);
    if (all.empty()) {
      std::string why;
      for (const std::string& r : reasons) why += (why.empty() ? "" : "; ") + r;
      const Eigen::Vector3d v = pose.axis.normalized();
      throw core::Error(
          fmt::format("{}: machine \"{}\" cannot reach tip ({:.4f}, {:.4f}, {:.4f}) mm with tool axis ({:.6f}, "
                      "{:.6f}, {:.6f}): {}",
                      file_, name_, pose.tip_mm.x(), pose.tip_mm.y(), pose.tip_mm.z(), v.x(), v.y(), v.z(), why));
    }
    return std::move(all.front());
  }

  // Every solution of the inverse within the machine's travels (each rotary angle the 2 pi equivalent closest to
  // near's), the least rotary motion from near first; `reasons` says why the others are out (travel limits). Two
  // at most on the closed-form families (the branches (B, C) and (-B, C + 180 deg) of a B/C table), one at a
  // singular pose.
  std::vector<Eigen::VectorXd> solutions(const ToolPose& pose, double tlo, const Eigen::VectorXd& near,
                                         std::vector<std::string>& reasons) const {
    require_size(near, n_, "the near vector");
    if (family_ == KinematicFamily::ForwardOnly)
      throw core::Error(fmt::format("{}: machine \"{}\" has no inverse transform (forward only): {}", file_, name_,
                                    forward_only_reason_));
    const double an = pose.axis.norm();
    if (!(an > 1e-9) || !std::isfinite(an) || !pose.tip_mm.allFinite())
      throw core::Error(fmt::format("{}: no tool pose to reach (tip ({}, {}, {}), axis ({}, {}, {}))", file_,
                                    pose.tip_mm.x(), pose.tip_mm.y(), pose.tip_mm.z(), pose.axis.x(), pose.axis.y(),
                                    pose.axis.z()));
    for (Eigen::Index i = 0; i < near.size(); ++i)
      if (!std::isfinite(near[i])) throw core::Error(file_ + ": the inverse needs finite near axes");
    const Eigen::Vector3d v = pose.axis / an;
    std::vector<std::pair<double, Eigen::VectorXd>> found;
    auto consider = [&](Eigen::VectorXd q) {
      // The linear axes, then every travel.
      q = place_tip(pose.tip_mm, tlo, q);
      for (const auto* chain : {&wp_, &tool_})
        for (const Joint& j : *chain)
          if (!j.continuous && !(q[j.index] >= j.lo - kTravelSlack && q[j.index] <= j.hi + kTravelSlack)) {
            reasons.push_back(j.rotary ? fmt::format("{} = {:.4f} deg is outside its travel [{:.4f}, {:.4f}] deg",
                                                     kAxisNames[j.program_axis], deg(q[j.index]), deg(j.lo), deg(j.hi))
                                       : fmt::format("{} = {:.4f} mm is outside its travel [{:.4f}, {:.4f}] mm",
                                                     kAxisNames[j.program_axis], q[j.index], j.lo, j.hi));
            return;
          }
      // Least rotary motion from near: the sum of the rotary axes' turns (rad); ties keep the first candidate.
      double cost = 0;
      for (const Joint* j : rot_) cost += std::abs(q[j->index] - near[j->index]);
      found.emplace_back(cost, std::move(q));
    };

    if (family_ == KinematicFamily::Cartesian) {
      // No rotary joint: the tool axis is the tool direction, always.
      const double err = std::atan2(v.cross(d_).norm(), v.dot(d_));
      if (err > kAxisSlack)
        throw core::Error(
            fmt::format("{}: machine \"{}\" cannot tilt the tool: axis ({:.6f}, {:.6f}, {:.6f}) is {:.6f} deg "
                        "from its fixed tool direction",
                        file_, name_, v.x(), v.y(), v.z(), deg(err)));
      consider(near);
    } else {
      solve_rotary(v, near, reasons, consider);
    }
    // The least cost first (a later candidate wins only by more than 1e-12), then the others in order.
    std::size_t best = 0;
    for (std::size_t i = 1; i < found.size(); ++i)
      if (found[i].first < found[best].first - 1e-12) best = i;
    std::vector<Eigen::VectorXd> out;
    if (found.empty()) return out;
    out.push_back(found[best].second);
    for (std::size_t i = 0; i < found.size(); ++i)
      if (i != best) out.push_back(std::move(found[i].second));
    return out;
  }

  // d tip / d (X, Y, Z) in the workpiece frame at the rotary axes of q (the tip is affine in the linear axes when the
  // rotary axes hold still): column k is the tip's motion per mm of the linear joint of program axis k.
  Eigen::Matrix3d linear_map(const Eigen::VectorXd& q) const {
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    for (std::size_t k = 0; k < tool_.size(); ++k) {
      if (tool_[k].rotary) continue;
      // A tool-chain joint's shift is turned by the tool joints before it, then into the workpiece frame.
      Eigen::Vector3d p = Eigen::Vector3d::Zero(), v = tool_[k].u;
      for (std::size_t i = k; i-- > 0;) apply(tool_[i], q[tool_[i].index], p, v);
      for (const Joint& j : wp_) apply(j, -q[j.index], p, v);
      m.col(tool_[k].program_axis) = v;
    }
    for (std::size_t k = 0; k < wp_.size(); ++k) {
      if (wp_[k].rotary) continue;
      // A workpiece-chain joint moves the workpiece: the tip moves the other way, seen through the joints after it.
      Eigen::Vector3d p = Eigen::Vector3d::Zero(), v = -wp_[k].u;
      for (std::size_t i = k + 1; i < wp_.size(); ++i) apply(wp_[i], -q[wp_[i].index], p, v);
      m.col(wp_[k].program_axis) = v;
    }
    return m;
  }

  // The machine index of program axis `program_axis` (0..5: X Y Z A B C), -1 when the chain has no joint for it.
  int axis_index(int program_axis) const {
    for (const auto* chain : {&wp_, &tool_})
      for (const Joint& j : *chain)
        if (j.program_axis == program_axis) return j.index;
    return -1;
  }

  // The machine index of the rotary axis that is free at the singular pose (the tool axis along it), or -1.
  int free_axis() const { return ja_ && family_ != KinematicFamily::ForwardOnly ? ja_->index : -1; }
  // Whether tool axis v (unit, workpiece frame) is within `tol` rad of that singular pose.
  bool near_singular(const Eigen::Vector3d& v, double tol) const {
    return free_axis() >= 0 && (v - ja_->u * ja_->u.dot(v)).norm() < tol;
  }

 private:
  struct Joint {
    int index = -1;  // machine axis index: q[index] is the joint value
    int program_axis = 0;
    bool rotary = false;
    Eigen::Vector3d u = Eigen::Vector3d::UnitZ(), p = Eigen::Vector3d::Zero();
    bool continuous = false;
    double lo = 0, hi = 0;  // travel
    std::string where;
  };

  // A travel limit is met within 1e-9 (mm or rad) so that poses computed at a limit stay reachable.
  static constexpr double kTravelSlack = 1e-9;
  // A tool axis within 1e-10 rad of a rotary axis is on it: the singular pose where that axis is free. Solving the
  // angle there from components of 1e-10 gives a direction that is noise; holding the axis still instead turns the
  // tool axis by at most 1e-10 rad.
  static constexpr double kSingular = 1e-10;
  static constexpr double kAxisSlack = 1e-9;

  // A rotary joint's cosine and sine at the angle whose bits are `bits` (forward_rows keeps them across rows:
  // computed again only when the angle changes; a fresh one computes them).
  struct Trig {
    bool valid = false;
    std::uint64_t bits = 0;
    double c = 1, s = 0;
  };
  // Applies the joint at value q to a point and a direction of the bodies it carries (q = 0 leaves them exactly
  // as they are, so a chain at zero reproduces the Cartesian machine bit for bit).
  static void apply(const Joint& j, double q, Eigen::Vector3d& p, Eigen::Vector3d& v) {
    Trig fresh;
    apply(j, q, p, v, fresh);
  }
  static void apply(const Joint& j, double q, Eigen::Vector3d& p, Eigen::Vector3d& v, Trig& trig) {
    if (q == 0.0) return;
    if (!j.rotary) {
      p += q * j.u;
      return;
    }
    const auto bits = std::bit_cast<std::uint64_t>(q);
    if (!trig.valid || trig.bits != bits) {
      const double c = std::cos(q), s = std::sin(q);
      trig = {true, bits, c, s};
    }
    p = j.p + rotate(j.u, trig.c, trig.s, p - j.p);
    v = rotate(j.u, trig.c, trig.s, v);
  }

  // The pose at joint values q (q[i] in machine order; a vector or a row), each joint's cosine and sine through
  // trig[] (tool joints from the tip up, then the workpiece's).
  template <class Q>
  ToolPose pose_at(const Q& q, double tlo, Trig* trig) const {
    Eigen::Vector3d p = gauge_ - tlo * d_, v = d_;
    std::size_t c = 0;
    for (auto it = tool_.rbegin(); it != tool_.rend(); ++it) apply(*it, q[it->index], p, v, trig[c++]);
    for (const Joint& j : wp_) apply(j, -q[j.index], p, v, trig[c++]);
    return ToolPose{p - origin_, v};
  }

  // A rotary joint's rotation at the angle whose bits are `bits`, and the shift p - rot p it gives its point.
  struct Rotation {
    bool valid = false;
    std::uint64_t bits = 0;
    Eigen::Matrix3d rot;
    Eigen::Vector3d shift;
  };
  static void rotation(const Joint& j, double q, Eigen::Matrix3d& rot) {
    const double c = std::cos(q), s = std::sin(q);
    for (int k = 0; k < 3; ++k) rot.col(k) = rotate(j.u, c, s, Eigen::Vector3d::Unit(k));
  }

  // Composes (r, t) <- (r, t) * exp(joint q).
  static void step(const Joint& j, double q, Eigen::Matrix3d& r, Eigen::Vector3d& t) {
    Rotation fresh;
    step(j, q, r, t, fresh);
  }
  // The same, the rotation kept across calls and computed again only when the angle changes (tip_velocity_rows).
  static void step(const Joint& j, double q, Eigen::Matrix3d& r, Eigen::Vector3d& t, Rotation& cache) {
    if (!j.rotary) {
      t += r * (q * j.u);
      return;
    }
    const auto bits = std::bit_cast<std::uint64_t>(q);
    if (!cache.valid || cache.bits != bits) {
      cache.valid = true;
      cache.bits = bits;
      rotation(j, q, cache.rot);
      cache.shift = j.p - cache.rot * j.p;
    }
    t += r * cache.shift;
    r = r * cache.rot;
  }

  static Eigen::Vector3d point_velocity(bool rotary, const Eigen::Vector3d& u, const Eigen::Vector3d& p,
                                        const Eigen::Vector3d& x) {
    return rotary ? Eigen::Vector3d(u.cross(x - p)) : u;
  }

  // The column-by-column paths of forward_rows and tip_velocity_rows (issue 21: a three-axis program on a five-axis
  // machine, every row the same rotation). They make each output value by the same operations in the same order as
  // the row-by-row code, so the same bits; a run shorter than kMinRun rows is not worth its set-up. Chunks of kChunk
  // rows on the stack: no allocation per call.
  static constexpr Eigen::Index kMinRun = 16, kChunk = 256;

  // Whether every rotary joint's value on row k is zero (+0 or -0: apply() leaves the pose as it is).
  bool rotaries_at_zero(const Eigen::Ref<const Eigen::MatrixXd>& q, Eigen::Index k) const {
    for (const Joint* j : rot_)
      if (q(k, j->index) != 0.0) return false;
    return true;
  }

  // p[r] += x[r] u (x[r] negated first when `negate`) unless x[r] is zero, apply()'s linear joint on each row. Two rows
  // at a time with SSE2 (GCC does not vectorise the select): the same product and sum on each lane, then the select.
  static void add_unless_zero(double* p, const double* x, double u, Eigen::Index m, bool negate) {
    Eigen::Index r = 0;
#if defined(__SSE2__)
    const __m128d vu = _mm_set1_pd(u), zero = _mm_setzero_pd(), sign = _mm_set1_pd(negate ? -0.0 : 0.0);
    for (; r + 2 <= m; r += 2) {
      const __m128d xr = _mm_xor_pd(_mm_loadu_pd(x + r), sign), pr = _mm_loadu_pd(p + r);
      const __m128d sum = _mm_add_pd(pr, _mm_mul_pd(xr, vu));
      const __m128d is_zero = _mm_cmpeq_pd(xr, zero);
      _mm_storeu_pd(p + r, _mm_or_pd(_mm_and_pd(is_zero, pr), _mm_andnot_pd(is_zero, sum)));
    }
#endif
    for (; r < m; ++r) {
      const double xr = negate ? -x[r] : x[r];
      if (xr != 0.0) p[r] = p[r] + xr * u;
    }
  }

  // Rows [k0, k1) of forward_rows, every rotary joint at zero there: pose_at's linear sums, column by column. A joint
  // at exactly zero leaves the point as it is (apply()'s early return), hence the select rather than the sum.
  void forward_linear_rows(const Eigen::Ref<const Eigen::MatrixXd>& q, const Eigen::Ref<const Eigen::VectorXd>& tlo,
                           Eigen::Index k0, Eigen::Index k1, Eigen::Ref<Eigen::MatrixXd> tip,
                           Eigen::Ref<Eigen::MatrixXd> axis) const {
    const bool axes_wanted = axis.size() > 0;
    for (Eigen::Index c0 = k0; c0 < k1; c0 += kChunk) {
      const Eigen::Index m = std::min(kChunk, k1 - c0);
      const double* l = tlo.data() + c0;
      for (int c = 0; c < 3; ++c) {
        double p[kChunk];
        for (Eigen::Index r = 0; r < m; ++r) p[r] = gauge_[c] - l[r] * d_[c];
        for (auto it = tool_.rbegin(); it != tool_.rend(); ++it) {
          if (it->rotary) continue;
          const double* x = q.col(it->index).data() + c0;
          const double u = it->u[c];
          add_unless_zero(p, x, u, m, false);
        }
        for (const Joint& j : wp_) {
          if (j.rotary) continue;
          const double* x = q.col(j.index).data() + c0;
          const double u = j.u[c];
          add_unless_zero(p, x, u, m, true);
        }
        double* out = tip.col(c).data() + c0;
        for (Eigen::Index r = 0; r < m; ++r) out[r] = p[r] - origin_[c];
        if (axes_wanted) axis.col(c).segment(c0, m).setConstant(d_[c]);
      }
    }
  }

  // Whether row k's workpiece joints have the bits `bits` (the cached rotation's).
  bool wp_same(const Eigen::Ref<const Eigen::MatrixXd>& q, Eigen::Index k,
               const std::vector<std::uint64_t>& bits) const {
    for (std::size_t i = 0; i < wp_.size(); ++i)
      if (std::bit_cast<std::uint64_t>(q(k, wp_[i].index)) != bits[i]) return false;
    return true;
  }
  // Whether row k's tool joints and tool length offset are finite (the column path's identity products below).
  bool linear_finite(const Eigen::Ref<const Eigen::MatrixXd>& q, const Eigen::Ref<const Eigen::VectorXd>& tlo,
                     Eigen::Index k) const {
    bool ok = std::isfinite(tlo[k]);
    for (const Joint& j : tool_) ok = ok && std::isfinite(q(k, j.index));
    return ok;
  }

  // Rows [k0, k1) of tip_velocity_rows when the tool chain is linear only (its rotation r stays the identity) and the
  // workpiece chain's values are those of the cached wp_u, wp_p, wp_r on every row. The row-by-row code's r * w with
  // r the identity: the three products 1 w_c, 0 w_a, 0 w_b summed, which for finite w is w_c + 0 w_a + 0 w_b in any
  // order (a sum of w_c and signed zeros is exact; its zero's sign does not depend on the order). The last product,
  // wp_r^T v, takes Eigen's own expression per row (its summation order is Eigen's).
  void tip_velocity_linear_rows(const Eigen::Ref<const Eigen::MatrixXd>& q, const Eigen::Ref<const Eigen::MatrixXd>& qd,
                                const Eigen::Ref<const Eigen::VectorXd>& tlo, Eigen::Index k0, Eigen::Index k1,
                                const std::vector<Eigen::Vector3d>& wp_u, const std::vector<Eigen::Vector3d>& wp_p,
                                const Eigen::Matrix3d& wp_r, Eigen::Ref<Eigen::MatrixXd> out) const {
    // u_moved of the tool joints: r u with r the identity, as the row-by-row code computes it.
    Eigen::Vector3d u_moved[6];
    {
      const Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
      for (std::size_t i = 0; i < tool_.size(); ++i) u_moved[i] = r * tool_[i].u;
    }
    const auto id_times = [](double wc, double wa, double wb) { return wc + 0.0 * wa + 0.0 * wb; };
    for (Eigen::Index c0 = k0; c0 < k1; c0 += kChunk) {
      const Eigen::Index m = std::min(kChunk, k1 - c0);
      double t[3][kChunk], tip_b[3][kChunk], v[3][kChunk];
      for (int c = 0; c < 3; ++c)
        for (Eigen::Index r = 0; r < m; ++r) t[c][r] = 0.0;
      // t += r (q u) joint by joint.
      for (const Joint& j : tool_) {
        const double* x = q.col(j.index).data() + c0;
        for (Eigen::Index r = 0; r < m; ++r) {
          const double w0 = x[r] * j.u[0], w1 = x[r] * j.u[1], w2 = x[r] * j.u[2];
          t[0][r] = t[0][r] + id_times(w0, w1, w2);
          t[1][r] = t[1][r] + id_times(w1, w0, w2);
          t[2][r] = t[2][r] + id_times(w2, w0, w1);
        }
      }
      // tip_b = r (gauge - tlo d) + t.
      const double* l = tlo.data() + c0;
      for (Eigen::Index r = 0; r < m; ++r) {
        const double y0 = gauge_[0] - l[r] * d_[0], y1 = gauge_[1] - l[r] * d_[1], y2 = gauge_[2] - l[r] * d_[2];
        tip_b[0][r] = id_times(y0, y1, y2) + t[0][r];
        tip_b[1][r] = id_times(y1, y0, y2) + t[1][r];
        tip_b[2][r] = id_times(y2, y0, y1) + t[2][r];
      }
      // v_rel: the tool joints' velocities, then minus the workpiece joints' at the tip.
      for (int c = 0; c < 3; ++c)
        for (Eigen::Index r = 0; r < m; ++r) v[c][r] = 0.0;
      for (std::size_t i = 0; i < tool_.size(); ++i) {
        const double* w = qd.col(tool_[i].index).data() + c0;
        for (int c = 0; c < 3; ++c) {
          const double u = u_moved[i][c];
          for (Eigen::Index r = 0; r < m; ++r) v[c][r] = v[c][r] + w[r] * u;
        }
      }
      for (std::size_t i = 0; i < wp_.size(); ++i) {
        const double* w = qd.col(wp_[i].index).data() + c0;
        const Eigen::Vector3d& a = wp_u[i];
        if (!wp_[i].rotary) {
          for (int c = 0; c < 3; ++c)
            for (Eigen::Index r = 0; r < m; ++r) v[c][r] = v[c][r] - w[r] * a[c];
          continue;
        }
        // u x (tip_b - p), Eigen's cross product's formula.
        const Eigen::Vector3d& p = wp_p[i];
        for (Eigen::Index r = 0; r < m; ++r) {
          const double b0 = tip_b[0][r] - p[0], b1 = tip_b[1][r] - p[1], b2 = tip_b[2][r] - p[2];
          const double x0 = a[1] * b2 - a[2] * b1, x1 = a[2] * b0 - a[0] * b2, x2 = a[0] * b1 - a[1] * b0;
          v[0][r] = v[0][r] - w[r] * x0;
          v[1][r] = v[1][r] - w[r] * x1;
          v[2][r] = v[2][r] - w[r] * x2;
        }
      }
      for (Eigen::Index r = 0; r < m; ++r) {
        const Eigen::Vector3d v_rel(v[0][r], v[1][r], v[2][r]);
        out.row(c0 + r) = (wp_r.transpose() * v_rel).transpose();
      }
    }
  }

  // The family, and for the two-rotary families the form the tool axis takes in the workpiece frame:
  //   v = Rot(a, alpha) Rot(b, beta) d,  joint_a = sa * alpha, joint_b = sb * beta,
  // since v = Rw^T Rt d with Rw, Rt the products of the workpiece and tool chains' rotations:
  //   table-table (workpiece rotaries w1 then w2): v = Rot(w2, -q2) Rot(w1, -q1) d;
  //   head-table (workpiece rotary w, tool rotary h): v = Rot(w, -qw) Rot(h, qh) d;
  //   head-head (tool rotaries h1 then h2): v = Rot(h1, q1) Rot(h2, q2) d.
  // The "a" joint is the one that is free when the tool axis lies along it (the C table of an A/C table machine).
  void classify() {
    std::vector<const Joint*> wr, tr;
    for (const Joint& j : wp_)
      if (j.rotary) wr.push_back(&j);
    for (const Joint& j : tool_)
      if (j.rotary) tr.push_back(&j);
    for (const Joint* j : wr) rot_.push_back(j);
    for (const Joint* j : tr) rot_.push_back(j);
    if (wr.empty() && tr.empty()) {
      family_ = KinematicFamily::Cartesian;
      return;
    }
    if (wr.size() == 2 && tr.empty()) {
      family_ = KinematicFamily::TableTable;
      ja_ = wr[1], sa_ = -1, jb_ = wr[0], sb_ = -1;
    } else if (wr.size() == 1 && tr.size() == 1) {
      family_ = KinematicFamily::HeadTable;
      ja_ = wr[0], sa_ = -1, jb_ = tr[0], sb_ = 1;
    } else if (wr.empty() && tr.size() == 2) {
      family_ = KinematicFamily::HeadHead;
      ja_ = tr[0], sa_ = 1, jb_ = tr[1], sb_ = 1;
    } else {
      family_ = KinematicFamily::ForwardOnly;
      forward_only_reason_ = fmt::format(
          "{} rotary joints on the workpiece side and {} on the tool side; the inverse is closed-form for two rotary "
          "joints (table-table, head-table, head-head) or none",
          wr.size(), tr.size());
      return;
    }
    if (ja_->u.cross(jb_->u).norm() < 1e-9) {
      family_ = KinematicFamily::ForwardOnly;
      forward_only_reason_ = fmt::format(
          "the rotary axes {} ({}) and {} ({}) are parallel: they turn the tool axis "
          "about one direction only",
          kAxisNames[ja_->program_axis], ja_->where, kAxisNames[jb_->program_axis], jb_->where);
    } else if (jb_->u.cross(d_).norm() < 1e-9) {
      family_ = KinematicFamily::ForwardOnly;
      forward_only_reason_ = fmt::format("the rotary axis {} ({}) lies along the tool: it cannot tilt it",
                                         kAxisNames[jb_->program_axis], jb_->where);
    }
  }

  // The 2 pi equivalent of theta closest to near within the joint's travel; nullopt when none is.
  static std::optional<double> equivalent(const Joint& j, double theta, double near) {
    const double t = near + std::remainder(theta - near, kTwoPi);
    if (j.continuous || (t >= j.lo - kTravelSlack && t <= j.hi + kTravelSlack)) return t;
    std::optional<double> best;
    const double kmin = std::ceil((j.lo - kTravelSlack - t) / kTwoPi);
    const double kmax = std::floor((j.hi + kTravelSlack - t) / kTwoPi);
    for (double k = kmin; k <= kmax && k - kmin < 1e4; k += 1) {
      const double c = t + k * kTwoPi;
      if (!best || std::abs(c - near) < std::abs(*best - near)) best = c;
    }
    return best;
  }

  // The rotary angles for tool axis v (Paden-Kahan subproblem 2: two rotations about intersecting axes, Murray, Li &
  // Sastry section 3.2.2). w = Rot(b, beta) d = Rot(a, -alpha) v has a.w = a.v, b.w = b.d and |w| = 1:
  //   w = x a + y b + z (a x b), with x, y from the two dot products and z = +-sqrt(...): two solutions, one on the
  //   boundary of the reachable orientations, none beyond it. z is taken from the part of v normal to a (exact for
  //   small tilts, where 1 - (a.v)^2 would lose the digits).
  template <class Consider>
  void solve_rotary(const Eigen::Vector3d& v, const Eigen::VectorXd& near, std::vector<std::string>& reasons,
                    Consider&& consider) const {
    const Eigen::Vector3d& a = ja_->u;
    const Eigen::Vector3d& b = jb_->u;
    const Eigen::Vector3d n = a.cross(b);
    const double c = a.dot(b), s2 = 1 - c * c;
    const double av = a.dot(v), bd = b.dot(d_);
    const double x = (av - c * bd) / s2, y = (bd - c * av) / s2;
    const Eigen::Vector3d v_perp = v - a * av;
    const double z2 = v_perp.squaredNorm() / s2 - y * y;
    const bool singular = v_perp.norm() < kSingular;

    std::vector<std::pair<double, double>> sols;  // (alpha, beta)
    if (singular) {
      // The tool axis lies along a: a is free. It stays where near has it (continuity through the singular pose; a
      // path passing close to it needs a fast turn of a, which is the machine's, not a flip of the solution).
      const double alpha = sa_ * near[ja_->index];
      const Eigen::Vector3d w = rotate(a, std::cos(alpha), -std::sin(alpha), v);
      const Eigen::Vector3d w_perp = w - b * b.dot(w), d_perp = d_ - b * bd;
      if (std::abs(b.dot(w) - bd) > 1e-9 || std::abs(w_perp.norm() - d_perp.norm()) > 1e-9) {
        reasons.push_back(fmt::format("the tool axis along {} makes an angle with {} that the tool never makes",
                                      kAxisNames[ja_->program_axis], kAxisNames[jb_->program_axis]));
        return;
      }
      sols.emplace_back(alpha, angle_about(b, d_, w));
    } else {
      if (z2 < -1e-10) {
        reasons.push_back(fmt::format(
            "the tool axis makes {:.6f} deg with the {} axis, outside the orientations {} and {} can give the tool",
            deg(std::acos(std::clamp(av, -1.0, 1.0))), kAxisNames[ja_->program_axis], kAxisNames[ja_->program_axis],
            kAxisNames[jb_->program_axis]));
        return;
      }
      const double z = std::sqrt(std::max(z2, 0.0));
      for (const double zs : {z, -z}) {
        const Eigen::Vector3d w = x * a + y * b + zs * n;
        sols.emplace_back(angle_about(a, w, v), angle_about(b, d_, w));
        if (z == 0) break;  // one solution on the boundary
      }
    }
    for (const auto& [alpha, beta] : sols) {
      const double ta = sa_ * alpha, tb = sb_ * beta;
      const auto qa = singular ? std::optional<double>(near[ja_->index]) : equivalent(*ja_, ta, near[ja_->index]);
      const auto qb = equivalent(*jb_, tb, near[jb_->index]);
      if (!qa || !qb) {
        const Joint& bad = qa ? *jb_ : *ja_;
        reasons.push_back(
            fmt::format("{} = {:.4f} deg (or any turn from it) is outside its travel [{:.4f}, {:.4f}] deg",
                        kAxisNames[bad.program_axis], deg(qa ? tb : ta), deg(bad.lo), deg(bad.hi)));
        continue;
      }
      Eigen::VectorXd q = near;
      q[ja_->index] = *qa;
      q[jb_->index] = *qb;
      consider(std::move(q));
    }
  }

  std::string file_, name_;
  std::size_t n_;
  std::vector<Joint> wp_, tool_;
  Eigen::Vector3d origin_, gauge_, d_;
  int lin_[3] = {-1, -1, -1};      // machine index of the linear joint of program axis X, Y, Z
  std::vector<const Joint*> rot_;  // rotary joints
  KinematicFamily family_ = KinematicFamily::ForwardOnly;
  bool tool_linear_ = true;  // the tool chain has no rotary joint (its rotation stays the identity)
  std::string forward_only_reason_;
  const Joint* ja_ = nullptr;
  const Joint* jb_ = nullptr;
  double sa_ = 1, sb_ = 1;
};

// ---- Tool paths into axis space ----------------------------------------------------------------------------------

// The programmed tip at path parameter s (workpiece frame): exactly the end points at s = 0 and 1.
Eigen::Vector3d tip_at(const core::Move& m, const core::ArcFrame* g, double s) {
  if (g) return g->point_at(s).head<3>();
  if (s <= 0) return m.start.head<3>();
  if (s >= 1) return m.end.head<3>();
  return m.start.head<3>() + s * (m.end.head<3>() - m.start.head<3>());
}

// Length of the programmed tip path (mm).
double tip_length(const core::Move& m, const core::ArcFrame* g) {
  return g ? g->length_mm() : (m.end.head<3>() - m.start.head<3>()).norm();
}

// Tool axis of a CL move at s: the great circle between its end values (the shortest rotation, as a CL file's
// successive tool vectors mean).
Eigen::Vector3d axis_at(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, double s) {
  if (s <= 0) return a0;
  if (s >= 1) return a1;
  const double ang = std::atan2(a0.cross(a1).norm(), a0.dot(a1));
  if (ang < 1e-12) return (a0 + s * (a1 - a0)).normalized();
  return (std::sin((1 - s) * ang) * a0 + std::sin(s * ang) * a1) / std::sin(ang);
}

// Move::tip_per_mm and tip_per_deg of an axis-space move, from the chain's Jacobian at its start, via points and end
// (a first-order bound: the interpolator's blends leave the path by micrometres, over which the Jacobian is constant
// to many digits). Linear part: the largest singular value of the linear axes' map, exactly 1 when it is orthonormal
// (so chain machines with their rotary axes still blend exactly as "xyz" machines do). Rotary axis i: the larger of
// the tip's speed per rad of it and 100 mm times the tool axis' (at most 1 rad per rad: each rotary joint turns the
// tool axis about its own axis), per degree.
template <class ToQ>
void set_gains(const ChainKinematics& k, core::Move& m, const ToQ& to_q) {
  double lin = 0;
  Eigen::Vector3d per_deg = Eigen::Vector3d::Zero();
  auto at = [&](const core::Vec6& v) {
    const Eigen::VectorXd q = to_q(v);
    const Eigen::Matrix3d lm = k.linear_map(q);
    const double sigma = (lm.transpose() * lm - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12
                             ? 1.0
                             : Eigen::JacobiSVD<Eigen::Matrix3d>(lm).singularValues()[0];
    lin = std::max(lin, sigma);
    for (int r = 0; r < 3; ++r) {
      const int idx = k.axis_index(3 + r);
      if (idx < 0) continue;
      Eigen::VectorXd qd = Eigen::VectorXd::Zero(q.size());
      qd[idx] = 1.0;
      const double g = std::max(k.tip_velocity(q, qd, m.tool_length_offset_mm).norm(), 100.0) * core::units::kDegToRad;
      per_deg[r] = std::max(per_deg[r], g);
    }
  };
  at(m.start);
  for (const core::Vec6& v : m.via) at(v);
  at(m.end);
  m.tip_per_mm = lin;
  m.tip_per_deg = per_deg;
}

core::ToolPath chain_toolpath(const core::ToolPath& path, const core::Machine& machine, const AxisSpaceOptions& opt) {
  if (!(opt.tolerance_mm > 0)) throw core::Error("toolpath_in_axis_space: the tolerance must be > 0");
  core::ToolPath out = path;
  const std::size_t na = machine.axes.size();
  // The chain is built only for CL and TCP moves: joint programs need no transform (and test machines trimmed to a
  // few axes have no complete chain).
  std::optional<ChainKinematics> kin_storage;
  auto kin = [&]() -> const ChainKinematics& {
    if (!kin_storage) kin_storage.emplace(machine);
    return *kin_storage;
  };
  auto to_q = [&](const core::Vec6& v) {
    Eigen::VectorXd q(static_cast<Eigen::Index>(na));
    for (std::size_t i = 0; i < na; ++i) q[static_cast<Eigen::Index>(i)] = v[machine.axes[i].program_axis];
    return q;
  };
  // Axis positions as a Vec6; program axes the machine lacks keep the program's values (the interpolator refuses a
  // program that moves them).
  auto to_v6 = [&](const Eigen::VectorXd& q, core::Vec6 base) {
    for (std::size_t i = 0; i < na; ++i) base[machine.axes[i].program_axis] = q[static_cast<Eigen::Index>(i)];
    return base;
  };
  const double tol = opt.tolerance_mm;
  const double axis_tol = tol / 100.0;  // rad: a point 100 mm up the tool within tol

  // Program move mi in axis space, joining prev_end; start_q: the axes a path's first move starts at (the branch of the
  // inverse chosen for it), else the inverse nearest prev_end.
  auto convert = [&](std::size_t mi, const core::Vec6& prev_end,
                     const std::optional<Eigen::VectorXd>& start_q) -> core::Move {
    const core::Move& pm = path.moves[mi];
    core::Move m = pm;
    const double tlo = pm.tool_length_offset_mm;
    const bool cl = pm.tool_axis_start.has_value() || pm.tool_axis_end.has_value();
    if (!cl && !pm.tcp) {
      // Joint programming: the words are the axes, the tool length offset on Z (LinuxCNC's identity kinematics).
      m.start[core::kZ] += tlo;
      m.end[core::kZ] += tlo;
      if (m.kind == core::MotionKind::Arc) {
        if (m.plane == core::ArcPlane::ZX) m.centre_mm[0] += tlo;
        if (m.plane == core::ArcPlane::YZ) m.centre_mm[1] += tlo;
      }
      // Gains for the interpolator's corner tolerance: only where the chain exists (test machines trimmed to a few
      // axes have none; they keep the 3-axis gains).
      bool complete = true;
      try {
        (void)kin();
      } catch (const core::Error&) {
        complete = false;
      }
      if (complete) set_gains(kin(), m, to_q);
      return m;
    }
    const ChainKinematics& k = kin();
    auto fail = [&](const std::string& msg) -> core::Error {
      return core::Error(core::located(path.source_path, pm.source_line, msg));
    };
    std::optional<core::ArcFrame> geom;
    if (pm.kind == core::MotionKind::Arc) geom = core::arc_frame(pm, path.source_path);
    const core::ArcFrame* g = geom ? &*geom : nullptr;
    Eigen::Vector3d a0 = Eigen::Vector3d::UnitZ(), a1 = a0;
    if (cl) {
      a0 = (pm.tool_axis_start ? *pm.tool_axis_start : *pm.tool_axis_end).normalized();
      a1 = (pm.tool_axis_end ? *pm.tool_axis_end : *pm.tool_axis_start).normalized();
      if (!a0.allFinite() || !a1.allFinite()) throw fail("tool axis of zero length");
      if (std::atan2(a0.cross(a1).norm(), a0.dot(a1)) > core::units::kPi - 1e-6)
        throw fail("the tool axis turns over by 180 deg in one move: no great circle between its end values");
    }
    // The exact axis-space image of the move at path parameter s.
    auto image = [&](double s, const Eigen::VectorXd& near) -> Eigen::VectorXd {
      try {
        if (cl) return k.inverse(ToolPose{tip_at(pm, g, s), axis_at(a0, a1, s)}, tlo, near);
        Eigen::VectorXd q = near;
        for (std::size_t i = 0; i < na; ++i) {
          const int pa = machine.axes[i].program_axis;
          if (pa >= 3)
            q[static_cast<Eigen::Index>(i)] = s >= 1 ? pm.end[pa] : pm.start[pa] + s * (pm.end[pa] - pm.start[pa]);
        }
        return k.place_tip(tip_at(pm, g, s), tlo, q);
      } catch (const core::Error& e) {
        throw fail(e.what());
      }
    };

    Eigen::VectorXd q0 = start_q ? *start_q : image(0.0, to_q(prev_end));
    if (mi > 0) {
      const core::Vec6 s6 = to_v6(q0, pm.start);
      if ((s6 - prev_end).cwiseAbs().maxCoeff() > 1e-6)
        throw fail(
            fmt::format("the move starts at axes ({:.6f}, {:.6f}, {:.6f}, {:.6f}, {:.6f}, {:.6f}) but the "
                        "previous move ended at ({:.6f}, {:.6f}, {:.6f}, {:.6f}, {:.6f}, {:.6f}): a tool length "
                        "change or a switch between tool-centre-point and joint programming needs a move of its "
                        "own",
                        s6[0], s6[1], s6[2], s6[3], s6[4], s6[5], prev_end[0], prev_end[1], prev_end[2], prev_end[3],
                        prev_end[4], prev_end[5]));
      q0 = to_q(prev_end);  // exact continuity
    }
    Eigen::VectorXd q1 = image(1.0, q0);
    // Rotary axes that turn by 1e-12 rad or less (a CL move whose tool axis the inverse solves again to the last
    // digit) hold still: the move keeps its line or arc.
    bool rot_const = true;
    for (std::size_t i = 0; i < na; ++i) {
      const auto ii = static_cast<Eigen::Index>(i);
      if (machine.axes[i].kind == core::AxisKind::Rotary && std::abs(q0[ii] - q1[ii]) > 1e-12) rot_const = false;
    }
    if (rot_const && cl) {
      try {
        q1 = k.place_tip(tip_at(pm, g, 1.0), tlo, q0);
      } catch (const core::Error& e) {
        throw fail(e.what());
      }
    }
    // With the rotary axes still, the tip is an affine image of X Y Z: lines stay lines, and arcs stay arcs when the
    // map is a rotation (or reflection) taking the arc's plane onto a plane of the axes.
    Eigen::Matrix3d lm = Eigen::Matrix3d::Identity();
    bool ortho = false;
    if (rot_const) {
      lm = k.linear_map(q0);
      ortho = (lm.transpose() * lm - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12;
    }
    bool curved = !rot_const;
    if (rot_const && g) {
      curved = true;
      if (ortho) {
        const int n_prog = g->normal;  // the arc plane's normal: Z for XY, Y for ZX, X for YZ
        const Eigen::Vector3d n_axes = lm.transpose() * Eigen::Vector3d::Unit(n_prog);
        int kk = 0;
        n_axes.cwiseAbs().maxCoeff(&kk);
        if (std::abs(std::abs(n_axes[kk]) - 1) < 1e-12) {
          curved = false;
          const double sense = (n_axes[kk] > 0 ? 1.0 : -1.0) * (lm.determinant() > 0 ? 1.0 : -1.0);
          m.plane = kk == core::kZ ? core::ArcPlane::XY : kk == core::kY ? core::ArcPlane::ZX : core::ArcPlane::YZ;
          m.rotation = sense > 0 ? pm.rotation : -pm.rotation;
          Eigen::Vector3d c3 = pm.start.head<3>();
          c3[g->axis1] = g->centre_mm[0];
          c3[g->axis2] = g->centre_mm[1];
          const Eigen::VectorXd qc = k.place_tip(c3, tlo, q0);
          core::Vec6 c6 = to_v6(qc, pm.start);
          const core::PlaneAxes pa = core::plane_axes(m.plane);
          m.centre_mm = Eigen::Vector2d(c6[pa.axis1], c6[pa.axis2]);
        }
      }
    }
    if (curved) {
      // March along the move, each point solved from the last (continuity of the rotary axes, no 2 pi jumps), with
      // steps halved until the axis-space chord keeps the tip (and tool axis) within the tolerance at its quarter
      // points, and doubled again after.
      const double turn = cl ? std::atan2(a0.cross(a1).norm(), a0.dot(a1)) : 0.0;
      double h_max = 1.0 / std::max(1.0, std::ceil(turn / (2 * core::units::kDegToRad)));
      // On an arc, no step spans more than half a turn: the checks at a chord's quarter points would see whole turns
      // (a full circle of four turns) as nothing. Halvings keep the steps the ones the tolerance picks anyway.
      while (g && h_max * std::abs(g->sweep_rad) > core::units::kPi) h_max *= 0.5;
      auto chord_ok = [&](double sa, const Eigen::VectorXd& qa, double sb, const Eigen::VectorXd& qb) {
        for (const double f : {0.25, 0.5, 0.75}) {
          const double s = sa + f * (sb - sa);
          const ToolPose p = k.forward(qa + f * (qb - qa), tlo);
          if ((p.tip_mm - tip_at(pm, g, s)).norm() > tol) return false;
          if (cl) {
            const Eigen::Vector3d ax = axis_at(a0, a1, s);
            if (std::atan2(p.axis.cross(ax).norm(), p.axis.dot(ax)) > axis_tol) return false;
          }
        }
        return true;
      };
      double s = 0, h = h_max, spun_at = -1;
      Eigen::VectorXd q = q0;
      m.via.clear();
      m.via_s.clear();
      auto add_via = [&](double sv, const Eigen::VectorXd& qv) {
        m.via.push_back(to_v6(qv, pm.start + sv * (pm.end - pm.start)));
        m.via_s.push_back(sv);
        if (m.via.size() > 1000000) throw fail("more than a million via points for one move");
      };
      const int free_ax = k.free_axis();
      while (s < 1) {
        const double sb = 1 - s <= h ? 1.0 : s + h;
        Eigen::VectorXd qb = image(sb, q);
        if (chord_ok(s, q, sb, qb)) {
          s = sb;
          q = std::move(qb);
          if (s < 1) add_via(s, q);
          h = std::min(2 * h, h_max);
          continue;
        }
        h *= 0.5;
        if (h >= 1e-9) continue;
        if (cl && free_ax >= 0 && spun_at != s && k.near_singular(axis_at(a0, a1, s), 1e-6)) {
          // Leaving the singular pose (the tool axis along the free rotary axis, whose angle the pose does not fix) in
          // a direction that needs another angle of it: the axis turns there first, with the tip and the tool axis
          // held (via points at the same s; the machine's physics: the closer a path passes the singular pose, the
          // faster that axis must turn, and through it, it must turn on the spot).
          const double target = qb[free_ax], from = q[free_ax];
          const Eigen::Vector3d tip_s = tip_at(pm, g, s);
          double done = 0, dh = 1;
          while (done < 1) {
            const double nb = std::min(1.0, done + dh);
            Eigen::VectorXd qn = q;
            qn[free_ax] = from + nb * (target - from);
            try {
              qn = k.place_tip(tip_s, tlo, qn);
            } catch (const core::Error& e) {
              throw fail(e.what());
            }
            if (!chord_ok(s, q, s, qn)) {
              dh *= 0.5;
              if (dh < 1e-9) throw fail("the free rotary axis cannot turn at the singular pose within the tolerance");
              continue;
            }
            done = nb;
            q = std::move(qn);
            add_via(s, q);
            dh = std::min(2 * dh, 1.0);
          }
          spun_at = s;
          h = h_max;
          continue;
        }
        // Why: the solution that continues this one is beyond a travel limit (the inverse's reasons at sb).
        std::vector<std::string> reasons;
        if (cl) (void)k.solutions(ToolPose{tip_at(pm, g, sb), axis_at(a0, a1, sb)}, tlo, q, reasons);
        std::string why;
        for (const std::string& r : reasons) why += (why.empty() ? "" : "; ") + r;
        throw fail(fmt::format(
            "the axes cannot follow the programmed path within {} mm at s = {:.9f}: the rotary axes would have to jump "
            "to the other solution of the inverse ({})",
            tol, s, why.empty() ? "a travel limit forces it" : why));
      }
      q1 = q;
      m.kind = core::MotionKind::Line;
      m.rotation = 0;
      m.centre_mm.setZero();
    }
    // The programmed feed is the tip's speed in the workpiece frame. When the axes' speed differs from it (rotary axes
    // turning, or linear axes that are not orthonormal), the move gets its programmed duration as an inverse-time
    // feed: RS274/NGC (NIST IR 6556, 2.1.2.5): the tip's length over F, or the rotary words' angle over F (deg/min)
    // when the tip does not move.
    if (!pm.rapid && pm.feed_mode == core::FeedMode::UnitsPerMinute && (!rot_const || !ortho) &&
        pm.feed_mm_per_min > 0) {
      double amount = tip_length(pm, g);
      if (!(amount > 1e-9)) {
        if (cl) {
          amount = std::atan2(a0.cross(a1).norm(), a0.dot(a1)) * core::units::kRadToDeg;
        } else {
          double d2 = 0;
          for (int pa = 3; pa < 6; ++pa) d2 += std::pow((pm.end[pa] - pm.start[pa]) * core::units::kRadToDeg, 2);
          amount = std::sqrt(d2);
        }
      }
      if (amount > 1e-12) {
        m.feed_mode = core::FeedMode::InverseTime;
        m.inverse_time_per_min = pm.feed_mm_per_min / amount;
      }
    }
    m.start = to_v6(q0, pm.start);
    m.end = to_v6(q1, pm.end);
    set_gains(k, m, to_q);
    return m;
  };

  // The branch of the inverse ((B, C) or (-B, C + 180 deg) on a B/C table) is chosen per stretch of the path between
  // switch points: the first move, and every CL rapid, where the axes may take the other branch as a controller's
  // orientation transformation does (the rapid then runs in axis space, straight from axes to axes: its tip leaves the
  // programmed line). A stretch is solved on the branch the axes are on first; only when that fails (a travel limit
  // the continuous solution meets) is it solved from the other branch, and only when every branch fails is it an
  // error naming both reasons. Each stretch starts free, so this greedy choice finds a branch wherever one exists.
  const std::size_t n = path.moves.size();
  auto is_cl = [&](std::size_t mi) {
    return path.moves[mi].tool_axis_start.has_value() || path.moves[mi].tool_axis_end.has_value();
  };
  auto switch_point = [&](std::size_t mi) { return is_cl(mi) && (mi == 0 || path.moves[mi].rapid); };
  core::Vec6 prev_end = path.initial_position;
  std::size_t mi = 0;
  while (mi < n) {
    std::size_t next = mi + 1;
    while (next < n && !switch_point(next)) ++next;
    // The stretch [mi, next) after its first move `first`.
    auto stretch = [&](core::Move first) {
      std::vector<core::Move> moves;
      moves.reserve(next - mi);
      moves.push_back(std::move(first));
      for (std::size_t j = mi + 1; j < next; ++j) moves.push_back(convert(j, moves.back().end, std::nullopt));
      return moves;
    };
    std::vector<core::Move> done;
    if (!switch_point(mi)) {
      done = stretch(convert(mi, prev_end, std::nullopt));
    } else {
      const core::Move& pm = path.moves[mi];
      const ChainKinematics& k = kin();
      const Eigen::Vector3d a0 = (pm.tool_axis_start ? *pm.tool_axis_start : *pm.tool_axis_end).normalized();
      const Eigen::Vector3d a1 = (pm.tool_axis_end ? *pm.tool_axis_end : *pm.tool_axis_start).normalized();
      // The branches at the stretch's start (first move) or at the rapid's end, the present one first.
      std::vector<std::string> errors, reasons;
      std::vector<Eigen::VectorXd> branches;
      try {
        branches =
            mi == 0 ? k.solutions(ToolPose{pm.start.head<3>(), a0}, pm.tool_length_offset_mm, to_q(prev_end), reasons)
                    : k.solutions(ToolPose{pm.end.head<3>(), a1}, pm.tool_length_offset_mm, to_q(prev_end), reasons);
      } catch (const core::Error&) {
        branches.clear();  // convert() below names the problem with its line
      }
      if (mi > 0) {
        try {
          done = stretch(convert(mi, prev_end, std::nullopt));
        } catch (const core::Error& e) {
          errors.push_back(e.what());
        }
      }
      for (std::size_t b = 0; done.empty() && b < branches.size(); ++b) {
        try {
          if (mi == 0) {
            done = stretch(convert(mi, prev_end, branches[b]));
          } else {
            // The rapid to this branch: straight in axis space.
            core::Move m = pm;
            m.kind = core::MotionKind::Line;
            m.rotation = 0;
            m.centre_mm.setZero();
            m.via.clear();
            m.via_s.clear();
            m.start = prev_end;
            m.end = to_v6(branches[b], pm.end);
            set_gains(k, m, to_q);
            done = stretch(std::move(m));
          }
        } catch (const core::Error& e) {
          errors.push_back(e.what());
        }
      }
      if (done.empty()) {
        if (errors.empty()) {
          done = stretch(convert(mi, prev_end, std::nullopt));  // no branch at all: convert() names the reason
        } else if (errors.size() == 1) {
          throw core::Error(errors.front());
        } else {
          const std::string to =
              next < n ? fmt::format("line {}", path.moves[next - 1].source_line) : std::string("the end");
          throw core::Error(core::located(
              path.source_path, pm.source_line,
              fmt::format("no solution branch of the inverse keeps the axes within their travels and continuous from "
                          "here to {}: on the branch the axes are on: {}; on the other branch: {}",
                          to, errors.front(), errors.back())));
        }
      }
    }
    if (mi == 0 && (is_cl(0) || path.moves[0].tcp)) out.initial_position = done.front().start;
    for (std::size_t j = 0; j < done.size(); ++j) out.moves[mi + j] = std::move(done[j]);
    prev_end = out.moves[next - 1].end;
    mi = next;
  }
  return out;
}

}  // namespace

void Kinematics::forward_rows(const Eigen::Ref<const Eigen::MatrixXd>& axes,
                              const Eigen::Ref<const Eigen::VectorXd>& tlo, Eigen::Ref<Eigen::MatrixXd> tip,
                              Eigen::Ref<Eigen::MatrixXd> axis) const {
  require_rows(axes.rows(), axes.cols(), static_cast<std::size_t>(axes.cols()), tlo.size(), tip.rows(), tip.cols(),
               axis.rows(), axis.cols());
  Eigen::VectorXd q(axes.cols());
  for (Eigen::Index k = 0; k < axes.rows(); ++k) {
    q = axes.row(k).transpose();
    const ToolPose p = forward(q, tlo[k]);
    tip.row(k) = p.tip_mm.transpose();
    if (axis.size() > 0) axis.row(k) = p.axis.transpose();
  }
}

void Kinematics::tip_velocity_rows(const Eigen::Ref<const Eigen::MatrixXd>& axes,
                                   const Eigen::Ref<const Eigen::MatrixXd>& velocities,
                                   const Eigen::Ref<const Eigen::VectorXd>& tlo,
                                   Eigen::Ref<Eigen::MatrixXd> out) const {
  require_rows(axes.rows(), axes.cols(), static_cast<std::size_t>(axes.cols()), tlo.size(), out.rows(), out.cols());
  if (velocities.rows() != axes.rows() || velocities.cols() != axes.cols())
    throw core::Error(fmt::format("kinematics: {} x {} axis velocities for {} x {} axis positions", velocities.rows(),
                                  velocities.cols(), axes.rows(), axes.cols()));
  Eigen::VectorXd q(axes.cols()), qd(axes.cols());
  for (Eigen::Index k = 0; k < axes.rows(); ++k) {
    q = axes.row(k).transpose();
    qd = velocities.row(k).transpose();
    out.row(k) = tip_velocity(q, qd, tlo[k]).transpose();
  }
}

std::unique_ptr<Kinematics> make_kinematics(const core::Machine& machine) {
  if (machine.kinematics == "chain") return std::make_unique<ChainKinematics>(machine);
  require_xyz(machine);
  return std::make_unique<CartesianXyz>(machine);
}

core::Vec6 axes_from_tip(const core::Vec6& tip, double tool_length_offset_mm, const core::Machine& machine) {
  require_xyz(machine);
  core::Vec6 a = tip;
  a[core::kZ] += tool_length_offset_mm;
  return a;
}

core::Vec6 tip_from_axes(const core::Vec6& axes, double tool_length_offset_mm, const core::Machine& machine) {
  require_xyz(machine);
  core::Vec6 t = axes;
  t[core::kZ] -= tool_length_offset_mm;
  return t;
}

core::ToolPath toolpath_in_axis_space(const core::ToolPath& path, const core::Machine& machine,
                                      const AxisSpaceOptions& options) {
  if (machine.kinematics == "chain") return chain_toolpath(path, machine, options);
  require_xyz(machine);
  core::ToolPath out = path;
  out.initial_position = axes_from_tip(path.initial_position, 0.0, machine);
  for (core::Move& m : out.moves) {
    const double tlo = m.tool_length_offset_mm;
    m.start = axes_from_tip(m.start, tlo, machine);
    m.end = axes_from_tip(m.end, tlo, machine);
    // Arc centres are in the plane's coordinates; Z is the first of ZX and the second of YZ.
    if (m.kind == core::MotionKind::Arc) {
      if (m.plane == core::ArcPlane::ZX) m.centre_mm[0] += tlo;
      if (m.plane == core::ArcPlane::YZ) m.centre_mm[1] += tlo;
    }
    m.tool_length_offset_mm = 0.0;
  }
  return out;
}

}  // namespace vmsim::motion
