#pragma once
// A position trace: what the NC logs while an axis runs (the interpolator's command and the encoder's position every
// Te), the input of `vmsim identify`. `vmsim motion` writes one (trace.csv), and so does `vmsim excite --simulate`.
//
// CSV format: optional '#' comment lines, a header row, then one row per sample, comma-separated:
//   t_s, then per axis <AXIS>_command_<unit>, <AXIS>_actual_<unit>   (unit: mm for X Y Z, deg for A B C)
// Columns in any order; every axis needs both its columns; t_s strictly increasing at a constant period (within
// 1e-6 of it: identification assumes a fixed Te). Unknown columns are errors.
#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::sysid {

struct PositionTrace {
  std::string source;                 // file name, for messages
  double period_s = 1e-3;
  Eigen::ArrayXd t_s;
  std::vector<std::string> axes;      // axis names in column order
  std::vector<bool> rotary;           // the file gave degrees (converted to rad here)
  Eigen::MatrixXd command, actual;    // samples x axes, axis units (mm, rad)
  int axis_index(const std::string& name) const;  // -1 when absent
};

// Throws core::Error naming the file and line (and column) for anything malformed.
PositionTrace read_position_trace_csv(const std::filesystem::path& path);
// Written atomically.
void write_position_trace_csv(const std::filesystem::path& path, const PositionTrace& trace,
                              const std::vector<std::string>& comment_lines = {});

}  // namespace vmsim::sysid
