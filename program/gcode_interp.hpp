#pragma once
// The RS274/NGC block executor (internal to the G-code reader).
//
// It follows LinuxCNC 2.9's interpreter (rs274ngc: execute_block, convert_g, convert_m, convert_stop, the
// canned cycles of interp_cycles.cc) so that its canonical calls match what `rs274 -g` prints, and it builds
// the ToolPath from the same motions with the work offsets folded in.
//
// Flow: gcode_lexer reads the lines once; run() walks them (O-word control flow jumps between line indices
// matched once by build_flow()); each ordinary line is evaluated into a Block (expressions, then parameter
// settings) and executed in LinuxCNC's order; motions go to the CanonWriter (text, program units) and to
// the ToolPath (mm, rad, offsets applied).
#include "program/gcode.hpp"
#include "program/gcode_lexer.hpp"
#include "program/tool_table.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <utility>
#include <string>
#include <unordered_map>
#include <vector>

namespace vmsim::program::gcode {

using Pos = std::array<double, 6>;  // X Y Z (program units) A B C (degrees), in the active coordinate system

enum class Plane : std::uint8_t { XY, XZ, YZ };  // G17, G18, G19 (canon names)
enum class ControlMode : std::uint8_t { ExactPath, ExactStop, Continuous };

std::string fmt_num(double v);  // "%.10g", for messages

inline constexpr int kNumParams = 5602;  // LinuxCNC's RS274NGC_MAX_PARAMETERS: #1 .. #5601
inline constexpr int kMaxCallDepth = 200;

// Canonical calls as text, one per call, each tagged with the line that made it.
class CanonWriter {
 public:
  CanonWriter(std::size_t max_calls, std::string file) : max_calls_(max_calls), file_(std::move(file)) {}
  void set_line(int source_line, const std::string& n_word) {
    line_ = source_line;
    n_word_ = &n_word;
  }
  void no_line() {
    line_ = 0;
    n_word_ = &kNoN;
  }
  void print(const char* format, ...) __attribute__((format(printf, 2, 3)));
  // The frequent calls, formatted with std::to_chars (the same digits as printf's "%.4f", several times faster).
  void axes_call(const char* name, const double* values, int n);
  void arc_call(const double* plane4, int rotation, const double* rest4);
  void push(std::string text);
  std::vector<CanonCall> take() { return std::move(calls_); }
  std::size_t remaining() const { return max_calls_ - calls_.size(); }
  void reserve(std::size_t n) { calls_.reserve(n); }
  std::size_t size() const { return calls_.size(); }

 private:
  static const std::string kNoN;
  std::size_t max_calls_;
  std::string file_;
  int line_ = 0;
  const std::string* n_word_ = &kNoN;
  std::vector<CanonCall> calls_;
};

// One line's words after evaluation, with LinuxCNC's modal-group bookkeeping.
struct Block {
  static constexpr int kMaxCodes = 16;  // each G code needs its own modal group, so 16 is more than enough
  std::array<double, 26> value{};
  std::uint32_t present = 0;             // bit (letter - 'A')
  std::array<int, 16> g_mode;            // modal group -> G code x10, -1 = none
  std::array<int, 11> m_mode;            // M modal group -> M code, -1 = none
  std::array<int, kMaxCodes> g_codes{};  // x10, as written
  std::array<int, kMaxCodes> m_codes{};
  int n_g = 0, n_m = 0;
  bool no_motion_m = false;  // a remapped no-motion M code is in the block
  int motion = -1;           // the motion this block makes (G code x10), -1 = none

  Block() {
    g_mode.fill(-1);
    m_mode.fill(-1);
  }
  bool has(char letter) const { return (present >> (letter - 'A')) & 1u; }
  double operator[](char letter) const { return value[static_cast<std::size_t>(letter - 'A')]; }
  bool has_axis() const { return has('X') || has('Y') || has('Z') || has('A') || has('B') || has('C'); }
};

class Interpreter final : public ParamSource {
 public:
  Interpreter(const ParsedProgram& program, std::string file, const GcodeOptions& options, const ToolTable* tools);
  GcodeResult run();

  // ParamSource
  double numbered(double index) const override;
  double named(int name_id) const override;
  bool exists(int name_id) const override;

 private:
  struct Frame {
    int sub_line = -1;     // the "sub" line (-1 for the main program)
    int return_line = -1;  // where execution resumes after the call
    std::array<double, 30> saved_args{};
    std::unordered_map<int, double> locals;          // named parameters without a leading '_'
    std::unordered_map<int, long long> repeat_left;  // repeat line -> remaining passes
  };

  // ---- control flow (gcode_flow.cpp)
  void build_flow();
  std::size_t exec_oword(std::size_t idx);
  bool eval_condition(std::size_t idx);

