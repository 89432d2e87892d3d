#pragma once
// The identification subcommands: excite, identify (transfer functions from a position trace) and compensate (the
// predictive-compensation paper), identify-friction (friction and inertia: the feed-drive simulation paper).
// main.cpp parses the command line; each returns the exit code and throws core::Error for input a user must fix.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::app {

struct ExciteArgs {
  std::string axis;  // X Y Z A B C
  std::filesystem::path machine;
  std::filesystem::path out;         // .ngc (G-code) or .csv (setpoints every Te)
  std::string signal = "inverse-m";  // inverse-m | prbs
  std::optional<int> bits;           // register length n (default: from resolution_hz)
  double resolution_hz = 1.0;        // frequency resolution 1 / signal period (eq. 11-12)
  double bandwidth_hz = 100.0;       // the axis bandwidth the signal must cover (eq. 14-15)
  std::optional<double> td_ms;       // Td, overrides bandwidth_hz
  double amplitude = 0.05;           // mm or deg
  double feed = 1200.0;              // superimposed constant velocity, mm/min or deg/min (0: none)
  int periods = 4;
  std::optional<double> start;                    // mm or deg (default: centred in the travel)
  double period_ms = 1.0;                         // Te
  std::optional<std::filesystem::path> simulate;  // also run it on the machine's drive: a position trace CSV
};
int run_excite(const ExciteArgs& args);

struct IdentifyArgs {
  // Position trace CSVs (sysid/position_trace.hpp); several: estimation on all of them as separate experiments.
  std::vector<std::filesystem::path> traces;
  // Separate validation trace (default: with one trace its second half, with several the last one, held out).
  std::optional<std::filesystem::path> validate;
  std::vector<std::string> axes;                 // default: every axis in the trace
  std::string structure = "all";                 // arx | armax | oe | all
  std::string orders = "2,5";                    // nb,na (the predictive-compensation paper: 2,5) or auto (BIC)
  int nc = 2;                                    // ARMAX noise order
  std::string delay = "auto";                    // nk in samples, or auto (smallest ARX loss over 1..5)
  std::string use = "best";                      // structure written to the model file: best (validation MSE) or one
  std::optional<std::filesystem::path> out_dir;  // axis_models.toml, report.json
  // Traces other than CSV (sysid/trace_formats.hpp): halscope pins "AXIS=CMD_PIN,ACT_PIN", .mat variables
  // "t=VAR,command=VAR,actual=VAR[,axis=X]", their position unit (mm, m, in, deg, rad).
  std::vector<std::string> channels;
  std::optional<std::string> mat;
  std::optional<std::string> trace_unit;
  std::vector<std::string> rest_offsets;  // "AXIS=VALUE" (mm or deg): encoder - command at rest
};
// vmsim identify --trace TRACE.csv: ARX / ARMAX / OE per axis, validated, ranked (the predictive-compensation paper
// Table 2).
int run_identify(const IdentifyArgs& args);

struct IdentifyFrictionArgs {
  std::filesystem::path trace;  // CSV: t_s, current_A, position_mm|position_deg|velocity_...
  std::optional<double> torque_constant_Nm_per_A;
  std::optional<double> lead_mm, gear_deg_per_rev;
  std::optional<std::filesystem::path> machine;  // with axis: Kt, lead or gear, gravity model from the machine file
  std::optional<std::string> axis;
  std::string gravity = "auto";                  // auto | none | constant | tilting
  std::optional<double> smoothing_ms;            // IdentifyOptions::smoothing_s, in ms
  std::optional<std::filesystem::path> out_dir;  // drive_identified.toml, friction_fit.csv, report.json
  std::optional<std::string> mat;                // .mat variables "t=VAR,position=VAR|velocity=VAR,control=VAR"
  std::optional<std::string> trace_unit;         // .mat positions: mm, m, in, deg, rad
  // The trace's current column (CSV) or control variable (.mat) times this is the load-side force (N, linear axis)
  // or torque (N m, rotary axis): a controller's control signal (a voltage) instead of a motor current.
  std::optional<double> control_gain;
};
// vmsim identify-friction TRACE: Coulomb and viscous friction, gravity offset and inertia of one axis (the feed-drive
// simulation paper 3.1).
int run_identify_friction(const IdentifyFrictionArgs& args);

struct CompensateArgs {
  std::filesystem::path job;
  std::optional<std::filesystem::path> out_dir;
  std::optional<std::filesystem::path> axis_models;  // predict with these identified models (default: the job's)
  int buffer_samples = 0;                            // m of the foot-point search (0: automatic)
  int max_iterations = 6;
  double smoothing_samples = 4.0;  // Gaussian smoothing of the correction along the setpoints (sigma)
  bool tip_only = false;           // five-axis: correct the tool tip only, not the tool axis
  bool dense_program = false;      // also write compensated_dense.ngc (one G93 block per setpoint)
  bool no_render = false;          // draw no chart (images/contour_error.png)
};
// vmsim compensate JOB: predicted contour error added back to the setpoints (the predictive-compensation paper section
// 4); compensated setpoints CSV, compensated G-code, report.json with the contour error before and after.
int run_compensate(const CompensateArgs& args);

}  // namespace vmsim::app
