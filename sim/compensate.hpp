#pragma once
// vmsim compensate as a library call: the predictive-compensation paper's contour-error compensation of a job. The
// job's setpoints (its chain, sim::Chain) are predicted with its axis models (the machine file's cascades, or the
// identified transfer functions of [job] axis_models or the option), corrected by the predicted contour error
// (methods/compensate), and written as a program a user can send to the machine (methods/compensated_program). That
// program is then read back as vmsim reads any program, re-timed by the chain's interpolator and run on the machine
// file's cascades: its contour error against the original plan, its cycle time against the original's. The command
// line writes the results to files and draws them; the Python module hands them over as arrays.
#include "core/job.hpp"
#include "core/progress.hpp"
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"
#include "methods/compensate.hpp"
#include "methods/compensated_program.hpp"
#include "motion/contour.hpp"
#include "motion/interp.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace vmsim::sim {

// The contour error of a motion against the planned tool-tip path, over the rows of the cutting (feed) moves (the
// setpoints and program the rows come from classify them): max, mean and rms of |CE|; with tool axes, the angle
// between the actual axis and the commanded one interpolated at motion::contour_error's foot point (the orientation
// part of the five-axis contour error).
struct ContourFigures {
  double max_mm = 0, mean_mm = 0, rms_mm = 0;
  double orientation_max_rad = 0, orientation_mean_rad = 0;
  bool orientation = false;
  Eigen::Index samples = 0;   // rows counted
  std::vector<char> counted;  // per row: 1 where the row is counted (a cutting move's)
  motion::ContourError ce;    // every row
  Eigen::VectorXd angle_rad;  // every row (five-axis)
};
ContourFigures contour_figures(const Eigen::MatrixXd& command_tip, const Eigen::MatrixXd& actual_tip,
                               const core::Setpoints& setpoints, const core::ToolPath& program,
                               const Eigen::MatrixXd* command_axis = nullptr,
                               const Eigen::MatrixXd* actual_axis = nullptr);

struct CompensateJobOptions {
  std::optional<std::filesystem::path> axis_models_file;  // predict with these identified models (--axis-models)
  // Buffer, iterations, smoothing, orientation (methods/compensate.hpp); `limits` is set to the job's machine (the
  // correction is faded where it would break an axis limit the setpoints kept).
  methods::CompensateOptions method;
  bool dense_program = false;  // also the dense form (one G93 block per setpoint)
};

struct CompensateJobResult {
  core::ToolPath program;                 // the job's, workpiece frame
  motion::InterpResult interp;            // its setpoints, the ones corrected
  Eigen::VectorXd tool_length_offset_mm;  // per setpoint
  methods::CompensateOptions options;     // as run
  methods::CompensationResult compensation;
  bool identified = false;  // predicted with identified axis models (then also measured on the machine's cascades)
  ContourFigures predicted_before, predicted_after;
  std::optional<ContourFigures> machine_before, machine_after;
  // The original program and the compensated one read back, re-timed and run on the machine file's cascades.
  ContourFigures original_on_machine, program_on_machine;
  std::vector<methods::AxisLimitCheck> limits_before, limits_after, limits_program;
  bool within_limits = true, program_within_limits = true;
  // The compensated program as written: compensated.<extension> when it cuts at least as well as the original on the
  // machine model (max and mean of the tip's contour error and, five-axis, of the orientation error, within 1 nm and
  // 1e-6 deg), else compensated_rejected.<extension>. Where it first cut worse, the correction it carries is faded out
  // around the places where its error exceeds the original's largest and it is written and checked again.
  methods::CompensatedProgram compensated_program;
  bool program_accepted = true;
  std::string program_file;  // compensated.<extension> or compensated_rejected.<extension>
  int fade_rounds = 0;       // rounds of fading (0: the program carries the compensated setpoints' correction whole)
  Eigen::Index faded_setpoints = 0;  // setpoints whose correction the program carries below its full value
  std::optional<methods::CompensatedProgram> tcp_program;  // compensated_tcp.ngc (five-axis CL programs, accepted)
  std::optional<std::string> original_tcp_text;            // original_tcp.ngc: the same form with no correction
  std::optional<std::string> dense_program_text;           // compensated_dense.ngc
  double cycle_time_original_s = 0, cycle_time_program_s = 0;
  std::optional<std::pair<double, double>> tcp_cycle_times_s;  // original_tcp.ngc, compensated_tcp.ngc
  // report.json's figures: prediction, method, iterations, contour_error, compensated_program, limits, setpoints (and
  // gain_schedule when the job's is not applied); the time spent: prepare, compensate, program_check.
  nlohmann::json report, timings;
};

// Throws core::Error for options out of range, a job without a program (a curve job), or as the chain and
// methods::compensate_contour do. The chain runs the drives' own gains (see the .cpp).
CompensateJobResult compensate_job(const core::Job& job, const CompensateJobOptions& options,
                                   core::Progress& progress = core::no_progress());

}  // namespace vmsim::sim
