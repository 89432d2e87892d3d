#include "sim/tool_poses.hpp"

#include "core/arc.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <Eigen/Geometry>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

namespace vmsim::sim {

namespace {

using core::units::kPi;

// Machine-file-order axis vector from program-axis (Vec6) positions.
Eigen::VectorXd machine_axes(const core::Vec6& v, const core::Machine& machine) {
  Eigen::VectorXd q(static_cast<Eigen::Index>(machine.axes.size()));
  for (std::size_t i = 0; i < machine.axes.size(); ++i)
    q[static_cast<Eigen::Index>(i)] = v[machine.axes[i].program_axis];
  return q;
}

// Position (all six program axes) at parameter s of a move: lines linear, arcs by their frame (core/arc). The ends are
// returned exactly.
core::Vec6 on_move(const core::Move& mv, const std::optional<core::ArcFrame>& arc, double s) {
  if (arc) return arc->point_at(s);
  if (s <= 0) return mv.start;
  if (s >= 1) return mv.end;
  return mv.start + s * (mv.end - mv.start);
}

Eigen::Vector3d slerp(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double s) {
  const double th = std::atan2(a.cross(b).norm(), a.dot(b));
  if (th < 1e-12) return ((1 - s) * a + s * b).normalized();
  if (th > kPi - 1e-9)
    throw core::Error(
        "the tool axis turns by 180 degrees within one CL move: the great circle between them is not unique");
  return ((std::sin((1 - s) * th) / std::sin(th)) * a + (std::sin(s * th) / std::sin(th)) * b).normalized();
}

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

}  // namespace

bool program_turns_tool(const core::ToolPath& program) {
  for (const core::Move& mv : program.moves) {
    if (mv.tool_axis_start || mv.tool_axis_end) return true;
    for (int a = core::kA; a <= core::kC; ++a)
      if (mv.start[a] != 0 || mv.end[a] != 0) return true;
  }
  return false;
}

bool tool_axis_constant(const core::Machine& machine, const Eigen::MatrixXd& axes, const Eigen::MatrixXd& axis_rows) {
  bool constant = true;
  for (std::size_t i = 0; constant && axes.rows() > 0 && i < machine.axes.size(); ++i) {
    if (machine.axes[i].kind != core::AxisKind::Rotary) continue;
    const auto c = static_cast<Eigen::Index>(i);
    constant = (axes.col(c).array() == axes(0, c)).all();
  }
  for (Eigen::Index k = 1; constant && k < axis_rows.rows(); ++k) constant = axis_rows.row(k) == axis_rows.row(0);
  return constant;
}

removal::PoseTrack pose_track_from_axes(const motion::Kinematics& kin, const core::Machine& machine,
                                        const Eigen::MatrixXd& axes, const Eigen::MatrixXd* velocities, double period_s,
                                        const std::function<double(Eigen::Index)>& tool_length_offset) {
  removal::PoseTrack tr;
  const Eigen::Index n = axes.rows();
  tr.period_s = period_s;
  tr.tip_mm.resize(n, 3);
  Eigen::MatrixXd ax(n, 3);
  Eigen::VectorXd tlo(n);
  for (Eigen::Index k = 0; k < n; ++k) tlo[k] = tool_length_offset(k);
  kin.forward_rows(axes, tlo, tr.tip_mm, ax);
  if (n > 0 && tool_axis_constant(machine, axes, ax)) {
    if (n > 0) tr.axis = ax.row(0).transpose();
  } else {
    tr.axis_per_sample = std::move(ax);
  }
  if (velocities) {
    if (velocities->rows() != n || velocities->cols() != axes.cols())
      throw core::Error(fmt::format("tool poses: {} x {} axis velocities for {} x {} axis positions",
                                    velocities->rows(), velocities->cols(), n, axes.cols()));
    tr.tip_velocity_mm_per_s.resize(n, 3);
    kin.tip_velocity_rows(axes, *velocities, tlo, tr.tip_velocity_mm_per_s);
  }
  return tr;
}

removal::PoseTrack program_pose_track(const core::ToolPath& program, const core::ToolPath& axis_space,
                                      const motion::Kinematics& kin, const core::Machine& machine,
                                      const removal::Tool& tool, double tolerance_mm) {
  return program_pose_track(program, axis_space, kin, machine, std::vector<removal::Tool>{tool}, {}, tolerance_mm);
}

removal::PoseTrack program_pose_track(const core::ToolPath& program, const core::ToolPath& axis_space,
                                      const motion::Kinematics& kin, const core::Machine& machine,
                                      const std::vector<removal::Tool>& tools, const std::vector<int>& move_tool,
                                      double tolerance_mm, std::vector<int>* pose_move) {
  if (!(tolerance_mm > 0)) throw core::Error("tool poses: the tolerance must be > 0");
  if (axis_space.moves.size() != program.moves.size())
    throw core::Error(fmt::format("tool poses: {} axis-space moves for {} program moves", axis_space.moves.size(),
                                  program.moves.size()));
  if (tools.empty()) throw core::Error("tool poses: no tool");
  if (!move_tool.empty() && move_tool.size() != program.moves.size())
    throw core::Error(
        fmt::format("tool poses: {} move tools for {} program moves", move_tool.size(), program.moves.size()));
  for (int t : move_tool)
    if (t < 0 || static_cast<std::size_t>(t) >= tools.size())
      throw core::Error(fmt::format("tool poses: tool index {} of {} tools", t, tools.size()));
  constexpr double kMaxTurn = 5 * kPi / 180, kMaxRotary = 10 * kPi / 180;
  std::vector<Eigen::Vector3d> tips, axes;
  std::vector<int> moves_of;
  for (std::size_t m = 0; m < program.moves.size(); ++m) {
    const core::Move& mv = program.moves[m];
    // Each move is sampled for the tool that cuts it (the error bound counts its reach).
    const double reach = tools[move_tool.empty() ? 0 : static_cast<std::size_t>(move_tool[m])].reach();
    const core::Move& am = axis_space.moves[m];
    const bool cl = mv.tool_axis_start.has_value() && mv.tool_axis_end.has_value();
    std::optional<core::ArcFrame> arc, aarc;
    if (mv.kind == core::MotionKind::Arc) arc = core::arc_frame(mv, program.source_path);
    if (am.kind == core::MotionKind::Arc) aarc = core::arc_frame(am, axis_space.source_path);
    // The swept angle of the arc the poses follow (the program's, or the axis-space move's for joint programming).
    const std::optional<core::ArcFrame>& followed = cl || mv.tcp ? arc : aarc;
    const double arc_sweep = followed ? std::abs(followed->sweep_rad) : 0.0;
    // The pose at s and the rotary axes there (program axes A B C, rad).
    auto pose = [&](double s, Eigen::Vector3d& rot) -> motion::ToolPose {
      if (cl) {
        const core::Vec6 p = on_move(mv, arc, s);
        rot = p.tail<3>();
        return motion::ToolPose{p.head<3>(),
                                slerp(mv.tool_axis_start->normalized(), mv.tool_axis_end->normalized(), s)};
      }
      if (mv.tcp) {
        const core::Vec6 p = on_move(mv, arc, s);
        rot = p.tail<3>();
        motion::ToolPose tp = kin.forward(machine_axes(p, machine), mv.tool_length_offset_mm);
        tp.tip_mm = p.head<3>();
        return tp;
      }
      const core::Vec6 a = on_move(am, aarc, s);
      rot = a.tail<3>();
      return kin.forward(machine_axes(a, machine), am.tool_length_offset_mm);
    };
    struct Piece {
      double s0, s1;
      motion::ToolPose p0, p1;
      Eigen::Vector3d r0, r1;
      int depth;
    };
    Eigen::Vector3d r0, r1;
    const motion::ToolPose first = pose(0, r0), last = pose(1, r1);
    if (tips.empty()) {
      tips.push_back(first.tip_mm);
      axes.push_back(first.axis.normalized());
      moves_of.push_back(static_cast<int>(m));
    }
    // Depth-first bisection, left piece first, so the points come out in order.
    std::vector<Piece> stack{{0, 1, first, last, r0, r1, 0}};
    while (!stack.empty()) {
      Piece pc = stack.back();
      stack.pop_back();
      const double sm = 0.5 * (pc.s0 + pc.s1);
      Eigen::Vector3d rm;
      const motion::ToolPose pm = pose(sm, rm);
      const Eigen::Vector3d a0 = pc.p0.axis.normalized(), a1 = pc.p1.axis.normalized();
      const double turn = angle_between(a0, a1);
      const double err = (pm.tip_mm - 0.5 * (pc.p0.tip_mm + pc.p1.tip_mm)).norm() +
                         reach * (pm.axis.normalized() - (a0 + a1).normalized()).norm();
      // A piece of an arc spanning more than half a turn is split whatever its midpoint says (the midpoint of whole
      // turns is the ends' point: a full circle of two turns would be cut as nothing).
      const bool split =
          pc.depth < 40 && (err > tolerance_mm || turn > kMaxTurn ||
                            (pc.r1 - pc.r0).cwiseAbs().maxCoeff() > kMaxRotary || (pc.s1 - pc.s0) * arc_sweep > kPi);
      if (split) {
        stack.push_back({sm, pc.s1, pm, pc.p1, rm, pc.r1, pc.depth + 1});
        stack.push_back({pc.s0, sm, pc.p0, pm, pc.r0, rm, pc.depth + 1});
        continue;
      }
      tips.push_back(pc.p1.tip_mm);
      axes.push_back(a1);
      moves_of.push_back(static_cast<int>(m));
    }
  }
  removal::PoseTrack tr;
  if (!move_tool.empty()) {
    tr.tool.reserve(moves_of.size());
    for (int m : moves_of) tr.tool.push_back(move_tool[static_cast<std::size_t>(m)]);
  }
  if (pose_move) *pose_move = std::move(moves_of);
  const auto n = static_cast<Eigen::Index>(tips.size());
  tr.tip_mm.resize(n, 3);
  tr.axis_per_sample.resize(n, 3);
  for (Eigen::Index k = 0; k < n; ++k) {
    tr.tip_mm.row(k) = tips[static_cast<std::size_t>(k)].transpose();
    tr.axis_per_sample.row(k) = axes[static_cast<std::size_t>(k)].transpose();
  }
  return tr;
}

}  // namespace vmsim::sim
