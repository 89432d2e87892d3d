#pragma once
// The 840D block executor (internal to the Sinumerik reader).
//
// Flow: sinumerik_parse reads every line once; run() walks the blocks (labels, GOTO*, IF/ELSE/ENDIF and
// WHILE/ENDWHILE jump between block indices matched once); each block executes in the 840D's order (declarations
// and assignments, then technology: F S T M6 spindle coolant, then planes, units, zero offsets, frames, the
// transformation, then the motion or the cycle, then program stops). Motions go to the canonical calls (text, mm and
// degrees, the ToolPath's coordinates) and to the ToolPath.
#include "program/gcode_interp.hpp"
#include "program/sinumerik.hpp"
#include "program/sinumerik_frames.hpp"
#include "program/sinumerik_parse.hpp"

#include <array>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

namespace vmsim::program::sinumerik {

class Executor final : public gcode::ParamSource {
 public:
  Executor(const Program& program, std::string file, const SinumerikOptions& options);
  SinumerikResult run();

  // ParamSource: R parameters and DEF variables.
  double numbered(double index) const override;
  double named(int name_id) const override;
  bool exists(int name_id) const override;

 private:
  // ---- control flow
  void match_blocks();
  std::size_t jump(const Block& b) const;
  bool execute(const Block& b);  // true at the program's end

  // ---- blocks
  double eval(ExprId e) const;
  double eval_length(ExprId e) const;  // program units -> mm
  void declare_and_assign(const Block& b);
  void technology(const Block& b);
  bool g_codes(const Block& b, int& motion, bool& supa);
  void keywords(const Block& b, bool& supa);
  void frame_statement(const Block& b);
  void set_transformation(bool on);
  void m_functions(const Block& b, bool& end);
  void not_modelled(const std::string& what);
  void call(const Call& c, bool from_mcall);

  // ---- motion
  Eigen::Vector3d programmed(const Frame& frame) const;  // current point in the frame's coordinates
  const Frame& active_frame() const { return frame_; }
  Frame total_frame() const { return swivel_.then(frame_); }
  bool motion(const Block& b, int g, bool supa);
  void line_to(bool rapid, const core::Vec6& end);
  void arc_to(const Block& b, int g, const Eigen::Vector3d& end_prog, const Eigen::Vector3d& rot_end_rad,
              const Frame& frame);
  void push_move(core::Move m);
  void emit_position(const char* name, const core::Vec6& v);

  // ---- cycles (sinumerik_cycles.cpp)
  void cycle832(const Call& c);
  void cycle800(const Call& c);
  void drilling_cycle(const Call& c);
  void drill_to(double normal_prog, bool rapid);
  double arg(const Call& c, std::size_t i, double fallback) const;
  bool has_arg(const Call& c, std::size_t i) const;
  void set_control_mode(const std::string& what, std::optional<double> tolerance_mm, bool exact);

  [[noreturn]] void fail(const std::string& message) const;
  std::string where() const;

  // ---- inputs
  const Program& prog_;
  std::string file_;
  SinumerikOptions options_;

  // ---- control flow
  std::vector<long> match_;   // IF -> ELSE/ENDIF, ELSE -> ENDIF, WHILE <-> ENDWHILE
  std::vector<long> if_end_;  // IF / ELSE -> the ENDIF that closes it
  std::vector<std::string> flow_error_;
  std::size_t index_ = 0;  // executing block

  // ---- variables
  std::vector<double> r_;  // R0 .. R999
  std::unordered_map<int, double> vars_;
  std::unordered_map<int, bool> is_int_;

  // ---- modal state
  core::Vec6 cur_ = core::Vec6::Zero();  // ToolPath coordinates of the controlled point (mm, rad)
  bool traori_ = false;
  bool swivel_active_ = false;
  bool tcp() const { return traori_ || swivel_active_; }
  Frame frame_;                   // programmable frame (TRANS/ROT/...)
  Frame swivel_;                  // CYCLE800's swivel frame
  int motion_mode_ = 0;           // G0 G1 G2 G3
  int plane_ = 17;                // G17 G18 G19
  bool absolute_ = true;          // G90
  bool inch_ = false;             // G70 / G700
  double feed_mm_per_min_ = 0.0;  // F (per minute; degrees per minute for rotary-only moves)
  int zero_offset_ = 0;           // 0 = G500, 54.., 505..
  int selected_tool_ = 0;
  int current_tool_ = 0;
  std::optional<Call> modal_call_;     // MCALL
  double contour_tolerance_mm_ = 0.0;  // CYCLE832's tolerance in force (0: none)
  std::optional<double> smallest_feed_tolerance_;

  // ---- output
  gcode::CanonWriter canon_;
  SinumerikResult result_;
  std::string n_word_;
  int line_ = 0;
};

}  // namespace vmsim::program::sinumerik
