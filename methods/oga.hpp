#pragma once
// Offline gain adjustment (OGA), Duong et al.: a variable position-loop gain, computed offline from the path's
// geometry, that lowers the mean square contour error MSE(CE) of a biaxial planar profile while the axes keep
// their velocity, acceleration, jerk and current limits.
//
// The steps, as Duong et al. section III lays them out:
//  1. Admissible gains (section III.D, Fig. 7): every (Kp, KF) of a grid ([1 : 0.5 : 9] (m/min)/mm x
//     [0 : 0.1 : 1.2]) is simulated on the whole profile for each moving axis; the configurations whose motion
//     keeps the axis limits are admissible (see "What the limits are checked on" below).
//  2. The best fixed pair (section III.D): every admissible X configuration with every admissible Z one, MSE(CE)
//     of the whole profile by motion::contour_error; the least is the reference case C1.
//  3. Windows (section III.E, Fig. 8): the profile is cut where the curvature of three consecutive setpoints
//     changes kind (convex, concave, straight) and at the transitions between kinds (where the curvature ramps).
//  4. Receding windows without overlap (section III, Fig. 3). In each window, for each adjusted axis, every gain
//     amplitude A = [Kmin - K(k-1) : dK : Kmax - K(k-1)] / 2 of the gain function (eq. 3: a half sinusoid of p
//     samples from the last gain of the previous window to K(k-1) + 2A; eq. 4: then held) is a candidate (Task
//     1); each candidate is simulated to the end of the window with the nonlinear axis model (Task 2); the contour
//     error of the window is computed for every combination of the axes' candidates (Task 3); the combination
//     with the least MSE(CE) over the window is kept (Task 4). KF stays at C1's value (Duong et al.'s case C2).
//  5. Verification (section III, Fig. 4): the whole schedule through drives::simulate_axes (the nonlinear model,
//     every axis) against C1; the limits, MSE(CE), and the currents (section IV, Fig. 12).
//
// Where vmsim departs from the seed, and why:
//  - Task 2 from the state at the window start: Duong et al. re-simulates each candidate from the first instant of
//    the path. The drive's state at the window start (AxisModel::clone, with the NC's feedforward state) gives
//    the same positions bit for bit, at a fraction of the cost (OgaOptions::from_start runs the seed's way, for
//    the tests and the benchmark). Candidates are simulated and combined in parallel (OpenMP); the choice does
//    not depend on the thread count.
//  - The axes are independent in the model (the feed-drive simulation paper section 2.2), so each axis' candidates are
//  simulated once
//    and the combinations cost only their contour error.
//  - A candidate whose motion breaks a limit inside its window is not chosen (the seed checks only afterwards,
//    step 5, and then changes the window length or the range by hand). If every candidate of an axis breaks one,
//    the least violating is kept and the window says so.
//  - The candidates also include keeping the previous gain (A = 0) when the grid of eq. 3 misses it (the grid
//    starts at Kmin, so K(k-1) = 6 is not on [5 : 0.03 : 6.5]): holding is always possible, and a window is never
//    made worse than holding by the search itself.
//
// What the limits are checked on. Duong et al. checks "the kinematic constraints of the machine's axes and the
// current limitation" on the simulated axes, without saying how. vmsim checks:
//  - velocity, acceleration and jerk: per-Te backward finite differences of the actual positions (the operator
//    the interpolator's setpoints are checked with, core::finite_difference_peaks: at rest before row 0), of the
//    drive model WITHOUT its Coulomb/Stribeck friction (its "twin": same loops, delays, viscous friction,
//    gravity, saturations), against the machine's max_velocity / max_acceleration / max_jerk;
//  - current: the period peak |i| (AxisSample::current_peak_A) of the full nonlinear model against the drive's
//    current_limit_A (strictly below: at the limit the velocity loop saturates).
//  Why without friction: with it, the actual jerk of the Mikron's X axis is 41 to 97 m/s^3 on the OGA profile for
//  every configuration of the grid, Kp = 1 and KF = 0 included (the limit is 10 m/s^3): the breakaway from
//  stiction at the start and the friction torque flipping at a velocity reversal step the acceleration within
//  one current period, whatever the gains. A literal check would admit nothing, so Duong et al.'s 72 and 108
//  admissible configurations cannot come from one; the limits there judge the motion the gains shape, which is
//  what the twin isolates. The friction's own peaks are reported by the verification beside the twin's.
#include "motion/contour.hpp"
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"
#include "methods/oga_schedule.hpp"
#include "drives/simulate.hpp"

