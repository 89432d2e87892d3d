#pragma once
// Identification of an axis drive's friction law and inertia from a measured trace (the feed-drive simulation paper
// section 3.1).
//
// The model is the mechanics of the cascade drive (drives/cascade_axis), the feed-drive simulation paper eq. 1 at the
// motor shaft:
//     J dw/dt = Kt i - Tc sign(w) - B w - T_gravity
// (a) At constant velocity dw/dt = 0, so the current is the friction law: i = (Tc/Kt) sign(v) + (B/Kt) w
//     (+ T_gravity/Kt). The trace is cut into constant-velocity stretches; each gives one point (mean velocity,
//     mean current) of the feed-drive simulation paper Fig. 3, and a linear least-squares fit through the points gives
//     Tc, B and gravity.
// (b) Where the axis accelerates, eq. 2: J = Kt (i - i_friction(v)) / (dw/dt), solved by least squares over the
//     accelerating samples with the friction law of (a).
//
// Gravity (vertical or tilting axes) is told apart from Coulomb friction by the asymmetry between the two
// directions: Coulomb friction changes sign with the velocity, gravity does not. At +v and -v the mean currents
// are g + c + b v and g - c - b v, so their half-sum is the gravity current g and their half-difference the
// friction. The fit therefore needs constant-velocity moves both ways whenever it estimates gravity.
//
// Units: axis units are mm (linear) or rad (rotary), as everywhere inside vmsim; motor-side values are SI.
#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::sysid {

// One axis' measured trace. Either position or velocity (or both) is given; velocity is derived from position by
// central differences when absent. The current must be sampled fast enough to show its mean: in a cascade the
// position loop changes the velocity command once per Te and the velocity loop answers within that period, so the
// current has a sawtooth at Te and a trace sampled once per Te sees the same phase of it every time (in the
// cascade model, the end-of-period current is 40 % below the period mean during accelerations). Use the drive's
// servo trace at the current- or velocity-loop period, or a current averaged over each period.
struct AxisTrace {
  Eigen::ArrayXd t_s;        // strictly increasing
  Eigen::ArrayXd position;   // axis units (mm or rad), or empty
  Eigen::ArrayXd velocity;   // axis units/s, or empty
  Eigen::ArrayXd current_A;  // motor (torque-producing) current
  bool rotary = false;       // the file gave degrees
  std::string source;        // file name, for messages
};

// Reads a trace CSV: an optional block of '#' comment lines, a header row naming the columns, then one row per
// sample. Columns (any order): t_s, current_A, and exactly one of position_mm, position_deg, velocity_mm_per_s,
// velocity_deg_per_s (degrees are converted to rad). Other columns are ignored (their names are returned in
// `ignored`). Throws core::Error naming the file, line and column for anything else.
AxisTrace read_axis_trace_csv(const std::filesystem::path& path, std::vector<std::string>* ignored = nullptr);

enum class GravityModel {
  Auto,      // constant offset when the trace has constant-velocity moves both ways, none otherwise
  None,      // horizontal axis
  Constant,  // vertical axis: T_gravity constant
  Tilting,   // tilting table: T_gravity = G sin(angle - offset); needs positions
};
const char* gravity_model_name(GravityModel g);  // "auto", "none", "constant", "tilting"

struct IdentifyOptions {
  double torque_constant_Nm_per_A = 0.0;  // Kt (> 0): from the motor's data sheet, not identifiable from currents
  double axis_per_motor_rad = 0.0;        // screw lead / 2 pi (mm/rad), or gear ratio (rad/rad); > 0
  GravityModel gravity = GravityModel::Auto;
  // Differentiation. V_k, the mean velocity over [t_{k-h}, t_{k+h}], is the positions' difference over that
  // window (or the mean of the velocity column); the acceleration is A_k = (V_{k+h} - V_{k-h}) / (t_{k+h} -
  // t_{k-h}), i.e. the true acceleration averaged twice by the window. Eq. 2 is then applied to the current,
  // velocity and gravity terms averaged twice by the same window (trapezoidal rule), so the equation holds for the
  // smoothed signals as it does for the raw ones: the smoothing adds no bias, it only suppresses the noise of the
  // differentiated position. smoothing_s is the window length 2 h dt (dt: the median sample period, h >= 1):
  // 10 ms is h = 5 at Te = 1 ms and h = 80 at 62.5 us. Constant-velocity stretches are found on A_k and V_k too.
  double smoothing_s = 0.01;
  // Constant velocity: |mean acceleration| <= steady_accel_fraction x the trace's peak |acceleration|.
  double steady_accel_fraction = 0.02;
  // Accelerating: |mean acceleration| >= accel_fraction x the peak.
  double accel_fraction = 0.2;
  // Samples slower than this fraction of the peak |velocity| are left out of both fits: near zero speed the
  // friction is static (stick-slip), not the sliding law being identified.
  double min_speed_fraction = 0.005;
  double min_stretch_s = 0.1;  // shortest usable constant-velocity stretch, after trimming
  double trim_s = 0.02;        // dropped at both ends of each stretch (the loops settling)
};

// One constant-velocity stretch: a point of the feed-drive simulation paper Fig. 3.
struct FrictionPoint {
  double t_start_s = 0.0, t_end_s = 0.0;
  int samples = 0;
  double velocity = 0.0;          // mean, axis units/s
  double acceleration = 0.0;      // mean (v_end - v_start) / duration, axis units/s^2 (its J term is removed)
  double mean_current_A = 0.0;    // measured mean, with the inertia term J a / (Kt r) removed
  double fitted_current_A = 0.0;  // the identified law at `velocity` (and the stretch's mean gravity term)
};

struct IdentifiedDrive {
  // Friction law in motor terms and as currents.
  double coulomb_Nm = 0.0, coulomb_A = 0.0;
  double viscous_Nm_s_per_rad = 0.0;
  double viscous_A_s_per_axis_unit = 0.0;     // A per (mm/s) or per (rad/s) of axis velocity
  GravityModel gravity = GravityModel::None;  // the model fitted (Auto resolved)
  double gravity_Nm = 0.0, gravity_A = 0.0;   // constant; tilting: amplitude G
  double gravity_angle_offset_rad = 0.0;      // tilting only
  double gravity_stderr_Nm = 0.0;             // standard error of gravity_Nm from the fit
  double inertia_kg_m2 = 0.0;
  // Fit quality.
  double friction_rms_residual_A = 0.0;  // stretch means against the law
  double inertia_rms_residual_A = 0.0;   // accelerating samples against J dw/dt + friction
  int stretches = 0, stretches_positive = 0, stretches_negative = 0;
  int accel_samples = 0;
  double peak_velocity = 0.0, peak_acceleration = 0.0;  // axis units/s, /s^2
  std::vector<FrictionPoint> points;
};

// Throws core::Error (naming trace.source) when the trace cannot determine the parameters: too few stretches,
// one direction only with a gravity model, no accelerating samples, non-positive Kt or ratio.
IdentifiedDrive identify_friction_inertia(const AxisTrace& trace, const IdentifyOptions& options);

}  // namespace vmsim::sysid
