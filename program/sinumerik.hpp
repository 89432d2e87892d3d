#pragma once
// Siemens SINUMERIK 840D sl part programs as CAM post-processors write them (NX, ...): the reader.
//
// What it reads (README.md "Programs"): ';' comments, N block numbers, labels with GOTOF/GOTOB/GOTO/GOTOC,
// IF/ELSE/ENDIF and WHILE/ENDWHILE, DEF REAL/INT/BOOL variables and R parameters with expressions, MSG(),
// G0/G1/G2/G3 (I J K centres, CR= radii, TURN= helix turns), AC()/IC(), G17-G19, G90/G91, G70/G71/G700/G710,
// G500/G54..G57/G505..G599, G53/SUPA, G60/G9/G64/G641/G642, SOFT/BRISK, FFWON/FFWOF, COMP*, tool calls
// (T="name"/Tn, M6, D), S, M3/M4/M5, M7/M8/M9, TRANS/ATRANS/ROT/AROT frames, TRAORI/TRAFOOF, CYCLE800 (swivel plane),
// CYCLE832 (high-speed settings), CYCLE81/CYCLE82/CYCLE83 drilling (also as MCALL), M0/M1/M2/M30/M17/RET.
// A statement it does not know is an error naming the file, the line and the word; with `lenient`, statements known
// to have no motion (unknown M and H functions, a few NC commands without path effect) become warnings.
//
// The ToolPath it gives: moves in the workpiece frame (the settable zero G54..; its offset is the controller's and not
// in the program, so it is taken as zero: workpiece zero = machine zero). Under TRAORI (and under a CYCLE800 swivel
// frame) the moves are tool-centre-point moves (Move::tcp): X Y Z the tool tip in the workpiece frame, where the
// programmable frame puts the programmed point, and B C (A) the rotary axes as programmed, so the machine's kinematics
// give the tool axis. Otherwise the moves are the machine's axes (joint programming), X Y Z through the active frame.
// SUPA blocks are machine positions. Tool lengths (D) live in the controller's tool offsets: the controlled point is
// the tool tip (tool_length_offset_mm = 0).
#include "core/toolpath.hpp"
#include "program/gcode.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace vmsim::program {

// What the reader needs of the machine's kinematics where programming switches between joint and tool-centre-point
// moves (TRAORI, TRAFOOF) and where CYCLE800 turns the rotary axes to a swivelled plane. Without it (vmsim canon, a
// bare read), the reader takes the identity (tip = axes), which is exact while the rotary axes stand at zero.
class MachineTransform {
 public:
  virtual ~MachineTransform() = default;
  // Tool tip in the workpiece frame with the axes at `joint` (X Y Z mm, A B C rad: a joint move's coordinates).
  virtual Eigen::Vector3d tip_of_joint(const core::Vec6& joint) const = 0;
  // The joint coordinates that put the tip at tcp's X Y Z with the rotary axes at tcp's A B C.
  virtual core::Vec6 joint_of_tip(const core::Vec6& tcp) const = 0;
  // Rotary axis positions (A B C, rad) that turn the tool axis to `tool_axis` (workpiece frame), the solution
  // nearest to the axes at `near` (joint coordinates).
  virtual Eigen::Vector3d rotary_for_tool_axis(const Eigen::Vector3d& tool_axis, const core::Vec6& near) const = 0;
};

struct SinumerikOptions {
  // Statements known to have no motion that vmsim does not model become warnings instead of errors.
  bool lenient = false;
  // M functions the machine's maker defines without motion (coolant, chip conveyor, ...): accepted silently.
  std::vector<int> no_motion_mcodes;
  // Where the tool tip is before the first block (workpiece frame, mm); the origin otherwise.
  std::optional<std::array<double, 3>> start_mm;
  const MachineTransform* machine = nullptr;
  // Arcs in a plane the workpiece frame has no name for (a frame turned by 45 deg): chords within this distance.
  double arc_chord_tolerance_mm = 1e-3;
  std::uint64_t max_blocks = 20'000'000;  // executed blocks (a GOTOB loop counts every pass)
  std::size_t max_canon_calls = 5'000'000;
};

// An interpolation setting the program makes (CYCLE832, G60/G64/G642, SOFT/BRISK, FFWON/FFWOF), in program order.
struct InterpSetting {
  int source_line = 0;
  std::string what;                    // "CYCLE832 finishing", "G642", "SOFT", "FFWON", ...
  std::optional<double> tolerance_mm;  // CYCLE832's contour tolerance
};

struct SinumerikStats {
  int lines = 0;             // lines of the file
  std::uint64_t blocks = 0;  // blocks executed (jumps and loops count every pass)
  int rapid_blocks = 0;      // G0 blocks with motion
  int linear_blocks = 0;     // G1 blocks with motion
  int arc_blocks = 0;        // G2/G3 blocks
  int cycle_calls = 0;       // drilling cycle executions
  int tool_changes = 0;      // M6
  int frame_statements = 0;  // TRANS/ATRANS/ROT/AROT
  int tcp_moves = 0;         // ToolPath moves under TRAORI / CYCLE800
  int chorded_arcs = 0;      // arcs in an oblique plane, given as chords
};

struct SinumerikResult {
  core::ToolPath path;
  std::vector<CanonCall> canon;       // LinuxCNC's canonical-call vocabulary, workpiece frame, mm and degrees
  std::vector<std::string> warnings;  // lenient: what was accepted without being modelled, "file:line: ..."
  std::vector<std::string> tools;     // T="name" in order of first call; tool number = index + 1
  std::vector<InterpSetting> interp_settings;
  // The smallest CYCLE832 contour tolerance in force during a feed move: the interpolation tolerance the program asks
  // for (a job that gives none in [interpolation] uses it). Empty when no feed move runs under CYCLE832.
  std::optional<double> contour_tolerance_mm;
  SinumerikStats stats;
};

SinumerikResult interpret_sinumerik(const std::filesystem::path& program, const SinumerikOptions& options = {});
// The same for text in memory; `name` stands for the file in messages.
SinumerikResult interpret_sinumerik_text(std::string_view text, const std::string& name,
                                         const SinumerikOptions& options = {});

// Whether the text looks like an 840D program (used when the extension does not say).
bool looks_like_sinumerik_program(std::string_view text);

}  // namespace vmsim::program