#include <Eigen/Core>

#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace vmsim::methods {

// ---- windows (Duong et al. section III.E) ---------------------------------------------------------------------------

enum class WindowKind { Straight, Convex, Concave, Transition };
const char* window_kind_name(WindowKind kind);

// Setpoint rows [begin, end): the commands whose gains one window decides.
struct Window {
  Eigen::Index begin = 0, end = 0;
  WindowKind kind = WindowKind::Straight;
};

struct WindowOptions {
  // |curvature| below this is straight (1/mm). 1e-4: radii beyond 10 m; the rounding of the setpoints' coordinates
  // gives about 1e-6 on straight moves at 3 m/min.
  double straight_curvature_per_mm = 1e-4;
  // A row is in a transition where the curvature changes faster than this along the path (1/mm^2): the blends
  // the interpolator puts where a line meets an arc or two arcs meet (0.05 to 0.3 1/mm^2 on the OGA profile at
  // 3 m/min), against ~1e-5 along an arc or a line.
  double transition_rate_per_mm2 = 0.01;
  // Three "consecutive" setpoints are taken at least this far apart (mm): near a stop the interpolator's steps
  // shrink to nanometres, where the coordinates' rounding would dominate a curvature from three points.
  double min_chord_mm = 1e-3;
  // Windows shorter than this (rows) are merged into the one before (the curvature's flicker at the end of a
  // blend, where its rate crosses the threshold back and forth).
  Eigen::Index min_rows = 3;
};

// Signed curvature (1/mm) at every row of `xyz` (rows x 3, mm) from the row and its neighbours at least
// min_chord_mm away (eq.: 2 (a x b) . n / (|a| |b| |a + b|)), positive when the path turns clockwise about n
// (for an XZ profile with n = +Y, travelling +X: turning towards -Z, convex for a part below the tool). Rows
// without such neighbours (a path shorter than 2 chords, the ends) take the nearest defined value.
Eigen::ArrayXd setpoint_curvature(const Eigen::MatrixXd& xyz, const Eigen::Vector3d& plane_normal,
                                  double min_chord_mm = 1e-3);

// The windows: runs of rows of the same kind (convex, concave, straight by the curvature's sign; transition
// where it changes faster than transition_rate_per_mm2), covering [0, rows) in order.
std::vector<Window> curvature_windows(const Eigen::MatrixXd& xyz, const Eigen::Vector3d& plane_normal,
                                      const WindowOptions& options = {});

// ---- gain function (Duong et al. eq. 3-4) ---------------------------------------------------------------------------

// p = 1 / (2 f Te), the sinusoid's length in samples (Duong et al.: f = 10 Hz, Te = 1 ms, p = 50); rounded to the
// nearest whole number. Throws core::Error below 2.
int sinusoid_samples(double frequency_hz, double te_s);

// The n gains of one window that starts after gain k_prev and aims at k_final: for i < p, eq. 3
//   K(k+i) = -A sin(2 pi f t_i) + A + K(k-1),  A = (k_final - k_prev) / 2,  t_i = p Te (1/2 + i/(p-1)),
// f = 1/(2 p Te), i.e. a half sinusoid from K(k-1) (i = 0: the first gain equals the last of the previous
// window) to k_final (i = p-1, set exactly); for i >= p, eq. 4, the last sinusoid value held. A window shorter
// than p stops part-way (its last gain is where the sinusoid got to).
void gain_function(double k_prev, double k_final, int p, Eigen::Index n, double* out);

// ---- limits of the actual motion --------------------------------------------------------------------------------

struct Peak {
  double value = 0.0;     // |signal| at its largest (axis units / s, s^2, s^3; A)
  Eigen::Index row = -1;  // response row (t = row * Te)
};
struct MotionPeaks {
  Peak velocity, acceleration, jerk;  // per-Te finite differences of the positions
  Peak current;                       // period peak |i|
};
// Which of the four limits judge a motion. Duong et al. names them all (the default); each alone shows which one
// makes the admissible sets what they are (report.json's admissible_by_limit, parts/oga_profile/README.md).
struct LimitSet {
  bool velocity = true, acceleration = true, jerk = true, current = true;
  bool all() const { return velocity && acceleration && jerk && current; }
};
// "velocity,acceleration,jerk,current" or a part of it (in that order); "none" for none.
std::string limit_set_name(const LimitSet& limits);
// From such a list (any order, comma-separated; "all" for the four). Throws core::Error naming an unknown limit.
LimitSet parse_limit_set(const std::string& text);

