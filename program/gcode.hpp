#pragma once
// RS274/NGC G-code as LinuxCNC's interpreter reads it.
#include "core/toolpath.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::program {

struct GcodeOptions {
  std::optional<std::filesystem::path> tool_table;  // LinuxCNC tool table (T1 P1 Z0 D10 ;comment)
  // M codes that a machine remaps to actions without motion (boat-xyzac.ngc's M428/M429 kinematics switch).
  // Any other M code LinuxCNC does not define is an error naming the line.
  std::vector<int> no_motion_mcodes;

  // LinuxCNC's machine units (INI LINEAR_UNITS): the tool table and the offset parameters (#5211.., #5221..)
  // are in these units. vmsim's machines are metric; `rs274 -g` standalone treats its tables as inches, so
  // set this to reproduce its tool length offsets. Programs start in G21 either way, as under `rs274 -g`.
  bool inch_machine = false;
  // Where the controlled point is before the first block (mm, no offsets active). LinuxCNC starts at the origin;
  // a job's start position (core::Job::start_mm) goes here so that the program's first moves keep the axes
  // the program does not name (a first `G0 Z40` stays above the start instead of heading for X0 Y0).
  std::optional<std::array<double, 3>> start_mm;
  // Block delete switch: skip lines that start with '/'. Off, as in LinuxCNC and `rs274 -g` by default.
  bool block_delete = false;
  // Guards against endless programs, so that a runaway loop is an error naming the line ("possible endless
  // loop") within a second or two, never a hang or a memory blow-up: executed lines (loops count every pass),
  // and canonical calls beyond 16 per line of the program (what loops, subroutines and cycle repeats add; a
  // call with its Move costs about 400 bytes).
  std::uint64_t max_blocks = 20'000'000;
  std::size_t max_canon_calls = 1'000'000;
};

// One canonical machining call as `rs274 -g` prints it (without its running number), and its source line.
struct CanonCall {
  int source_line = 0;
  std::string n_word;  // "N....." when the block had no N word, else the N word padded as rs274 does
  std::string text;    // e.g. STRAIGHT_FEED(1.0000, 2.0000, 3.0000, 0.0000, 0.0000, 0.0000)
};

struct GcodeResult {
  core::ToolPath path;           // mm, rad, offsets applied (see toolpath.hpp)
  std::vector<CanonCall> canon;  // program units, offsets as separate calls, as LinuxCNC's canon layer sees them
};

// Interprets the whole program. Errors (core::Error) name the file, the line and the offending word.
GcodeResult interpret_gcode(const std::filesystem::path& program, const GcodeOptions& options = {});

// One line of `rs274 -g` output: "%5d " number, the N column padded to 7 characters, the call.
std::string format_canon_line(int number, const CanonCall& call);

inline core::ToolPath read_gcode(const std::filesystem::path& program, const GcodeOptions& options = {}) {
  return interpret_gcode(program, options).path;
}

}  // namespace vmsim::program
