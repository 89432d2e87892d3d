#pragma once
// A position trace: what the NC logs while an axis runs (the interpolator's command and the encoder's position every
// Te), the input of `vmsim identify`. `vmsim motion` writes one (trace.csv), and so does `vmsim excite --simulate`.
//
// CSV format: optional '#' comment lines, a header row, then one row per sample, comma-separated:
//   t_s, then per axis <AXIS>_command_<unit>, <AXIS>_actual_<unit>   (unit: mm for X Y Z, deg for A B C)
// Columns in any order; every axis needs both its columns; t_s strictly increasing. Unknown columns are errors.
// Other formats (LinuxCNC halscope logs, MATLAB .mat files) are read into the same struct by sysid/trace_formats.hpp.
//
// Sampling. Identification assumes a fixed period Te. Real time stamps jitter (a logger's clock, time stored in
// single precision): a trace whose every step is within kJitterTolerance of the mean step is taken as sampled at the
// mean step (max_jitter_s says how far off it was); one whose steps vary more is resampled onto the mean step by
// linear interpolation (resampled = true), which the commands report.
#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::sysid {

struct PositionTrace {
  std::string source;  // file name, for messages
  double period_s = 1e-3;
  Eigen::ArrayXd t_s;
  std::vector<std::string> axes;                  // axis names in column order
  std::vector<bool> rotary;                       // the file gave degrees (converted to rad here)
  Eigen::MatrixXd command, actual;                // samples x axes, axis units (mm, rad)
  double max_jitter_s = 0.0;                      // largest |step - period_s| of the time stamps as read
  bool resampled = false;                         // the jitter exceeded kJitterTolerance: resampled onto period_s
  int axis_index(const std::string& name) const;  // -1 when absent
};

inline constexpr double kJitterTolerance = 0.01;  // of the period

// Sets period_s, max_jitter_s and resampled from t_s, resampling when needed (see above). Throws core::Error naming
// trace.source (and the line, from `lines`: the file line of each sample, when given) for time stamps that do not
// increase or fewer than 2 samples.
void regularise_sampling(PositionTrace& trace, const std::vector<int>& lines = {});

// Throws core::Error naming the file and line (and column) for anything malformed.
PositionTrace read_position_trace_csv(const std::filesystem::path& path);
// Written atomically.
void write_position_trace_csv(const std::filesystem::path& path, const PositionTrace& trace,
                              const std::vector<std::string>& comment_lines = {});

}  // namespace vmsim::sysid