// max(peak / limit) over the four (those in `limits`); < 1 when every limit holds strictly (current) or is met (v, a,
// j <= limit).
double limit_ratio(const MotionPeaks& peaks, const core::MachineAxis& axis, const LimitSet& limits = {});
// "" when every limit (of `limits`) holds; else the first broken one, e.g. "jerk 10.5 m/s^3 > 10 m/s^3 at t 0.412 s".
std::string limit_violation(const MotionPeaks& peaks, const core::MachineAxis& axis, double te_s,
                            const LimitSet& limits = {});
// Finite-difference peaks of a position column (rows x 1), at rest before row 0, over rows [first, rows).
MotionPeaks finite_difference_motion_peaks(const Eigen::VectorXd& position, double te_s, Eigen::Index first = 0);

// ---- the search ---------------------------------------------------------------------------------------------------

struct AxisGains {
  double kp = 0.0;  // (m/min)/mm
  double kf = 0.0;
};

// One configuration of one axis simulated on the whole profile (Duong et al. Fig. 7).
struct ConfigCheck {
  AxisGains gains;
  MotionPeaks twin;   // velocity, acceleration, jerk of the frictionless twin; current of the full model
  MotionPeaks model;  // velocity, acceleration, jerk of the full model (friction included), for the counts; current
  bool admissible = false;
  std::string violation;  // why not
};

struct OgaOptions {
  std::vector<double> kp_grid;  // (m/min)/mm; empty: Duong et al.'s [1 : 0.5 : 9]
  // The limits that judge the configurations (step 1) and the schedule's candidates (step 4); the verification
  // (step 5) reports every limit whatever this says.
  LimitSet limits;
  std::vector<double> kf_grid;  // empty: Duong et al.'s [0 : 0.1 : 1.2]
  // C1: the best fixed pair of the search (Duong et al.'s definition), or the machine file's own gains.
  enum class Reference { Best, Machine } reference = Reference::Best;
  // Search the best fixed pair (every admissible X configuration with every Z one: the costly part of the run).
  // Off: the result has no best pair; needs reference = Machine.
  bool search_best_pair = true;
  // Kp range of the schedule per adjusted axis name ((m/min)/mm); an axis not named takes Duong et al.'s placement
  // around C1 ([Kp1 - 1, Kp1 + 0.5], i.e. [5, 6.5] around 6), within the contiguous admissible Kp at C1's KF.
  std::map<std::string, std::pair<double, double>> range;
  double gain_step = 0.03;     // dK, (m/min)/mm
  double frequency_hz = 10.0;  // f of the sinusoidal part
  double settle_s = 0.2;       // simulated after the last setpoint (the last window holds its gains over it)
  WindowOptions windows;
  bool from_start = false;  // Task 2 as Duong et al.: re-simulate every candidate from the first instant
  // Contour error of a window: computed over the window's rows with this many rows before it (the actual motion
  // already decided) so the foot-point search has converged when the window starts.
  Eigen::Index lead_in_rows = 100;
  // Per response row (setpoints + settling rows): weight of the row in MSE(CE), 1 on the contour, 0 elsewhere
  // (e.g. rapids). Empty: every row counts.
  Eigen::ArrayXd row_weight;
  std::function<void(const std::string&)> progress;  // a line per stage
  // The best-fixed-pair search spread over processes (vmsim oga under mpirun, app/cmd_oga.cpp; drives knows no MPI):
  // process `index` of `count` evaluates its contiguous share of the pairs, the others' entries left +inf, then
  // `combine` must give every process every value (an element-wise minimum over the processes: each entry is
  // finite on one process at most). Every process then holds the same values and goes on to the same result.
  struct ProcessShare {
    int index = 0, count = 1;
    std::function<void(std::vector<double>&)> combine;
  } share;
};

struct OgaWindowResult {
  Window window;
  std::vector<double> final_kp;    // per adjusted axis: the gain eq. 3 aimed at (k_final)
  std::vector<double> last_kp;     // the gain at the window's last row (= final_kp unless the window < p)
  double mse_um2 = 0.0;            // MSE(CE) over the window's rows with the chosen gains
  double hold_mse_um2 = 0.0;       // ... keeping the previous gains
  std::vector<int> candidates;     // per axis: candidates simulated
  std::vector<int> within_limits;  // per axis: those whose motion kept the limits in the window
  std::string note;                // limits broken by every candidate of an axis, if any
};

