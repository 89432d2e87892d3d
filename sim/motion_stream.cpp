#include "sim/motion_stream.hpp"

#include "core/error.hpp"
#include "core/timing.hpp"
#include "core/units.hpp"
#include "motion/kinematics.hpp"
#include "sim/job_program.hpp"
#include "sim/tool_poses.hpp"
#include "sim/tools.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace vmsim::sim {

namespace {

using core::Clock;
using core::seconds_since;

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

namespace {

// sim/axis_following.hpp's figures, row by row: per axis the largest |setpoint - actual| (its first row on a tie)
// and the RMS (summed as Eigen sums the whole column), and the tool axis's angle.
class FollowingFigures {
 public:
  FollowingFigures(const core::Machine& machine, Eigen::Index setpoints) : machine_(&machine), n_(setpoints) {
    axes_.resize(machine.axes.size());
  }
  void add(Eigen::Index k0, const core::Setpoints& sp, const drives::AxisResponse& resp, const motion::Kinematics& kin,
           const Motion& m) {
    const double to_deg = 180 / core::units::kPi;
    const Eigen::Index end = std::min(n_, k0 + resp.samples());
    for (std::size_t i = 0; i < axes_.size(); ++i) {
      const auto c = static_cast<Eigen::Index>(i);
      const double scale = machine_->axes[i].kind == core::AxisKind::Rotary ? to_deg : 1.0;
      Axis& a = axes_[i];
      for (Eigen::Index k = k0; k < end; ++k) {
        const double e = (sp.position(k, c) - resp.position(k - k0, c)) * scale;
        const double ae = std::abs(e);
        if (k == 0 || ae > a.max) a.max = ae, a.at = k;
        a.sum2.add(e * e);
      }
    }
    for (Eigen::Index k = k0; k < end; ++k) {
      const double tlo = tlo_at(m, k);
      const Eigen::Vector3d a = kin.forward(sp.position.row(k).transpose(), tlo).axis;
      const Eigen::Vector3d b = kin.forward(resp.position.row(k - k0).transpose(), tlo).axis;
      const double ang = std::atan2(a.cross(b).norm(), a.dot(b)) * to_deg;
      tool_max_ = std::max(tool_max_, ang);
      tool_ss_ += ang * ang;
    }
  }
  nlohmann::json json(double period_s) const {
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
    out["tool_axis"] = {{"max_angle_deg", tool_max_}, {"rms_angle_deg", std::sqrt(tool_ss_ / static_cast<double>(n_))}};
    return out;
  }

 private:
  struct Axis {
    double max = 0;
    Eigen::Index at = 0;
    EigenOrderSum sum2;
  };
  const core::Machine* machine_;
  Eigen::Index n_;
  std::vector<Axis> axes_;
  double tool_max_ = 0, tool_ss_ = 0;
};

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
  auto t0 = Clock::now();
  m.program = read_job_program(job);
  (void)move_tools(job, m.program);  // a tool the job does not describe fails here, before any motion is computed
  m.timings["read_program"] = seconds_since(t0);
  t0 = Clock::now();
  progress.stage(job.name + ": interpolation");
  m.interp = chain.interpolate(m.program);
  progress.done();
  m.timings["interpolate"] = seconds_since(t0);

  t0 = Clock::now();
  progress.stage(job.name + ": servo drives");
  core::Setpoints& sp = m.interp.setpoints;
  const Eigen::Index ns = sp.samples();
  DriveBlocks drives = chain.simulate_in_blocks(sp);
  const Eigen::Index rows = drives.sim->rows();
  const auto kin = motion::make_kinematics(machine);
  if (options.figures) {
    out.signals.emplace(job, m.program, sp, rows, options.feed_scale);
    out.command_tip_mm.resize(rows, 3);
  }
  FollowingFigures following(machine, std::min(ns, rows));
  removal::PoseTrack& tr = out.track;
  tr.period_s = sp.period_s;
  tr.tip_mm.resize(rows, 3);
  tr.tip_velocity_mm_per_s.resize(rows, 3);
  TrackAxes axes;
  const Eigen::RowVectorXd first = sp.position.row(0);
  const auto tlo = [&](Eigen::Index k) { return tlo_at(m, k); };
  while (!drives.sim->done()) {
    const Eigen::Index k0 = drives.sim->next_row();
    const drives::AxisResponse block = drives.sim->next(options.block_rows);
    const Eigen::Index n = block.samples();
    // The track's rows: pose_track_from_axes on the block, its rows those of the whole motion.
    const removal::PoseTrack b = pose_track_from_axes(*kin, machine, block.position, &block.velocity, sp.period_s,
                                                      [&](Eigen::Index r) { return tlo(k0 + r); });
    tr.tip_mm.middleRows(k0, n) = b.tip_mm;
    tr.tip_velocity_mm_per_s.middleRows(k0, n) = b.tip_velocity_mm_per_s;
    bool block_constant = b.axis_per_sample.rows() == 0;
    for (std::size_t i = 0; block_constant && i < machine.axes.size(); ++i)
      if (machine.axes[i].kind == core::AxisKind::Rotary)
        block_constant =
            (block.position.col(static_cast<Eigen::Index>(i)).array() == first[static_cast<Eigen::Index>(i)]).all();
    if (k0 == 0) axes.axis = b.axis_per_sample.rows() ? Eigen::Vector3d(b.axis_per_sample.row(0)) : b.axis;
    if (b.axis_per_sample.rows()) {
      axes.turning_blocks.emplace_back(k0, b.axis_per_sample);
    } else {
      axes.constant_blocks.emplace_back(k0, b.axis);
      block_constant = block_constant && b.axis == axes.axis;
    }
    axes.constant = axes.constant && block_constant;
    drives.after->add(k0, sp, block);
    if (options.figures) {
      out.signals->add(k0, block);
      following.add(k0, sp, block, *kin, m);
      for (Eigen::Index r = 0; r < n; ++r) {
        const Eigen::Index k = k0 + r;
        out.command_tip_mm.row(k) =
            kin->forward(sp.position.row(std::min(k, ns - 1)).transpose(), tlo(k)).tip_mm.transpose();
      }
    }
  }
  if (axes.constant) {
    tr.axis = axes.axis;
  } else {
    tr.axis_per_sample.resize(rows, 3);
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
  sp.path_length_mm.resize(0);
  m.tool_length_offset_mm.resize(0);
  m.streamed = true;
  progress.done();
  m.timings["drives"] = seconds_since(t0);
  return out;
}

void finish_streamed_motion(Motion& m, MotionStream& stream, const Eigen::MatrixXd& actual_tip_mm) {
  const auto t0 = Clock::now();
  if (stream.signals) {
    m.contour = motion::contour_error(stream.command_tip_mm, actual_tip_mm);
    stream.command_tip_mm.resize(0, 3);
    stream.signals->add_contour(*m.contour);
    m.signals = stream.signals->finish();
    stream.signals.reset();
  }
  m.timings["contour_error"] = seconds_since(t0);
}

}  // namespace vmsim::sim
