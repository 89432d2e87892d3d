#include "sim/motion_stream.hpp"

#include "core/error.hpp"
#include "core/huge_pages.hpp"
#include "core/timing.hpp"
#include "motion/kinematics.hpp"
#include "sim/axis_following.hpp"
#include "sim/tool_poses.hpp"
#include "sim/tools.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

namespace vmsim::sim {

namespace {

using core::Clock;
using core::seconds_since;

// The track's tool axis, block by block: constant while every block's is the first block's, bit for bit, and the
// rotary axes hold the first row's positions (pose_track_from_axes' test over the whole motion); otherwise per row.
struct TrackAxes {
  bool constant = true;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  std::vector<std::pair<Eigen::Index, Eigen::Vector3d>> constant_blocks;  // (first row, axis) of each constant block
  std::vector<std::pair<Eigen::Index, Eigen::MatrixXd>> turning_blocks;   // (first row, axes) of the others
};

}  // namespace

MotionStream stream_actual_motion(const Chain& chain, Motion& m, const StreamOptions& options,
                                  core::Progress& progress) {
  const core::Job& job = chain.job();
  const core::Machine& machine = job.machine;
  MotionStream out;
  read_and_interpolate(chain, core::RemovalSpec::Motion::Actual, m, progress);

  const auto t0 = Clock::now();
  progress.stage(job.name + ": servo drives");
  core::Setpoints& sp = m.interp.setpoints;
  const Eigen::Index ns = sp.samples();
  sp.path_length_mm.resize(0);  // nothing in a run reads it: 8 B per setpoint less while the drives run
  DriveBlocks drives = chain.simulate_in_blocks(sp);
  const Eigen::Index rows = drives.sim->rows();
  const auto kin = motion::make_kinematics(machine);
  if (options.figures) {
    out.signals.emplace(job, m.program, sp, rows, options.feed_scale);
    out.command_tip_mm.resize(rows, 3);
    core::advise_huge_pages(out.command_tip_mm);
  }
  removal::PoseTrack& tr = out.track;
  tr.period_s = sp.period_s;
  tr.tip_mm.resize(rows, 3);
  tr.tip_velocity_mm_per_s.resize(rows, 3);
  core::advise_huge_pages(tr.tip_mm);
  core::advise_huge_pages(tr.tip_velocity_mm_per_s);
  TrackAxes axes;
  const Eigen::RowVectorXd first = sp.position.row(0);
  const auto tlo = [&](Eigen::Index k) { return tlo_at(m, k); };
  AxisFollowing following(machine, std::min(ns, rows), kin.get(), tlo);
  // Each row's tool poses computed once (forward_rows) and shared: the track, the signals, the following error and
  // the contour error's command all take them, as they would have from their own forward() calls.
  Eigen::VectorXd tlo_rows;
  Eigen::MatrixXd command_axis, actual_axis, held;
  while (!drives.sim->done()) {
    const Eigen::Index k0 = drives.sim->next_row();
    const drives::AxisResponse block = drives.sim->next(options.block_rows);
    const Eigen::Index n = block.samples();
    tlo_rows.resize(n);
    for (Eigen::Index r = 0; r < n; ++r) tlo_rows[r] = tlo(k0 + r);
    // The track's rows, as pose_track_from_axes gives them on the block, written in place.
    actual_axis.resize(n, 3);
    kin->forward_rows(block.position, tlo_rows, tr.tip_mm.middleRows(k0, n), actual_axis);
    kin->tip_velocity_rows(block.position, block.velocity, tlo_rows, tr.tip_velocity_mm_per_s.middleRows(k0, n));
    // The block's tool axis is constant when its rotary axes hold still (bitwise) and every pose's axis is the first's
    // (pose_track_from_axes' test; an empty block counts as constant, as its empty per-row axes did).
    const bool axis_constant = tool_axis_constant(machine, block.position, actual_axis);
    const Eigen::Vector3d block_axis =
        n > 0 ? Eigen::Vector3d(actual_axis.row(0).transpose()) : Eigen::Vector3d(Eigen::Vector3d::UnitZ());
    bool block_constant = axis_constant;
    for (std::size_t i = 0; block_constant && i < machine.axes.size(); ++i)
      if (machine.axes[i].kind == core::AxisKind::Rotary)
        block_constant =
            (block.position.col(static_cast<Eigen::Index>(i)).array() == first[static_cast<Eigen::Index>(i)]).all();
    if (k0 == 0) axes.axis = block_axis;
    if (!axis_constant) {
      axes.turning_blocks.emplace_back(k0, actual_axis);
    } else {
      axes.constant_blocks.emplace_back(k0, block_axis);
      block_constant = block_constant && block_axis == axes.axis;
    }
    axes.constant = axes.constant && block_constant;
    drives.after->add(k0, sp, block);
    if (options.figures) {
      // The commanded poses: the setpoint each row holds (the last one while the axes settle).
      const Eigen::Index nc = std::clamp<Eigen::Index>(ns - k0, 0, n);
      command_axis.resize(n, 3);
      if (nc > 0)
        kin->forward_rows(sp.position.middleRows(k0, nc), tlo_rows.head(nc), out.command_tip_mm.middleRows(k0, nc),
                          command_axis.topRows(nc));
      if (nc < n) {
        held = sp.position.row(ns - 1).replicate(n - nc, 1);
        kin->forward_rows(held, tlo_rows.tail(n - nc), out.command_tip_mm.middleRows(k0 + nc, n - nc),
                          command_axis.bottomRows(n - nc));
      }
      out.signals->add(k0, block, tr.tip_mm.middleRows(k0, n), out.command_tip_mm.middleRows(k0, n));
      following.add(k0, sp, block.position, command_axis, actual_axis);
    }
  }
  if (axes.constant) {
    tr.axis = axes.axis;
  } else {
    tr.axis_per_sample.resize(rows, 3);
    core::advise_huge_pages(tr.axis_per_sample);
    for (const auto& [k0, a] : axes.constant_blocks) {
      const Eigen::Index end = std::min(rows, k0 + options.block_rows);
      for (Eigen::Index k = k0; k < end; ++k) tr.axis_per_sample.row(k) = a.transpose();
    }
    for (const auto& [k0, a] : axes.turning_blocks) tr.axis_per_sample.middleRows(k0, a.rows()) = a;
  }
  tr.tool = sample_tools(job, m, rows);
  m.drive_checks = std::move(drives.checks);
  drives.after->finish(m.drive_checks);
  if (options.figures) m.axis_following = following.json(sp.period_s);
  drives = {};
  // The response's rows and the setpoints' positions are spent: what stays counts the setpoints and their moves.
  m.response.emplace();
  m.response->period_s = sp.period_s;
  m.response->axis_names = sp.axis_names;
  sp.position.resize(ns, 0);
  sp.path_speed_mm_per_s.resize(0);
  m.tool_length_offset_mm.resize(0);
  m.streamed = true;
  progress.done();
  m.timings["drives"] = seconds_since(t0);
  return out;
}

void finish_streamed_motion(Motion& m, MotionStream& stream, const Eigen::MatrixXd& actual_tip_mm) {
  const auto t0 = Clock::now();
  if (stream.signals) {
    // The command is released inside, once merged: it and the contour error's arrays are never held together.
    m.contour = motion::contour_error(std::move(stream.command_tip_mm), actual_tip_mm);
    stream.command_tip_mm.resize(0, 3);
    stream.signals->add_contour(*m.contour);
    m.signals = stream.signals->finish();
    stream.signals.reset();
  }
  m.timings["contour_error"] = seconds_since(t0);
}

}  // namespace vmsim::sim