  // ---- blocks (gcode_interp.cpp)
  Block read_block(const SourceLine& line);
  void apply_assignments(const SourceLine& line);
  bool execute_block(Block& b);  // true at program end (M2, M30)
  void check_codes(Block& b);
  void comment(const std::string& text);
  void feed_mode(int g);
  void select_tool(const Block& b);
  void m_codes(const Block& b);
  void g_codes(Block& b);
  bool stop(const Block& b);
  void set_plane(int g);
  void length_units(int g);
  void tool_length_offset(int g, const Block& b);
  void coordinate_system(int g);
  void control_mode(int g, const Block& b);
  void setup_g10(const Block& b);
  void axis_offsets(int g, const Block& b);
  void save_home(int g);
  void emit_control_mode(ControlMode mode, double tolerance);

  // ---- motion (gcode_motion.cpp)
  void motion(int g, Block& b);
  Pos find_ends(const Block& b) const;
  void straight(int g, const Block& b);
  void arc(int g, const Block& b);
  void cycle(int g, Block& b);
  void home(int g, const Block& b);
  void traverse_to(const Pos& end);
  void feed_to(const Pos& end);
  void record_line(bool rapid, const Pos& end);
  void record_arc(const Pos& end, Plane plane, double c1, double c2, int turn);
  void start_move(core::Move& m, const Pos& end);  // start, end, tool data, source line
  void set_inverse_time_rate(double length);

  // ---- geometry and units
  double to_user_len(double v) const;      // program units -> machine units (tool table, #5xxx)
  double from_user_len(double v) const;    // machine units -> program units
  core::Vec6 machine(const Pos& p) const;  // ToolPath frame: mm, rad, work offsets applied
  void current_in_system(int system, Pos& out) const;
  static void rotate(double& x, double& y, double deg);
  const ToolEntry* tool_entry(int number, const char* what) const;
  double tool_offset_prog(const ToolEntry* t, int axis) const;

  [[noreturn]] void fail(const std::string& message) const;
  std::string g_name(int g10) const;

  // ---- inputs
  const ParsedProgram& prog_;
  std::string file_;
  GcodeOptions options_;
  const ToolTable* tools_;
  std::vector<std::uint8_t> predef_;  // by name id: which predefined parameter (#<_x>, ...), 0 = none

  // ---- control flow
  std::vector<int> match_;
  std::vector<std::uint8_t> do_end_;
  std::vector<std::string> flow_error_;
  long first_flow_error_ = -1;  // line index of the O-word error to report
  std::unordered_map<std::string, std::size_t> subs_;
  std::size_t end_line_ = 0;    // lines from here on are not part of the program
  std::size_t first_line_ = 0;  // after an opening '%'
  bool percent_mode_ = false;
  std::vector<Frame> frames_;
  std::size_t line_ = 0;  // index of the executing line
  std::uint64_t blocks_ = 0;

  // ---- parameters
  std::vector<double> params_;
  std::vector<std::optional<double>> globals_;
  int value_id_ = -1, value_returned_id_ = -1;  // #<_value>, #<_value_returned>

  // ---- modal state (LinuxCNC's setup_struct, program units)
  Pos pos_{};
  bool inch_ = false;
  Plane plane_ = Plane::XY;
  bool absolute_ = true;
  bool ijk_absolute_ = false;
  bool inverse_time_ = false;
  double feed_rate_ = 0.0;  // program units/min (deg/min); under G93 the last computed rate
  double speed_ = 0.0;
  int motion_mode_ = 800;        // G80
  bool retract_r_plane_ = true;  // LinuxCNC starts in G99
  int origin_index_ = 1;
  Pos origin_offset_{};       // G54..G59.3
  Pos axis_offset_{};         // G92 / G52
  double rotation_xy_ = 0.0;  // degrees
  Pos tool_offset_{};         // G43 (x y z a b c)
  int current_tool_ = 0;      // in the spindle
  int selected_tool_ = 0;     // last T word
  ControlMode control_ = ControlMode::Continuous;
  double control_tolerance_ = 0.0;
  double naivecam_tolerance_ = 0.0;
  bool mist_ = false, flood_ = false;
  bool feed_override_ = true, speed_override_ = true;
  int spindle_ = 0;  // 1 cw, -1 ccw, 0 stopped
  // canned cycles
  double cycle_r_ = 0, cycle_cc_ = 0, cycle_p_ = 0, cycle_q_ = 0, cycle_il_ = 0;
  bool cycle_il_flag_ = false;
  double block_f_ = 0;  // F word of the executing block (inverse time)
  bool tlo_active_ = false;
  // Physical feed LinuxCNC's canon layer holds after SET_FEED_RATE: unit changes (G20/G21) do not alter it.
  double feed_linear_mm_ = 0.0;    // mm/min
  double feed_angular_deg_ = 0.0;  // deg/min, for moves of the rotary axes only

  // ---- output
  CanonWriter canon_;
  core::ToolPath path_;
  // Where the controlled point physically is (ToolPath frame) and the tool length offset it is measured
  // with. Moves start here, not at the interpreter's idea of the position: the two differ where LinuxCNC's
  // bookkeeping is not exact (G10 L2 with an XY rotation while G92 is active), and the machine does not jump.
  core::Vec6 tip_ = core::Vec6::Zero();
  double tip_tlo_mm_ = 0.0;
  bool diameter_from_feed_ = false;
};

}  // namespace vmsim::program::gcode
