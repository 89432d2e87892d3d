#pragma once
// From a sampled tool motion (tool poses every Te, from the drives' actual positions, the setpoints or the
// programmed path) to the straight swept volumes the kernel removes.
//
// The motion a track stands for: between samples k and k + 1 the tip follows the chord (or, with velocities, the
// cubic Hermite curve) and the tool axis turns at a constant rate on the great circle from a_k to a_k+1 (slerp),
// both on the same parameter u in [0, 1]. Its swept volume V is the union of the tool bodies at these poses.
//
// The sweeps: straight moves at constant orientation (removal/swept_tool.hpp), each removed exactly. The removed
// volume V' differs from V by at most TrackSweeps::error_bound_mm <= TrackOptions::tolerance_mm in Hausdorff
// distance (every point of V' within that of V and vice versa), the sum of three terms:
//   e_hermite: a chord between Hermite sub-samples 1/m apart in u bows from the curve by at most |p''|max / (8 m^2)
//              (the linear-interpolation error at the same u; |p''| is largest at an end of a cubic);
//   e_merge:   samples merged into one straight sweep stay within e_merge of its chord; pairing each pose with the
//              convex combination of its neighbours' closest chord points keeps every tip within e_merge;
//   e_orient:  a sweep holds the axis at a* while the track's axis a(u) turns; with the body rotated about the tip,
//              no point of it moves by more than reach |a(u) - a*| (Tool::reach(): the farthest body point from the
//              tip, hypot(L - rc, R - rc) + rc), so e_orient = reach * max |a(u) - a*| over the sweep.
// They add: pose by pose, the sweep's body is within e_tip + e_orient of the track's body at the same u, and both
// volumes are unions over u. A sweep's axis a* is the mid-axis of its run, normalize(a_first + a_last): a sub-step
// turning by phi then has max |a(u) - a*| = 2 sin(phi / 4), so
//       e_orient(phi) = 2 reach sin(phi / 4) ~ reach phi / 2       (orientation_error_bound_mm)
// half what holding the start orientation would give, i.e. half the sub-steps. The tip's chord does not enter: the
// tip terms are separate and the orientation term is a rotation about the tip at the same u. The bound is reached
// (to within L / reach) at a track's ends, where a body turned by phi/2 from the first or last sweep's axis has no
// neighbouring sweep to cover its rim; inside a track, neighbouring sweeps turned the other way cover most of it
// (tests/removal/five_axis_test.cpp measures both).
//
// Budget: tolerance_mm is split e_hermite = e_merge = tolerance / 2 for a constant axis (3-axis motion: no
// orientation term, no extra sub-steps, the same sweeps as before per-sample axes existed), and
// e_hermite = e_merge = tolerance / 4, e_orient = tolerance / 2 when the axis turns anywhere on the track. The
// interval k is then cut into max(m_hermite, ceil(phi_k / phi_max)) sub-steps, phi_max = 4 asin(e_orient /
// (2 reach)), and merging accepts a run only while its tips stay within e_merge of the chord and its axes within
// e_orient / reach of the run's mid-axis. Cost: about (pi / 180) reach / (2 e_orient) = (pi / 180) reach / tolerance
// sweeps per degree of rotation (a 50 mm tool: 87 per degree at 10 um, 8727 at the default 0.1 um).
#include "removal/swept_tool.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <vector>

namespace vmsim::removal {

struct PoseTrack {
  double period_s = 1e-3;
  Eigen::MatrixXd tip_mm;                           // samples x 3, workpiece frame
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // tool axis when it is constant (3-axis motion)
  // Optional tool axis at each sample (samples x 3, workpiece frame, from the tip towards the spindle; need not be
  // unit, normalised here): a turning tool (5-axis motion). When given, `axis` is not used. Consecutive axes must
  // differ by less than 90 degrees (the slerp between them is then unique).
  Eigen::MatrixXd axis_per_sample;
  // Optional tip velocities (samples x 3, mm/s): between samples the tip then follows the cubic Hermite curve
  // through both samples with these velocities, not the chord.
  Eigen::MatrixXd tip_velocity_mm_per_s;
  // Optional, per sample: which tool is in the spindle (an index into the tools given to sweeps_from_track), for a
  // program that changes tools. The interval from sample k - 1 to k is cut by sample k's tool (the move that sample
  // lies on). Empty: one tool cuts the whole track.
  std::vector<int> tool;
};

struct TrackOptions {
  // Largest Hausdorff distance between the removed volume and the track's swept volume (see above for the split).
  double tolerance_mm = 1e-4;
  // Optional: a box holding all the material the track can cut (workpiece frame: the stock's bounds). The bound then
  // holds within the box (every point of V' inside it within the tolerance of V and vice versa: the removed material
  // is), and e_orient counts only the tool's engaging length: a body point within the box lies within R of an axis
  // point tip + h a within the box grown by R, so on track interval k no body point inside it is farther from the tip
  // than reach_k = min(reach(), hypot(H_k, R)), H_k the highest such h over the interval (the box grown by R + delta_k,
  // delta_k = the tip's largest move from sample k over the interval and the sweep, plus L (turn_k + e_orient / R):
  // the axis' largest move; a sweep's axis is within e_orient / reach_k <= e_orient / R of the track's). Sub-steps and
  // merging then use reach_k for reach: a tilted tool whose shank stands far above the stock needs far fewer sweeps.
  // Unset: the whole body counts (reach()).
  std::optional<Eigen::AlignedBox3d> material_box;
};

struct TrackSweeps {
  std::vector<SweptTool> sweeps;
  std::size_t points = 0;  // points of the (sub-sampled) track before merging
  // The bound the sweeps achieve: e_hermite (largest bow actually left) + e_merge (largest tip distance actually
  // left) + e_orient (orientation_error_mm). At most tolerance_mm, except when a Hermite interval would need more
  // than 1000 sub-samples (capped: the bound then says how far it is).
  double error_bound_mm = 0;
  double orientation_error_mm = 0;  // max over sweeps of reach (reach_k with a material box) * max |a(u) - a*|
  // Consecutive sweeps cut by one tool, in track order: sweeps [first, first + count) by tools[tool] (one run for a
  // single tool).
  struct Run {
    int tool = 0;
    std::size_t first = 0, count = 0;
  };
  std::vector<Run> runs;
};

// Bound on the Hausdorff distance between the volume a tool sweeps while its axis turns by phi_rad (about the tip,
// any tip motion) and the same motion at the mid-axis: 2 reach sin(phi / 4).
double orientation_error_bound_mm(const Tool& tool, double phi_rad);

// Throws core::Error for tracks whose shapes disagree, a zero or non-finite axis, an axis turning by 90 degrees or
// more between two samples, or an interval needing more than 1e6 orientation sub-steps at this tolerance.
TrackSweeps sweeps_from_track(const Tool& tool, const PoseTrack& track, const TrackOptions& options = {});

// A track cut by several tools (PoseTrack::tool): each run of samples with one tool becomes its own track, from the
// sample before the run (where the previous tool left the axes) to the run's last, and its sweeps are that tool's,
// within the same tolerance. Sweeps and runs stay in track order. Without PoseTrack::tool, tools[0] cuts it all
// (exactly the single-tool sweeps). Throws core::Error when a sample's tool index is not one of `tools`.
TrackSweeps sweeps_from_track(const std::vector<Tool>& tools, const PoseTrack& track, const TrackOptions& options = {});

}  // namespace vmsim::removal
