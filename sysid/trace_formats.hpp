#pragma once
// The servo traces vmsim reads, in one place: what `vmsim identify` (command and encoder position per axis) and
// `vmsim identify-friction` (position or velocity and the torque-producing signal of one axis) take from the files
// users bring. The format is chosen by content, then extension:
//   LinuxCNC halscope log  first line "Sampling period is N nSec", then one sample per line as `pin value` pairs
//                          ("(null)" for an unused channel); the trailing line halscope writes with every value zero
//                          is dropped. Time: k N ns. Channels chosen by pin name (TraceChannels::pins).
//   MATLAB .mat            v5 (and v7.3 where libmatio reads HDF5), read through libmatio; vectors named by the user
//                          (TraceChannels::variables: t, command, actual, position, velocity, control).
//   CSV (anything else)    vmsim's own trace files (sysid/position_trace.hpp, sysid/friction_inertia.hpp).
// halscope and .mat files carry no units: positions are in TraceChannels::unit (mm, m, in, deg, rad), converted to
// mm or rad here.
#include "sysid/friction_inertia.hpp"
#include "sysid/position_trace.hpp"

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::sysid {

enum class TraceFormat { Csv, Halscope, Mat };
const char* trace_format_name(TraceFormat f);  // "csv", "halscope", "mat"
// By content (a halscope header, the MAT-file text header "MATLAB 5.0 MAT-file" or "MATLAB 7.3 MAT-file"), then by
// extension (.mat); CSV otherwise. Throws core::Error when the file cannot be opened.
TraceFormat detect_trace_format(const std::filesystem::path& path);

// One axis's command and encoder channels of a halscope log, by pin name.
struct PinPair {
  std::string axis;     // X Y Z A B C
  std::string command;  // e.g. joint.0.motor-pos-cmd
  std::string actual;   // e.g. hm2_7i76e.0.encoder.02.position or joint.0.motor-pos-fb
};

struct TraceChannels {
  // halscope: the pairs to read; empty: every joint.N.motor-pos-cmd in the log as axis "XYZABC"[N] (trivial
  // kinematics' joint order) with joint.N.motor-pos-fb, else the log's one encoder position pin (*encoder*.position).
  std::vector<PinPair> pins;
  // .mat: role -> variable name. Roles: t (time, s), command, actual (identify), position or velocity, control
  // (identify-friction); axis -> the axis name (default X).
  std::map<std::string, std::string> variables;
  std::optional<std::string> unit;  // mm, m, in (linear) or deg, rad (rotary); default mm
};

// "AXIS=CMD_PIN,ACT_PIN" (the --channel option). Throws core::Error saying what was expected.
PinPair parse_pin_pair(const std::string& spec);
// "role=name,role=name,..." (the --mat option). Throws core::Error for a malformed item or a role given twice.
std::map<std::string, std::string> parse_mat_variables(const std::string& spec);

// A position trace from any of the formats (the CSV reader for CSV: channels must then be empty). Throws core::Error
// naming the file (and line) for anything malformed, and for a pin or variable that is missing, listing those present.
PositionTrace read_position_trace(const std::filesystem::path& path, const TraceChannels& channels = {});

// An axis trace (identify-friction) from a .mat file (roles t, position or velocity, control) or a CSV file.
AxisTrace read_axis_trace(const std::filesystem::path& path, const TraceChannels& channels = {},
                          std::vector<std::string>* ignored = nullptr);

// The reader's parts, for tests: a halscope log as a table of pins (the sampling period and each pin's samples).
struct HalscopeLog {
  std::string source;
  double period_s = 0.0;
  std::vector<std::string> pins;            // in the order of the first sample line, "(null)" left out
  std::vector<std::vector<double>> values;  // per pin, per sample
  int first_sample_line = 0;                // the file line of sample 0
  bool dropped_zero_line = false;           // the trailing all-zero line was dropped
};
HalscopeLog read_halscope_log(const std::filesystem::path& path);

// One numeric vector of a .mat file as doubles (any real numeric class; a 1 x n or n x 1 array). Throws core::Error
// naming the file and variable, listing the variables present when it is missing.
std::vector<double> read_mat_vector(const std::filesystem::path& path, const std::string& variable);
// The names of the file's variables.
std::vector<std::string> mat_variable_names(const std::filesystem::path& path);

}  // namespace vmsim::sysid
