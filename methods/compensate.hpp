#pragma once
// Predictive contour-error compensation (the predictive-compensation paper section 4): predict where the axes really go
// for the planned setpoints (with any AxisModel: the physical cascade or an identified transfer function), transform to
// the workpiece through the machine's kinematics, find each predicted point's foot on the planned path by the two-step
// search (nearest command point in a buffer of length m, then the adjacent segment, eq. 18-22), and move each setpoint
// by the predicted contour error found at its place on the path (eq. 23). Repeated on the compensated setpoints while
// the predicted error still falls: the contour error stays measured against the planned (original) path.
// Five-axis machines (chains with rotary joints): the tool axis too. The predicted tool axis is compared with the
// commanded tool axis at the same foot point (the orientation part of the five-axis contour error), and the corrected
// pose (tip + tip error, axis + orientation error) goes back to the joints through the chain's closed-form inverse,
// not its Jacobian: the inverse is exact for any size of correction (the rotary axes lag by degrees where the tables
// turn fast, far beyond a first-order step), keeps the rotary angles continuous through its `near` argument, and
// needs no pseudo-inverse of the 6 x 5 pose Jacobian (the tool axis has two degrees of freedom, not three).
#include "motion/kinematics.hpp"
#include "core/machine.hpp"
#include "core/setpoints.hpp"

#include <Eigen/Core>

#include <functional>
#include <string>
#include <vector>

namespace vmsim::methods {

// The predictive-compensation paper's foot-point search. command_tip: ns x 3, actual_tip: rows x 3 (rows >= ns:
// settling rows compare with the last command point's neighbourhood). buffer_samples m (odd; <= 0: 2 n + 1 with n from
// the largest distance between a predicted point and its command point, in command steps, plus a margin).
struct FootPoints {
  Eigen::MatrixXd error;      // rows x 3: foot point - actual point (the contour error vector, eq. 23's Pc->Pn)
  Eigen::VectorXd norm_mm;    // |error|
  Eigen::VectorXd parameter;  // foot's place on the command polyline: segment index + fraction (0 .. ns - 1)
  int buffer_samples = 0;     // m used
};
FootPoints find_foot_points(const Eigen::MatrixXd& command_tip, const Eigen::MatrixXd& actual_tip, int buffer_samples);

// The commanded tool axis at places on the command polyline (segment index + fraction, as FootPoints::parameter):
// normalised linear interpolation between the two setpoints' axes (they differ by far less than a degree per Te).
Eigen::MatrixXd axes_at(const Eigen::MatrixXd& command_axis, const Eigen::VectorXd& parameter);

// Angle (rad) between unit tool axes, row by row.
Eigen::VectorXd axis_angles(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b);

struct CompensateOptions {
  int buffer_samples = 0;         // m of the foot-point search (<= 0: automatic, see FootPoints)
  int max_iterations = 6;         // predictions of compensated setpoints after the first
  double min_improvement = 0.01;  // continue while the mean predicted contour error falls by more than this fraction
  // The correction is smoothed along the setpoints by a Gaussian of this standard deviation (samples; 0: none). The
  // foot points lie on the chords between setpoints, whose sag (h^2 / 8R, ~0.02 um at 0.05 mm steps on R 20 mm)
  // ripples from sample to sample: invisible in position, but its third difference over Te = 1 ms is tens of m/s^3.
  double smoothing_samples = 4.0;
  // Axis limits (velocity, acceleration, jerk of the setpoints by backward differences, as core::finite_difference_
  // peaks): where the corrected setpoints break one that the setpoints they correct kept, the correction is faded
  // out around that sample (halved over +-limit_window_samples, smoothed, up to limit_passes times, then removed
  // there). Off: the correction is applied whatever it asks of the axes (the report still says where it breaks one).
  const core::Machine* limits = nullptr;
  int limit_window_samples = 25;
  int limit_passes = 12;
  // Five-axis machines: correct the tool axis as well (its predicted orientation error at the foot point); a
  // correction is accepted only when the mean orientation error does not grow either. Ignored on machines whose tool
  // axis never turns (KinematicFamily::Cartesian).
  bool orientation = true;
};

// The problem in the machine's terms: setpoints (axis units), the kinematics and each setpoint's tool length offset
// (for the tool tip), and the prediction: axis setpoints (ns x axes) to actual axis positions (rows x axes, rows >=
// ns, row k at the instant setpoint k is sent, as drives/simulate).
struct CompensationProblem {
  const core::Setpoints* setpoints = nullptr;
  const motion::Kinematics* kinematics = nullptr;
  Eigen::VectorXd tool_length_offset_mm;  // per setpoint (empty: 0)
  std::function<Eigen::MatrixXd(const Eigen::MatrixXd& axis_setpoints)> predict;
};

struct CompensationIteration {
  double max_mm = 0.0,
         mean_mm = 0.0;  // predicted contour error over every row (the predictive-compensation paper's search)
  double orientation_max_rad = 0.0, orientation_mean_rad = 0.0;  // tool axis vs the commanded one at the foot point
  bool accepted = false;
  int faded_samples = 0;  // setpoints where the axis limits held the correction below its full value
};

struct CompensationResult {
  Eigen::MatrixXd setpoints;         // compensated axis setpoints, ns x axes
  Eigen::MatrixXd predicted_before;  // actual axes for the original setpoints
  Eigen::MatrixXd predicted_after;   // actual axes for the compensated ones
  Eigen::MatrixXd command_tip;       // the planned tool-tip path (workpiece frame), ns x 3
  Eigen::MatrixXd command_axis;      // the planned tool axis (workpiece frame, unit), ns x 3
  bool orientation = false;          // the tool axis was corrected too (a five-axis chain with the option on)
  std::vector<CompensationIteration> iterations;  // [0]: the original setpoints
  int buffer_samples = 0;
};

// Throws core::Error when the prediction does not return rows x axes with rows >= ns, or non-finite positions.
CompensationResult compensate_contour(const CompensationProblem& problem, const CompensateOptions& options = {});

// Tool tips of axis rows (rows beyond the offsets take the last offset).
Eigen::MatrixXd tool_tips(const motion::Kinematics& kin, const Eigen::MatrixXd& axes, const Eigen::VectorXd& tlo_mm);
// Tool axes (unit, workpiece frame) of axis rows.
Eigen::MatrixXd tool_axes(const motion::Kinematics& kin, const Eigen::MatrixXd& axes, const Eigen::VectorXd& tlo_mm);

// Where setpoints exceed an axis's velocity, acceleration or jerk limit (backward differences as the drives receive
// them, at rest before and after, as core::finite_difference_peaks), per axis.
struct AxisLimitCheck {
  std::string axis;
  double peak_velocity = 0, peak_acceleration = 0, peak_jerk = 0;  // axis units / s^n
  double limit_velocity = 0, limit_acceleration = 0, limit_jerk = 0;
  int samples_over = 0;        // samples where any of the three exceeds its limit (relative margin 1e-6)
  double first_over_s = -1.0;  // time of the first such sample (-1: none)
  bool within() const { return samples_over == 0; }
};
std::vector<AxisLimitCheck> check_axis_limits(const Eigen::MatrixXd& setpoints, double period_s,
                                              const core::Machine& machine);

}  // namespace vmsim::methods
