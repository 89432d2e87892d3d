// The 840D executor: blocks, control flow, technology, frames, transformation, motion.
#include "program/sinumerik_interp.hpp"
#include "core/regular_file.hpp"

#include "core/error.hpp"
#include "core/units.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace vmsim::program::sinumerik {

namespace {

using core::units::kInchToMm;
using core::units::kDegToRad;
constexpr int kNumR = 1000;

int axis_index(char letter) {
  switch (letter) {
    case 'X':
      return 0;
    case 'Y':
      return 1;
    case 'Z':
      return 2;
    case 'A':
      return 3;
    case 'B':
      return 4;
    case 'C':
      return 5;
    default:
      return -1;
  }
}

// The plane's first, second and normal axes (G17 XY, G18 ZX, G19 YZ), as LinuxCNC's ARC_FEED orders them.
std::array<int, 3> plane_axes(int plane) {
  if (plane == 18) return {2, 0, 1};
  if (plane == 19) return {1, 2, 0};
  return {0, 1, 2};
}

// M functions with a meaning in the 840D's own numbering (Siemens, NC programming, "M functions"); M7/M8/M9 are the
// coolant functions every maker assigns the same way.
bool known_m(int m) { return m <= 9 || m == 17 || m == 30; }

std::string fmt4(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

}  // namespace

Executor::Executor(const Program& program, std::string file, const SinumerikOptions& options)
    : prog_(program),
      file_(std::move(file)),
      options_(options),
      r_(kNumR, 0.0),
      canon_(options.max_canon_calls, file_) {
  if (options_.start_mm)
    cur_.head<3>() = Eigen::Vector3d((*options_.start_mm)[0], (*options_.start_mm)[1], (*options_.start_mm)[2]);
  result_.path.source_path = file_;
  result_.path.initial_position = cur_;
  result_.stats.lines = static_cast<int>(prog_.blocks.size());
}

std::string Executor::where() const { return core::located(file_, line_, ""); }

void Executor::fail(const std::string& message) const { throw core::Error(core::located(file_, line_, message)); }

double Executor::numbered(double index) const {
  const double r = std::round(index);
  if (r < 0 || r >= kNumR)
    throw gcode::ExprError("R" + std::to_string(static_cast<long long>(r)) + " does not exist (R0 .. R999)");
  return r_[static_cast<std::size_t>(r)];
}
double Executor::named(int name_id) const {
  const auto it = vars_.find(name_id);
  if (it == vars_.end())
    throw gcode::ExprError("variable " + prog_.names.name(name_id) + " is not defined (DEF REAL/INT/BOOL)");
  return it->second;
}
bool Executor::exists(int name_id) const { return vars_.count(name_id) != 0; }

double Executor::eval(ExprId e) const {
  try {
    return prog_.exprs.evaluate(e, *this);
  } catch (const gcode::ExprError& err) {
    fail(err.what());
  }
}
double Executor::eval_length(ExprId e) const { return eval(e) * (inch_ ? kInchToMm : 1.0); }

// ---------------------------------------------------------------------------------------------------------------
// control flow

void Executor::match_blocks() {
  const std::size_t n = prog_.blocks.size();
  match_.assign(n, -1);
  if_end_.assign(n, -1);
  flow_error_.assign(n, "");
  std::vector<std::size_t> stack;
  for (std::size_t i = 0; i < n; ++i) {
    const Block& b = prog_.blocks[i];
    switch (b.control) {
      case Control::If:
      case Control::While:
        stack.push_back(i);
        break;
      case Control::Else:
        if (stack.empty() || prog_.blocks[stack.back()].control != Control::If) {
          flow_error_[i] = "ELSE without IF";
        } else {
          match_[stack.back()] = static_cast<long>(i);
          stack.back() = i;  // the ENDIF now closes the ELSE
        }
        break;
      case Control::EndIf:
        if (stack.empty() || (prog_.blocks[stack.back()].control != Control::If &&
                              prog_.blocks[stack.back()].control != Control::Else)) {
          flow_error_[i] = "ENDIF without IF";
        } else {
          if (match_[stack.back()] < 0) match_[stack.back()] = static_cast<long>(i);
          if_end_[stack.back()] = static_cast<long>(i);
          stack.pop_back();
        }
        break;
      case Control::EndWhile:
        if (stack.empty() || prog_.blocks[stack.back()].control != Control::While) {
          flow_error_[i] = "ENDWHILE without WHILE";
        } else {
          match_[stack.back()] = static_cast<long>(i);
          match_[i] = static_cast<long>(stack.back());
          stack.pop_back();
        }
        break;
      default:
        break;
    }
  }
  for (std::size_t i : stack)
    flow_error_[i] = prog_.blocks[i].control == Control::While ? "WHILE without ENDWHILE" : "IF without ENDIF";
}

// Index of the block a GOTO* goes to (labels "NAME:" and block numbers "N100").
std::size_t Executor::jump(const Block& b) const {
  auto hit = [&](std::size_t i) {
    const Block& t = prog_.blocks[i];
    return t.label == b.goto_target || t.n_word == b.goto_target;
  };
  const std::size_t n = prog_.blocks.size();
  const bool fwd = b.goto_kind != GotoKind::Backward;
  const bool back = b.goto_kind != GotoKind::Forward;
  if (fwd)
    for (std::size_t i = index_ + 1; i < n; ++i)
      if (hit(i)) return i;
  if (back)
    for (std::size_t i = index_ + 1; i-- > 0;)
      if (hit(i)) return i;
  if (b.goto_kind == GotoKind::AnyNoError) return index_ + 1;
  fail("jump target " + b.goto_target + " not found " +
       (b.goto_kind == GotoKind::Forward    ? "after this block (GOTOF)"
        : b.goto_kind == GotoKind::Backward ? "before this block (GOTOB)"
                                            : "in the program"));
}

SinumerikResult Executor::run() {
  match_blocks();
  const std::size_t n = prog_.blocks.size();
  index_ = 0;
  while (index_ < n) {
    const Block& b = prog_.blocks[index_];
    line_ = b.number;
    n_word_ = b.n_word.empty() ? "N....." : b.n_word;
    canon_.set_line(line_, n_word_);
    if (++result_.stats.blocks > options_.max_blocks)
      fail("more than " + std::to_string(options_.max_blocks) + " blocks executed: possible endless loop");
    if (!b.error.empty()) fail(b.error);
    if (!flow_error_[index_].empty()) fail(flow_error_[index_]);
    std::size_t next = index_ + 1;
    switch (b.control) {
      case Control::Goto:
        declare_and_assign(b);
        next = jump(b);
        break;
      case Control::IfGoto:
        declare_and_assign(b);
        if (eval(b.condition) != 0.0) next = jump(b);
        break;
      case Control::If:
        if (eval(b.condition) == 0.0) next = static_cast<std::size_t>(match_[index_]) + 1;  // ELSE's next, or ENDIF's
        break;
      case Control::Else:
        next = static_cast<std::size_t>(if_end_[index_]) + 1;
        break;  // the IF part ran
      case Control::While:
        if (eval(b.condition) == 0.0) next = static_cast<std::size_t>(match_[index_]) + 1;
        break;
      case Control::EndWhile:
        next = static_cast<std::size_t>(match_[index_]);
        break;
      case Control::EndIf:
        break;
      case Control::None:
        if (!b.empty && execute(b)) {
          index_ = n;
          continue;
        }
        break;
    }
    index_ = next;
  }
  canon_.no_line();
  result_.canon = canon_.take();
  result_.contour_tolerance_mm = smallest_feed_tolerance_;
  return std::move(result_);
}

// ---------------------------------------------------------------------------------------------------------------
// one block

void Executor::declare_and_assign(const Block& b) {
  for (const Declaration& d : b.declarations) {
    double v = d.init != kNoExpr ? eval(d.init) : 0.0;
    if (d.type == "INT") v = std::round(v);
    if (d.type == "BOOL") v = v != 0.0 ? 1.0 : 0.0;
    vars_[d.name] = v;
    is_int_[d.name] = d.type != "REAL";
  }
  for (const Assignment& a : b.assignments) {
    const double v = eval(a.value);
    if (a.name >= 0) {
      if (!vars_.count(a.name)) fail(a.text + "=...: variable " + a.text + " is not defined (DEF REAL/INT/BOOL)");
      vars_[a.name] = is_int_[a.name] ? std::round(v) : v;
    } else {
      const double idx = eval(a.index);
      if (idx < 0 || idx >= kNumR) fail(a.text + " does not exist (R0 .. R999)");
      r_[static_cast<std::size_t>(idx)] = v;
    }
  }
}

bool Executor::execute(const Block& b) {
  declare_and_assign(b);
  if (!b.comment.empty()) canon_.print("COMMENT(\"%s\")", b.comment.c_str());
  technology(b);
  int g = motion_mode_;
  bool supa = false;
  const bool motion_g = g_codes(b, g, supa);
  keywords(b, supa);
  bool end = false;
  m_functions(b, end);  // spindle, coolant, tool change (program ends are acted on after the motion)
  if (b.frame != FrameOp::None) {
    frame_statement(b);
  } else {
    const bool has_axes = !b.axes.empty();
    if (has_axes || (motion_g && (g == 2 || g == 3))) {
      motion(b, g, supa);
      if (modal_call_ && has_axes && !b.call) call(*modal_call_, true);
    }
  }
  if (b.mcall) {
    if (b.call) {
      modal_call_ = *b.call;
    } else {
      modal_call_.reset();
    }
  } else if (b.call) {
    call(*b.call, false);
  }
  for (const Keyword& k : b.keywords)
    if (k.name == "RET") end = true;
  if (end) {
    canon_.print("PROGRAM_END()");
    return true;
  }
  return false;
}

void Executor::technology(const Block& b) {
  const bool dwell = std::find(b.g_codes.begin(), b.g_codes.end(), 4) != b.g_codes.end();
  if (b.f != kNoExpr && !dwell) {  // in a G4 block F is the dwell time
    const double f = eval(b.f);
    if (f <= 0.0) fail("F" + fmt4(f) + ": the feed must be positive");
    feed_mm_per_min_ = f * (inch_ ? kInchToMm : 1.0);
    canon_.print("SET_FEED_RATE(%.4f)", feed_mm_per_min_);
  }
  if (b.s != kNoExpr) {
    const double s = eval(b.s);
    if (s < 0.0) fail("S" + fmt4(s) + ": the spindle speed must not be negative");
    canon_.print("SET_SPINDLE_SPEED(0, %.4f)", s);
  }
  if (b.t_name) {
    auto& tools = result_.tools;
    const auto it = std::find(tools.begin(), tools.end(), *b.t_name);
    selected_tool_ = static_cast<int>(it - tools.begin()) + 1;
    if (it == tools.end()) tools.push_back(*b.t_name);
    canon_.print("SELECT_TOOL(%d)", selected_tool_);
    canon_.print("COMMENT(\"interpreter: tool %d is T=\\\"%s\\\"\")", selected_tool_, b.t_name->c_str());
  }
  if (b.t_number != kNoExpr) {
    const double t = eval(b.t_number);
    if (t < 0 || std::round(t) != t) fail("T" + fmt4(t) + ": a tool number is a non-negative integer");
    selected_tool_ = static_cast<int>(t);
    canon_.print("SELECT_TOOL(%d)", selected_tool_);
  }
  if (b.d != kNoExpr) {
    const double d = eval(b.d);
    if (d < 0 || std::round(d) != d) fail("D" + fmt4(d) + ": a cutting edge number is a non-negative integer");
    // The edge's length lives in the controller's tool offsets, not in the program: the tip stays the controlled point.
  }
}

// G functions; returns whether the block programs a motion G code (G0..G3), which becomes `motion`.
bool Executor::g_codes(const Block& b, int& motion, bool& supa) {
  bool motion_g = false;
  for (int g : b.g_codes) {
    switch (g) {
      case 0:
      case 1:
      case 2:
      case 3:
        if (motion_g) fail("two motion G functions (G0..G3) in one block");
        motion_g = true;
        motion = g;
        motion_mode_ = g;
        break;
      case 4: {
        if (b.f == kNoExpr) fail("G4 needs its dwell time in seconds as F (G4 F2)");
        canon_.print("DWELL(%.4f)", eval(b.f));
        break;
      }
      case 9:
        canon_.print("COMMENT(\"interpreter: G9 exact stop in this block\")");
        break;
      case 17:
      case 18:
      case 19:
        plane_ = g;
        canon_.print("SELECT_PLANE(CANON_PLANE_%s)", g == 17 ? "XY" : g == 18 ? "XZ" : "YZ");
        break;
      case 40:
      case 450:
      case 451:
        break;  // radius compensation off; corner modes of G41/G42 only
      case 41:
      case 42:
        fail("G" + std::to_string(g) +
             ": cutter radius compensation is not supported (the path would need the tool's radius)");
      case 53:
      case 153:
        supa = true;
        break;
      case 60:
        set_control_mode("G60", std::nullopt, true);
        break;
      case 64:
        set_control_mode("G64", std::nullopt, false);
        break;
      case 641:
      case 642:
      case 643:
      case 644:
      case 645:
        set_control_mode("G" + std::to_string(g),
                         contour_tolerance_mm_ > 0 ? std::optional<double>(contour_tolerance_mm_) : std::nullopt,
                         false);
        break;
      case 601:
      case 602:
      case 603:
        break;  // exact-stop windows of G60/G9
      case 70:
      case 700:
        inch_ = true;
        break;
      case 71:
      case 710:
        inch_ = false;
        break;
      case 90:
        absolute_ = true;
        break;
      case 91:
        absolute_ = false;
        break;
      case 94:
        break;
      case 93:
        fail("G93: inverse-time feed is not supported by the Sinumerik reader");
      case 95:
      case 96:
      case 97:
        fail("G" + std::to_string(g) + ": feed per revolution / constant cutting speed is not supported");
      case 500:
        zero_offset_ = 0;
        canon_.print("COMMENT(\"interpreter: G500 settable zero offset off\")");
        break;
      default:
        if ((g >= 54 && g <= 57) || (g >= 505 && g <= 599)) {
          zero_offset_ = g;
          // The settable frames' offsets are the controller's, not the program's: the workpiece zero is taken at the
          // machine zero (sinumerik.hpp).
          if (g <= 57)
            canon_.print("SET_G5X_OFFSET(%d, %.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", g - 53, 0.0, 0.0, 0.0, 0.0, 0.0,
                         0.0);
          else
            canon_.print("COMMENT(\"interpreter: G%d settable zero offset (taken as zero)\")", g);
          break;
        }
        fail("G" + std::to_string(g) + ": G function not supported");
    }
  }
  return motion_g;
}

void Executor::set_control_mode(const std::string& what, std::optional<double> tolerance_mm, bool exact) {
  if (exact) {
    canon_.print("SET_MOTION_CONTROL_MODE(CANON_EXACT_STOP)");
  } else {
    canon_.print("SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, %f)", tolerance_mm.value_or(0.0));
  }
  result_.interp_settings.push_back({line_, what, tolerance_mm});
}

void Executor::keywords(const Block& b, bool& supa) {
  for (const Keyword& k : b.keywords) {
    const std::string& w = k.name;
    if (w == "SUPA") {
      supa = true;
    } else if (w == "TRAORI") {
      set_transformation(true);
    } else if (w == "TRAFOOF") {
      set_transformation(false);
    } else if (w == "SOFT" || w == "BRISK" || w == "DRIVE" || w == "FFWON" || w == "FFWOF") {
      // Acceleration profile and feedforward: vmsim's interpolator is always jerk-limited and its drives take their
      // feedforward gains from the machine file; the setting is reported.
      result_.interp_settings.push_back({line_, w, std::nullopt});
      canon_.print("COMMENT(\"interpreter: %s\")", w.c_str());
    } else if (w == "COMPOF" || w == "COMPON" || w == "COMPCURV" || w == "COMPCAD" || w == "FNORM" || w == "UPATH" ||
               w == "SPATH" || w == "CFC" || w == "CFTCP" || w == "CFIN" || w == "STOPRE" || w == "ORIWKS" ||
               w == "ORIMKS" || w == "ORIAXES") {
      // No effect on the path vmsim interpolates: the compressor's smoothing, feed references at the tool centre,
      // the preprocessing stop, orientation references (vmsim interpolates rotary axes linearly: ORIAXES).
    } else if (w == "ORIVECT") {
      fail(
          "ORIVECT: great-circle orientation interpolation is not supported (vmsim interpolates the rotary axes: "
          "ORIAXES)");
    } else if (w == "RET") {
      // acted on after the block's motion
    } else {
      not_modelled(w + ": NC command without motion");
    }
  }
}

void Executor::not_modelled(const std::string& what) {
  if (!options_.lenient)
    fail(what + ", not modelled by vmsim (read with --lenient, or [job] program_lenient = true, to accept it)");
  result_.warnings.push_back(core::located(file_, line_, what + ": accepted without effect (lenient)"));
}

void Executor::m_functions(const Block& b, bool& end) {
  for (int m : b.m_codes) {
    if (!known_m(m)) {
      if (std::find(options_.no_motion_mcodes.begin(), options_.no_motion_mcodes.end(), m) !=
          options_.no_motion_mcodes.end())
        continue;
      const std::string what = "M" + std::to_string(m) + ": the machine maker's M function (no motion known)";
      if (!options_.lenient) fail(what + "; list it in [job] no_motion_mcodes, or read with --lenient");
      result_.warnings.push_back(core::located(file_, line_, what + ": accepted without effect (lenient)"));
      continue;
    }
    switch (m) {
      case 0:
        canon_.print("PROGRAM_STOP()");
        break;
      case 1:
        canon_.print("OPTIONAL_PROGRAM_STOP()");
        break;
      case 2:
      case 17:
      case 30:
        end = true;
        break;
      case 3:
        canon_.print("START_SPINDLE_CLOCKWISE(0)");
        break;
      case 4:
        canon_.print("START_SPINDLE_COUNTERCLOCKWISE(0)");
        break;
      case 5:
        canon_.print("STOP_SPINDLE_TURNING(0)");
        break;
      case 6:
        current_tool_ = selected_tool_;
        ++result_.stats.tool_changes;
        canon_.print("CHANGE_TOOL(%d)", current_tool_);
        break;
      case 7:
        canon_.print("MIST_ON()");
        break;
      case 8:
        canon_.print("FLOOD_ON()");
        break;
      case 9:
        canon_.print("MIST_OFF()");
        canon_.print("FLOOD_OFF()");
        break;
      default:
        break;
    }
  }
  for (int h : b.h_codes) {
    const std::string what = "H" + std::to_string(h) + ": auxiliary function (the machine maker's, no motion known)";
    if (!options_.lenient) fail(what + "; read with --lenient to accept it");
    result_.warnings.push_back(core::located(file_, line_, what + ": accepted without effect (lenient)"));
  }
}

void Executor::set_transformation(bool on) {
  if (on == traori_) return;
  const bool was_tcp = tcp();
  traori_ = on;
  if (tcp() != was_tcp) {
    if (tcp()) {
      // The axes do not move: the tip in the workpiece frame is where the machine's kinematics put it.
      if (options_.machine) cur_.head<3>() = options_.machine->tip_of_joint(cur_);
    } else if (options_.machine) {
      cur_ = options_.machine->joint_of_tip(cur_);
    }
  }
  canon_.print("COMMENT(\"interpreter: %s\")",
               on ? "TRAORI: tool-centre-point moves, X Y Z the tool tip in the workpiece frame"
                  : "TRAFOOF: moves of the machine's axes");
}

void Executor::frame_statement(const Block& b) {
  ++result_.stats.frame_statements;
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  bool any = false;
  for (const AxisWord& w : b.axes) {
    const int a = axis_index(w.letter);
    if (a < 0 || a > 2 || w.mode != AxisMode::Default)
      fail(std::string(1, w.letter) + ": a frame statement takes X, Y and Z only");
    v[a] = b.frame == FrameOp::Trans || b.frame == FrameOp::ATrans ? eval_length(w.value) : eval(w.value);
    any = true;
  }
  const char* name = "";
  switch (b.frame) {
    case FrameOp::Trans:
      name = "TRANS";
      frame_ = Frame::translation(v);
      break;
    case FrameOp::ATrans:
      name = "ATRANS";
      frame_ = frame_.then(Frame::translation(v));
      break;
    case FrameOp::Rot:
    case FrameOp::ARot: {
      name = b.frame == FrameOp::Rot ? "ROT" : "AROT";
      Frame r;
      if (b.rpl != kNoExpr) {
        if (any) fail(std::string(name) + ": RPL= and axis angles in one block");
        r = Frame::rotation_about(plane_axes(plane_)[2], eval(b.rpl));
      } else {
        r = Frame::rotation_rpy_deg(v.x(), v.y(), v.z());
      }
      frame_ = b.frame == FrameOp::Rot ? r : frame_.then(r);
      break;
    }
    case FrameOp::None:
      break;
  }
  const Frame t = total_frame();
  const Eigen::Vector3d z = t.rotation.col(2);
  canon_.print("COMMENT(\"interpreter: %s: frame origin (%.4f, %.4f, %.4f), z axis (%.4f, %.4f, %.4f)\")", name,
               t.offset.x(), t.offset.y(), t.offset.z(), z.x(), z.y(), z.z());
}

// ---------------------------------------------------------------------------------------------------------------
// motion

Eigen::Vector3d Executor::programmed(const Frame& frame) const { return frame.inverse_apply(cur_.head<3>()); }

void Executor::emit_position(const char* name, const core::Vec6& v) {
  const double out[6] = {v[0], v[1], v[2], v[3] / kDegToRad, v[4] / kDegToRad, v[5] / kDegToRad};
  canon_.axes_call(name, out, 6);
}

void Executor::push_move(core::Move m) {
  m.source_line = line_;
  m.tool_number = current_tool_;
  m.tcp = tcp();
  if ((m.end - m.start).cwiseAbs().maxCoeff() <= 1e-9 && m.kind == core::MotionKind::Line) return;
  if (m.tcp) ++result_.stats.tcp_moves;
  if (!m.rapid && contour_tolerance_mm_ > 0)
    smallest_feed_tolerance_ =
        std::min(smallest_feed_tolerance_.value_or(contour_tolerance_mm_), contour_tolerance_mm_);
  result_.path.moves.push_back(std::move(m));
}

void Executor::line_to(bool rapid, const core::Vec6& end) {
  emit_position(rapid ? "STRAIGHT_TRAVERSE" : "STRAIGHT_FEED", end);
  core::Move m;
  m.kind = core::MotionKind::Line;
  m.rapid = rapid;
  m.start = cur_;
  m.end = end;
  if (!rapid) {
    if (feed_mm_per_min_ <= 0.0) fail("a feed move (G1, G2, G3) without a feed: program F first");
    m.feed_mm_per_min = feed_mm_per_min_;
  }
  push_move(m);
  cur_ = end;
}

bool Executor::motion(const Block& b, int g, bool supa) {
  if (supa && tcp()) fail("SUPA / G53 under TRAORI or a CYCLE800 swivel: machine positions need TRAFOOF");
  if (supa && (g == 2 || g == 3)) fail("SUPA / G53 with an arc: machine positions take straight moves only");
  const Frame frame = supa ? Frame{} : total_frame();
  Eigen::Vector3d p = programmed(frame);
  const Eigen::Vector3d start_prog = p;
  Eigen::Vector3d rot = cur_.tail<3>();  // rad
  bool linear = false, rotary = false;
  for (const AxisWord& w : b.axes) {
    const int a = axis_index(w.letter);
    if (a < 0) continue;  // I J K: arc centres
    const bool inc = w.mode == AxisMode::Incremental || (w.mode == AxisMode::Default && !absolute_);
    if (a < 3) {
      const double v = eval_length(w.value);
      p[a] = inc ? p[a] + v : v;
      linear = true;
    } else {
      const double v = eval(w.value) * kDegToRad;
      rot[a - 3] = inc ? rot[a - 3] + v : v;
      rotary = true;
    }
  }
  (void)linear;
  (void)rotary;
  if (g == 2 || g == 3) {
    ++result_.stats.arc_blocks;
    arc_to(b, g, p, rot, frame);
    (void)start_prog;
    return true;
  }
  for (const AxisWord& w : b.axes)
    if (axis_index(w.letter) < 0) fail(std::string(1, w.letter) + ": arc centres belong to G2/G3 blocks");
  if (b.cr != kNoExpr || b.turn != kNoExpr) fail("CR= and TURN= belong to G2/G3 blocks");
  core::Vec6 end;
  end.head<3>() = frame.apply(p);
  end.tail<3>() = rot;
  if (g == 0)
    ++result_.stats.rapid_blocks;
  else
    ++result_.stats.linear_blocks;
  line_to(g == 0, end);
  return true;
}

// G2/G3 in the plane of G17/G18/G19 of the programmed frame. Siemens, NC programming, "Circular interpolation":
// I J K are the centre relative to the start point (=AC(..): absolute); CR=+r takes the arc up to 180 degrees,
// CR=-r the one over 180; TURN=n adds n full turns (a helix when the normal axis moves). The end point must lie on the
// circle within 0.01 mm or 0.1 % of the radius (the 840D's defaults for MD21000/MD21010).
void Executor::arc_to(const Block& b, int g, const Eigen::Vector3d& end_prog, const Eigen::Vector3d& rot_end,
                      const Frame& frame) {
  const std::array<int, 3> ax = plane_axes(plane_);
  const Eigen::Vector3d p0 = programmed(frame);
  const Eigen::Vector2d s(p0[ax[0]], p0[ax[1]]), e(end_prog[ax[0]], end_prog[ax[1]]);
  const double sense = g == 3 ? 1.0 : -1.0;  // counter-clockwise seen from the plane normal's positive side
  Eigen::Vector2d c = s;
  bool centre = false;
  for (const AxisWord& w : b.axes) {
    const int k = w.letter == 'I' ? 0 : w.letter == 'J' ? 1 : w.letter == 'K' ? 2 : -1;
    if (k < 0) continue;
    const int slot = k == ax[0] ? 0 : k == ax[1] ? 1 : -1;
    if (slot < 0) fail(std::string(1, w.letter) + ": not an axis of the active plane G" + std::to_string(plane_));
    if (w.mode == AxisMode::Incremental) fail(std::string(1, w.letter) + "=IC(): centres are incremental already");
    const double v = eval_length(w.value);
    c[slot] = w.mode == AxisMode::Absolute ? v : s[slot] + v;
    centre = true;
  }
  if (centre && b.cr != kNoExpr) fail("an arc takes either a centre (I J K) or a radius (CR=), not both");
  if (!centre && b.cr == kNoExpr) fail("G" + std::to_string(g) + " needs a centre (I J K) or a radius (CR=)");
  if (b.cr != kNoExpr) {
    const double r = eval_length(b.cr);
    const Eigen::Vector2d chord = e - s;
    const double d = chord.norm();
    if (d < 1e-9) fail("CR=: a full circle needs its centre (I J K)");
    if (std::fabs(r) < d / 2 - 1e-6)
      fail("CR=" + fmt4(r) + ": the radius is shorter than half the chord (" + fmt4(d / 2) + ")");
    const double h = std::sqrt(std::max(0.0, r * r - d * d / 4));
    const Eigen::Vector2d left(-chord.y() / d, chord.x() / d);
    // A counter-clockwise arc of up to 180 degrees has its centre left of the chord; CR < 0 or G2 flips the side.
    const double side = sense * (r > 0 ? 1.0 : -1.0);
    c = (s + e) / 2 + side * h * left;
  }
  const double r0 = (s - c).norm(), r1 = (e - c).norm();
  if (r0 < 1e-9) fail("the arc's centre is its start point");
  if (std::fabs(r1 - r0) > std::max(0.01, 1e-3 * r0))
    fail("the end point is " + fmt4(std::fabs(r1 - r0)) + " mm off the circle of radius " + fmt4(r0) +
         " (840D tolerance: 0.01 mm or 0.1 %)");
  int turns = 0;
  if (b.turn != kNoExpr) {
    const double t = eval(b.turn);
    if (t < 0 || std::round(t) != t || t > 999) fail("TURN=" + fmt4(t) + ": full turns are an integer 0..999");
    turns = static_cast<int>(t);
  }

  Eigen::Vector3d c3 = p0;
  c3[ax[0]] = c[0];
  c3[ax[1]] = c[1];
  // The plane's normal in the workpiece frame: an arc stays an arc when it is a coordinate axis.
  const Eigen::Vector3d n_w = frame.rotation.col(ax[2]);
  int k = -1;
  for (int i = 0; i < 3; ++i)
    if (std::fabs(std::fabs(n_w[i]) - 1.0) < 1e-12) k = i;
  core::Vec6 end;
  end.head<3>() = frame.apply(end_prog);
  end.tail<3>() = rot_end;
  if (feed_mm_per_min_ <= 0.0) fail("a feed move (G1, G2, G3) without a feed: program F first");
  if (k >= 0) {
    const std::array<int, 3> wp = k == 2   ? std::array<int, 3>{0, 1, 2}
                                  : k == 1 ? std::array<int, 3>{2, 0, 1}
                                           : std::array<int, 3>{1, 2, 0};
    const Eigen::Vector3d cw = frame.apply(c3);
    const int rotation = static_cast<int>(sense * (n_w[k] > 0 ? 1 : -1)) * (1 + turns);
    const double plane4[4] = {end[wp[0]], end[wp[1]], cw[wp[0]], cw[wp[1]]};
    const double rest4[4] = {end[wp[2]], end[3] / kDegToRad, end[4] / kDegToRad, end[5] / kDegToRad};
    canon_.arc_call(plane4, rotation, rest4);
    core::Move m;
    m.kind = core::MotionKind::Arc;
    m.plane = k == 2 ? core::ArcPlane::XY : k == 1 ? core::ArcPlane::ZX : core::ArcPlane::YZ;
    m.centre_mm = Eigen::Vector2d(cw[wp[0]], cw[wp[1]]);
    m.rotation = rotation;
    m.start = cur_;
    m.end = end;
    m.feed_mm_per_min = feed_mm_per_min_;
    push_move(m);
    cur_ = end;
    return;
  }
  // An oblique plane (a frame turned about two axes): chords in the programmed plane, within the chord tolerance.
  ++result_.stats.chorded_arcs;
  canon_.print("COMMENT(\"interpreter: arc in a plane oblique to the workpiece axes, as chords within %.4f mm\")",
               options_.arc_chord_tolerance_mm);
  const double a0 = std::atan2(s.y() - c.y(), s.x() - c.x());
  double a1 = std::atan2(e.y() - c.y(), e.x() - c.x());
  double sweep = a1 - a0;
  const double two_pi = 2 * core::units::kPi;
  if (sense > 0) {
    while (sweep <= 1e-12) sweep += two_pi;
  } else {
    while (sweep >= -1e-12) sweep -= two_pi;
  }
  sweep += sense * two_pi * turns;
  const double rmax = std::max(r0, r1);
  const double tol = std::min(options_.arc_chord_tolerance_mm, rmax / 2);
  const double step = 2 * std::acos(1 - tol / rmax);
  const int n = std::max(1, static_cast<int>(std::ceil(std::fabs(sweep) / step)));
  const core::Vec6 start = cur_;
  for (int i = 1; i <= n; ++i) {
    const double u = static_cast<double>(i) / n;
    core::Vec6 q;
    if (i == n) {
      q = end;
    } else {
      const double a = a0 + u * sweep, r = r0 + u * (r1 - r0);
      Eigen::Vector3d pp;
      pp[ax[0]] = c[0] + r * std::cos(a);
      pp[ax[1]] = c[1] + r * std::sin(a);
      pp[ax[2]] = p0[ax[2]] + u * (end_prog[ax[2]] - p0[ax[2]]);
      q.head<3>() = frame.apply(pp);
      q.tail<3>() = start.tail<3>() + u * (end.tail<3>() - start.tail<3>());
    }
    line_to(false, q);
  }
}

// ---------------------------------------------------------------------------------------------------------------

}  // namespace vmsim::program::sinumerik

namespace vmsim::program {

SinumerikResult interpret_sinumerik_text(std::string_view text, const std::string& name,
                                         const SinumerikOptions& options) {
  const sinumerik::Program parsed = sinumerik::parse_program(text);
  sinumerik::Executor executor(parsed, name, options);
  return executor.run();
}

SinumerikResult interpret_sinumerik(const std::filesystem::path& program, const SinumerikOptions& options) {
  core::require_regular_file(program);
  std::ifstream in(program, std::ios::binary);
  if (!in) throw core::Error(program.string() + ": cannot open the Sinumerik program");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw core::Error(program.string() + ": cannot read the Sinumerik program");
  return interpret_sinumerik_text(text.str(), program.string(), options);
}

bool looks_like_sinumerik_program(std::string_view text) { return sinumerik::looks_like_sinumerik(text); }

}  // namespace vmsim::program