struct OgaResult {
  std::vector<int> axes;  // the adjusted machine axes (the two of X Y Z that move)
  std::vector<std::string> axis_names;
  Eigen::Vector3d plane_normal = Eigen::Vector3d::UnitY();  // of the profile's plane (the axis that does not move)
  double period_s = 1e-3;
  Eigen::Index rows = 0;  // response rows: setpoints + settling
  std::vector<double> kp_grid, kf_grid;
  std::vector<std::vector<ConfigCheck>> sweep;  // per adjusted axis: kp-major over (kp_grid, kf_grid)
  std::vector<AxisGains> best;                  // best admissible fixed pair (Duong et al. section III.D); empty when
  double best_mse_um2 = 0.0;                    // not searched or no configuration is admissible
  Eigen::Index pairs_evaluated = 0;
  std::vector<AxisGains> c1;  // reference case C1 (best or the machine's)
  double c1_mse_um2 = 0.0;
  std::vector<std::pair<double, double>> range;  // per adjusted axis, (m/min)/mm
  int sinusoid_samples = 0;                      // p
  std::vector<OgaWindowResult> windows;
  GainTable table, c1_table;                   // C2 and C1 (constant) in (m/min)/mm, the adjusted axes
  drives::GainSchedule schedule, c1_schedule;  // the same in 1/s for simulate_axes (to_gain_schedule)
  double c2_mse_um2 = 0.0;                     // MSE(CE) of C2 as the search summed it window by window
  std::map<std::string, double> timings_s;
};

// Throws core::Error for options that cannot run and for profiles OGA does not handle (not exactly two of X Y Z
// moving, a rotary axis moving, an axis without a drive, a range without C1's Kp). Setpoints: the interpolator's
// (every machine axis).
OgaResult offline_gain_adjustment(const core::Setpoints& setpoints, const core::Machine& machine,
                                  const OgaOptions& options = {});

// ---- set-up from a job's motion -----------------------------------------------------------------------------------

// OgaOptions::row_weight for a program's setpoints: 1 on the rows of feed moves (the contour, as vmsim motion's
// "cutting moves"), 0 on rapids and before the first move; the settle_s rows after the last setpoint take the last
// move's. Rows: setpoints + round(settle_s / Te).
Eigen::ArrayXd feed_move_row_weights(const core::Setpoints& setpoints, const core::ToolPath& program, double settle_s);

// A Kp range given for every adjusted axis (vmsim oga --range MIN:MAX) set on each of X Y Z whose setpoints move,
// unless `range` names that axis already (an AXIS=MIN:MAX range wins).
void set_range_of_moving_axes(const core::Setpoints& setpoints, const core::Machine& machine,
                              const std::pair<double, double>& all,
                              std::map<std::string, std::pair<double, double>>& range);

// ---- verification (Duong et al. Fig. 4, section IV)
// ------------------------------------------------------------------

struct AxisVerification {
  std::string axis;
  MotionPeaks twin_c1, twin_c2;            // checked (see "What the limits are checked on")
  MotionPeaks model_c1, model_c2;          // the full nonlinear model's finite differences, for information
  std::string violation_c1, violation_c2;  // "" when the limits hold
  // Duong et al. Fig. 12: the current reference (velocity-loop output) of C2 against C1: max |i2 - i1| over
  // max |i1|, and where.
  double current_setpoint_peak_c1_A = 0.0, current_setpoint_peak_c2_A = 0.0;
  double current_setpoint_max_diff_A = 0.0, current_setpoint_max_rel_diff = 0.0;
  Eigen::Index current_setpoint_max_diff_row = -1;
};

struct OgaVerification {
  drives::AxisResponse c1, c2;        // every machine axis, the nonlinear model
  motion::ContourError ce_c1, ce_c2;  // on the X Y Z axis positions, signed about the plane normal
  double mse_c1_um2 = 0.0, mse_c2_um2 = 0.0, max_c1_mm = 0.0, max_c2_mm = 0.0;  // over the weighted rows
  std::vector<AxisVerification> axes;                                           // the adjusted axes
  bool limits_held = true;                                                      // C2's twin and currents
  std::vector<std::string> advice;  // where a limit breaks and what to change
};

OgaVerification verify_oga(const core::Setpoints& setpoints, const core::Machine& machine, const OgaResult& result,
                           const OgaOptions& options = {});

}  // namespace vmsim::methods
