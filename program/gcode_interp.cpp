// Block execution: evaluation of a line, LinuxCNC's modal groups and checks, and the non-motion codes in
// LinuxCNC's order of execution (comment, feed mode, F, S, T, M codes, G codes, stops). Parameters live in
// gcode_params.cpp, coordinate systems and offsets in gcode_offsets.cpp, motions in gcode_motion.cpp.
#include "program/gcode_interp.hpp"
#include "core/units.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace vmsim::program::gcode {

namespace {

using core::units::kInchToMm;

// Modal groups of the G codes vmsim executes (LinuxCNC's numbering), -1 for anything else.
int g_group(int g) {
  switch (g) {
    case 40:
    case 100:
    case 280:
    case 281:
    case 300:
    case 301:
    case 520:
    case 530:
    case 920:
    case 921:
    case 922:
    case 923:
      return 0;
    case 0:
    case 10:
    case 20:
    case 30:
    case 730:
    case 800:
    case 810:
    case 820:
    case 830:
    case 850:
    case 890:
      return 1;
    case 170:
    case 180:
    case 190:
      return 2;
    case 900:
    case 910:
      return 3;
    case 901:
    case 911:
      return 4;
    case 930:
    case 940:
      return 5;
    case 200:
    case 210:
      return 6;
    case 400:
      return 7;
    case 430:
    case 431:
    case 432:
    case 490:
      return 8;
    case 980:
    case 990:
      return 10;
    case 540:
    case 550:
    case 560:
    case 570:
    case 580:
    case 590:
    case 591:
    case 592:
    case 593:
      return 12;
    case 610:
    case 611:
    case 640:
      return 13;
    case 960:
    case 970:
      return 14;
    default:
      return -1;
  }
}

const char* g_group_name(int group) {
  switch (group) {
    case 0:
      return "non-modal";
    case 1:
      return "motion";
    case 2:
      return "plane selection";
    case 3:
      return "distance mode";
    case 4:
      return "arc centre mode";
    case 5:
      return "feed mode";
    case 6:
      return "units";
    case 7:
      return "cutter compensation";
    case 8:
      return "tool length offset";
    case 10:
      return "canned cycle return";
    case 12:
      return "coordinate system";
    case 13:
      return "path control";
    case 14:
      return "spindle mode";
    default:
      return "?";
  }
}

// Why a G code LinuxCNC knows is not executed; nullptr if it is not one of those.
const char* g_unsupported(int g) {
  switch (g) {
    case 410:
    case 420:
    case 411:
    case 421:
      return "(cutter radius compensation) is not supported; post the program for the tool centre path "
             "(vmsim follows the programmed point) and use G40";
    case 50:
    case 51:
    case 52:
    case 53:
      return "(spline / NURBS motion) is not supported";
    case 70:
    case 80:
      return "(lathe diameter/radius mode) is not supported";
    case 330:
    case 331:
    case 760:
      return "(spindle-synchronised motion / threading) is not supported";
    case 382:
    case 383:
    case 384:
    case 385:
      return "(probing) is not supported: where the probe stops is not known before the machine runs";
    case 171:
    case 181:
    case 191:
      return "(U V W arc planes) is not supported";
    case 700:
    case 710:
    case 711:
    case 720:
    case 721:
      return "(lathe cycle) is not supported";
    case 740:
    case 840:
    case 860:
    case 870:
    case 880:
      return "(canned cycle) is not supported; vmsim executes G73 G81 G82 G83 G85 G89";
    case 950:
      return "(feed per revolution) is not supported; use G94 (units per minute) or G93 (inverse time)";
    default:
      return nullptr;
  }
}

int m_group(int m) {
  switch (m) {
    case 0:
    case 1:
    case 2:
    case 30:
    case 60:
      return 4;
    case 6:
    case 61:
      return 6;
    case 3:
    case 4:
    case 5:
      return 7;
    case 7:
    case 8:
    case 9:
      return 8;
    case 48:
    case 49:
    case 50:
    case 51:
    case 52:
    case 53:
      return 9;
    default:
      return -1;
  }
}

const char* m_unsupported(int m) {
  if (m == 19) return "(spindle orientation) is not supported";
  if (m >= 62 && m <= 68) return "(digital/analog I/O) is not supported";
  if (m >= 70 && m <= 73) return "(saving/restoring modal state) is not supported";
  if (m == 98 || m == 99) return "(Fanuc-style subroutine call/return) is not supported; use O-word subroutines";
  if (m >= 100 && m <= 199)
    return "is a user-defined M code; if it makes no motion, accept it with --no-motion-m "
           "(GcodeOptions::no_motion_mcodes)";
  return nullptr;
}

bool is_cycle(int g) { return g == 730 || g == 810 || g == 820 || g == 830 || g == 850 || g == 890; }

// "G1", "T2.5": built by appending (GCC 12 warns falsely on "literal" + std::string temporaries).
std::string word(char letter, double v) {
  std::string s(1, letter);
  s += fmt_num(v);
  return s;
}

}  // namespace

std::string fmt_num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// ---------------------------------------------------------------------------------------------------------------
// Messages

void Interpreter::fail(const std::string& message) const {
  const int number = line_ < prog_.lines.size() ? prog_.lines[line_].number : 0;
  throw core::Error(core::located(file_, number, message));
}

std::string Interpreter::g_name(int g10) const {
  std::string s = word('G', g10 / 10);
  if (g10 % 10) {
    s += '.';
    s += std::to_string(g10 % 10);
  }
  return s;
}

// ---------------------------------------------------------------------------------------------------------------
// Reading and checking a block

Block Interpreter::read_block(const SourceLine& line) {
  Block b;
  for (const Word& w : line.words) {
    double v = 0.0;
    try {
      v = prog_.exprs.evaluate(w.value, *this);
    } catch (const ExprError& e) {
      fail(std::string(1, w.letter) + " word: " + e.what());
    }
    if (w.letter == 'G') {
      const double t = v * 10.0;
      const double r = std::nearbyint(t);
      if (std::fabs(t - r) > 1e-3 || r < 0.0 || r > 9999.0) fail(word('G', v) + " is not a G code");
      if (b.n_g == Block::kMaxCodes) fail("too many G codes on one line");
      b.g_codes[static_cast<std::size_t>(b.n_g++)] = static_cast<int>(r);
    } else if (w.letter == 'M') {
      const double r = std::nearbyint(v);
      if (std::fabs(r - v) > 1e-4 || r < 0.0 || r > 9999.0) fail(word('M', v) + " is not an M code");
      if (b.n_m == Block::kMaxCodes) fail("too many M codes on one line");
      b.m_codes[static_cast<std::size_t>(b.n_m++)] = static_cast<int>(r);
    } else {
      if (b.has(w.letter)) fail(std::string("two ") + w.letter + " words on one line");
      b.value[static_cast<std::size_t>(w.letter - 'A')] = v;
      b.present |= 1u << (w.letter - 'A');
    }
  }
  return b;
}

void Interpreter::check_codes(Block& b) {
  for (int gi = 0; gi < b.n_g; ++gi) {
    const int g = b.g_codes[static_cast<std::size_t>(gi)];
    const int group = g_group(g);
    if (group < 0) {
      if (const char* why = g_unsupported(g)) fail(g_name(g) + " " + why);
      fail(g_name(g) + " is not a G code LinuxCNC knows");
    }
    int& slot = b.g_mode[static_cast<std::size_t>(group)];
    // LinuxCNC lets G80 share a block with another motion code, which wins ("G80 G81 ..." starts a cycle).
    if (group == 1 && (slot == 800 || (g == 800 && slot != -1))) {
      if (slot == 800) slot = g;
      continue;
    }
    if (slot != -1)
      fail(g_name(slot) + " and " + g_name(g) + " are in the same modal group (" + g_group_name(group) + ")");
    slot = g;
  }
  if (b.n_m > 4) fail("more than four M codes on one line");
  for (int mi = 0; mi < b.n_m; ++mi) {
    const int m = b.m_codes[static_cast<std::size_t>(mi)];
    if (std::find(options_.no_motion_mcodes.begin(), options_.no_motion_mcodes.end(), m) !=
        options_.no_motion_mcodes.end()) {
      b.no_motion_m = true;  // remapped by the machine: accepted, makes no motion and no canonical call
      continue;
    }
    const int group = m_group(m);
    if (group < 0) {
      if (const char* why = m_unsupported(m)) fail(word('M', m) + " " + why);
      fail(word('M', m) +
           " is not an M code LinuxCNC knows; if the machine remaps it to an action without motion, "
           "declare it (--no-motion-m, GcodeOptions::no_motion_mcodes)");
    }
    if (b.m_mode[static_cast<std::size_t>(group)] != -1)
      fail(word('M', b.m_mode[static_cast<std::size_t>(group)]) + " and M" + std::to_string(m) +
           " are in the same modal group");
    b.m_mode[static_cast<std::size_t>(group)] = m;
  }
  for (const char letter : {'E', 'U', 'V', 'W'}) {
    if (!b.has(letter)) continue;
    if (letter == 'E') fail("E word is not supported (no M66-M68 or G76)");
    fail(std::string(1, letter) + " word: U, V and W axes are not supported");
  }

  // The motion this block makes: its own group-1 code, or the modal one when it has axis words that no
  // other code uses (G10, G28, G30, G52, G92 and G43.1 take the axis words for themselves).
  const int g0 = b.g_mode[0];
  const bool g0_axes = g0 == 100 || g0 == 280 || g0 == 300 || g0 == 520 || g0 == 920 || b.g_mode[8] == 431;
  if (b.g_mode[1] != -1) {
    b.motion = b.g_mode[1];
    if (b.motion == 800 && b.has_axis() && !g0_axes) fail("axis words with G80 (G80 cancels motion)");
    if (b.motion != 800 && g0_axes && b.has_axis())
      fail(g_name(g0 == -1 ? b.g_mode[8] : g0) + " and " + g_name(b.motion) + " both use the axis words on one line");
  } else if (b.has_axis() && !g0_axes) {
    if (motion_mode_ == 800)
      fail("axis words without a motion mode (G80 is active; give G0, G1, G2, G3 or a canned cycle)");
    b.motion = motion_mode_;
  }
  if (g0 == 530 && b.motion != 0 && b.motion != 10) fail("G53 must be used with G0 or G1");
  if ((g0 == 920 || g0 == 520) && !b.has_axis()) fail(g_name(g0) + " needs at least one axis word");
  // No word may go unused (LinuxCNC's check_other_codes).
  const bool arc = b.motion == 20 || b.motion == 30;
  const bool cyc = is_cycle(b.motion);
  const int m9 = b.m_mode[9];
  if ((b.has('I') || b.has('J') || b.has('K')) && !arc) {
    const char l = b.has('I') ? 'I' : b.has('J') ? 'J' : 'K';
    fail(std::string(1, l) + " word with no G2 or G3 to use it");
  }
  if (b.has('R') && !arc && !cyc && g0 != 100) fail("R word with no G2, G3, canned cycle or G10 to use it");
  if (b.has('L') && !cyc && g0 != 100) fail("L word with no G10 or canned cycle to use it");
  if (b.has('H') && b.g_mode[8] != 430 && b.g_mode[8] != 432) fail("H word with no G43 to use it");
  if (b.has('D') && b.g_mode[14] != 960) fail("D word with no G96 to use it (G41/G42 are not supported)");
  if (b.has('P') && !arc && b.motion != 820 && b.motion != 890 && g0 != 40 && g0 != 100 && b.g_mode[13] != 640 &&
      !(m9 >= 50 && m9 <= 53) && !b.no_motion_m)
    fail("P word with no G4, G10, G2/G3, G64, G82, G89 or M50-M53 to use it");
  if (b.has('Q') && b.motion != 730 && b.motion != 830 && b.g_mode[13] != 640 && b.m_mode[6] != 61 && !b.no_motion_m)
    fail("Q word with no G73, G83, G64 or M61 to use it");
  if (b.m_mode[6] == 61 && !b.has('Q')) fail("M61 needs a Q word (the tool number)");
  if (b.has('F') && b['F'] < 0.0) fail("negative F word");
  if (b.has('S') && b['S'] < 0.0) fail("negative S word (spindle speed)");
}

// ---------------------------------------------------------------------------------------------------------------
// Executing a block in LinuxCNC's order (execute_block)

bool Interpreter::execute_block(Block& b) {
  check_codes(b);
  const SourceLine& line = prog_.lines[line_];
  if (line.comment) comment(*line.comment);
  if (b.g_mode[14] != -1) {
    if (b.g_mode[14] == 970)
      canon_.print("SET_SPINDLE_MODE(0 %.4f)", 0.0);
    else
      canon_.print("SET_SPINDLE_MODE(0 %.4f)", b.has('D') ? std::fabs(b['D']) : 1e30);
  }
  if (b.g_mode[5] != -1) feed_mode(b.g_mode[5]);
  block_f_ = b.has('F') ? b['F'] : 0.0;
  if (b.has('F') && !inverse_time_) {
    feed_rate_ = b['F'];
    feed_linear_mm_ = feed_rate_ * (inch_ ? kInchToMm : 1.0);
    feed_angular_deg_ = feed_rate_;
    canon_.axes_call("SET_FEED_RATE", &feed_rate_, 1);
  }
  if (b.has('S')) {
    speed_ = b['S'];
    canon_.print("SET_SPINDLE_SPEED(0, %.4f)", speed_);
  }
  if (b.has('T')) select_tool(b);
  m_codes(b);
  g_codes(b);
  return stop(b);
}

void Interpreter::comment(const std::string& text) {
  // LinuxCNC (convert_comment): leading blanks skipped, then MSG, DEBUG, PRINT, LOG... are recognised
  // case-insensitively; anything else is a plain comment.
  std::size_t start = 0;
  while (start < text.size() && std::isspace(static_cast<unsigned char>(text[start]))) ++start;
  std::string lc;
  for (std::size_t i = start; i < text.size(); ++i)
    lc += static_cast<char>(std::tolower(static_cast<unsigned char>(text[i])));
  const auto expand = [&](std::size_t skip) {
    // Parameters in the text are replaced by their values ("%lf", ###### when undefined).
    const std::string s = text.substr(start + skip);
    std::string out;
    for (std::size_t i = 0; i < s.size();) {
      if (s[i] != '#') {
        out += s[i++];
        continue;
      }
      ++i;
      bool found = false;
      double value = 0.0;
      if (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) {
        std::size_t j = i;
        while (j < s.size() && std::isdigit(static_cast<unsigned char>(s[j])) && j - i < 6) ++j;
        const int n = std::stoi(s.substr(i, j - i));
        i = j;
        if (n >= 0 && n < kNumParams) {
          try {
            value = n == 0 ? params_[0] : numbered(n);
            found = true;
          } catch (const ExprError&) {
          }
        }
      } else if (i < s.size() && s[i] == '<') {
        const std::size_t close = s.find('>', i);
        if (close == std::string::npos) fail("(debug,...): named parameter without a closing '>'");
        std::string name;
        for (std::size_t k = i + 1; k < close; ++k)
          if (!std::isspace(static_cast<unsigned char>(s[k])))
            name += static_cast<char>(std::tolower(static_cast<unsigned char>(s[k])));
        i = close + 1;
        const int id = prog_.names.find(name);
        if (id >= 0 && exists(id)) {
          value = named(id);
          found = true;
        }
      } else {
        out += '#';
        continue;
      }
      if (found) {
        char buf[512];
        std::snprintf(buf, sizeof buf, "%lf", std::fabs(value) < kToleranceEqual ? 0.0 : value);
        out += buf;
      } else {
        out += "######";
      }
    }
    return out;
  };
  if (lc.starts_with("msg,")) {
    canon_.print("MESSAGE(\"%s\")", text.c_str() + start + 4);
  } else if (lc.starts_with("debug,")) {
    if (params_[5599] > 0.0) canon_.print("MESSAGE(\"%s\")", expand(6).c_str());
  } else if (lc.starts_with("print,") || lc.starts_with("log,") || lc.starts_with("logopen,") ||
             lc.starts_with("logappend,") || lc == "logclose") {
    // Output to the operator's terminal or a log file: no canonical call, nothing for the machine.
  } else if (lc.starts_with("abort,")) {
    fail("program aborted by (abort,...): " + expand(6));
  } else if (lc.starts_with("py,") || lc.starts_with("pyrun,") || lc.starts_with("pyreload")) {
    fail("Python comments (" + text.substr(start) + ") are not supported");
  } else {
    canon_.print("COMMENT(\"%s\")", text.c_str() + start);
  }
}

void Interpreter::feed_mode(int g) {
  if (g == 930) {
    canon_.print("COMMENT(\"%s\")", "interpreter: feed mode set to inverse time");
    inverse_time_ = true;
    canon_.print("SET_FEED_MODE(0, 0)");  // the interpreter turns inverse time into per-move feed rates
  } else {
    canon_.print("COMMENT(\"%s\")", "interpreter: feed mode set to units per minute");
    inverse_time_ = false;
    canon_.print("SET_FEED_MODE(0, 0)");
    feed_rate_ = 0.0;
    feed_linear_mm_ = feed_angular_deg_ = 0.0;
    canon_.print("SET_FEED_RATE(%.4f)", 0.0);
  }
}

const ToolEntry* Interpreter::tool_entry(int number, const char* what) const {
  if (number == 0) return nullptr;
  if (tools_ == nullptr)
    fail(std::string(what) + ": tool " + std::to_string(number) +
         " is unknown: give the LinuxCNC tool table (--tool-table / GcodeOptions::tool_table)");
  const ToolEntry* t = tools_->find(number);
  if (t == nullptr)
    fail(std::string(what) + ": tool " + std::to_string(number) + " is not in the tool table " + tools_->source_path);
  return t;
}

void Interpreter::select_tool(const Block& b) {
  const double t = b['T'];
  if (t != std::floor(t)) fail(word('T', t) + ": the tool number must be a whole number");
  if (t < 0) fail(word('T', t) + ": negative tool number");
  if (t > 1e9) fail(word('T', t) + ": tool number out of range");
  const int tool = static_cast<int>(t);
  if (tools_ != nullptr) tool_entry(tool, (word('T', tool)).c_str());
  canon_.print("SELECT_TOOL(%d)", tool);
  selected_tool_ = tool;
}

void Interpreter::m_codes(const Block& b) {
  // LinuxCNC reports tools by their index in the table (its "pocket"); without a table, by number.
  const auto tool_index = [&](int tool) {
    if (tool == 0 || tools_ == nullptr) return tool;
    const ToolEntry* t = tools_->find(tool);
    return t != nullptr ? t->index : tool;
  };
  if (b.m_mode[6] == 6) {
    canon_.print("START_CHANGE()");
    canon_.print("STOP_SPINDLE_TURNING(0)");
    spindle_ = 0;
    canon_.print("CHANGE_TOOL(%d)", tool_index(selected_tool_));
    current_tool_ = selected_tool_;
  } else if (b.m_mode[6] == 61) {
    const double q = b['Q'];
    if (q < 0 || q != std::floor(q) || q > 1e9) fail("M61 Q" + fmt_num(q) + ": Q must be a tool number (0 or more)");
    const int tool = static_cast<int>(q);
    tool_entry(tool, "M61");
    canon_.print("CHANGE_TOOL_NUMBER(%d)", tool_index(tool));
    current_tool_ = tool;
  }
  switch (b.m_mode[7]) {
    case 3:
      canon_.print("START_SPINDLE_CLOCKWISE(0)");
      spindle_ = 1;
      break;
    case 4:
      canon_.print("START_SPINDLE_COUNTERCLOCKWISE(0)");
      spindle_ = -1;
      break;
    case 5:
      canon_.print("STOP_SPINDLE_TURNING(0)");
      spindle_ = 0;
      break;
    default:
      break;
  }
  switch (b.m_mode[8]) {
    case 7:
      canon_.print("MIST_ON()");
      mist_ = true;
      break;
    case 8:
      canon_.print("FLOOD_ON()");
      flood_ = true;
      break;
    case 9:
      canon_.print("MIST_OFF()");
      canon_.print("FLOOD_OFF()");
      mist_ = flood_ = false;
      break;
    default:
      break;
  }
  // M50-M53 without P mean "enable" (LinuxCNC's P default is -1, not 0).
  const bool enable = !b.has('P') || b['P'] != 0.0;
  switch (b.m_mode[9]) {
    case 48:
      canon_.print("ENABLE_FEED_OVERRIDE()");
      canon_.print("ENABLE_SPEED_OVERRIDE(0)");
      feed_override_ = speed_override_ = true;
      break;
    case 49:
      canon_.print("DISABLE_FEED_OVERRIDE()");
      canon_.print("DISABLE_SPEED_OVERRIDE(0)");
      feed_override_ = speed_override_ = false;
      break;
    case 50:
      canon_.print(enable ? "ENABLE_FEED_OVERRIDE()" : "DISABLE_FEED_OVERRIDE()");
      feed_override_ = enable;
      break;
    case 51:
      canon_.print(enable ? "ENABLE_SPEED_OVERRIDE(0)" : "DISABLE_SPEED_OVERRIDE(0)");
      speed_override_ = enable;
      break;
    case 52:
      canon_.print(enable ? "ENABLE_ADAPTIVE_FEED()" : "DISABLE_ADAPTIVE_FEED()");
      break;
    case 53:
      canon_.print(enable ? "ENABLE_FEED_HOLD()" : "DISABLE_FEED_HOLD()");
      break;
    default:
      break;
  }
}

void Interpreter::g_codes(Block& b) {
  if (b.g_mode[0] == 40) {
    if (!b.has('P') || b['P'] < 0.0) fail("G4 needs a P word (dwell time in seconds, 0 or more)");
    canon_.print("DWELL(%.4f)", b['P']);
  }
  if (b.g_mode[2] != -1) set_plane(b.g_mode[2]);
  if (b.g_mode[6] != -1) length_units(b.g_mode[6]);
  if (b.g_mode[7] == 400) canon_.print("COMMENT(\"%s\")", "interpreter: cutter radius compensation off");
  if (b.g_mode[8] != -1) tool_length_offset(b.g_mode[8], b);
  if (b.g_mode[12] != -1) coordinate_system(b.g_mode[12]);
  if (b.g_mode[13] != -1) control_mode(b.g_mode[13], b);
  if (b.g_mode[3] != -1) {
    const bool abs = b.g_mode[3] == 900;
    if (abs != absolute_)
      canon_.print("COMMENT(\"%s\")", abs ? "interpreter: distance mode changed to absolute"
                                          : "interpreter: distance mode changed to incremental");
    absolute_ = abs;
  }
  if (b.g_mode[4] != -1) {
    const bool abs = b.g_mode[4] == 901;
    if (abs != ijk_absolute_)
      canon_.print("COMMENT(\"%s\")", abs ? "interpreter: IJK distance mode changed to absolute"
                                          : "interpreter: IJK distance mode changed to incremental");
    ijk_absolute_ = abs;
  }
  if (b.g_mode[10] != -1) {
    retract_r_plane_ = b.g_mode[10] == 990;
    canon_.print("COMMENT(\"%s\")", retract_r_plane_ ? "interpreter: retract mode set to r_plane"
                                                     : "interpreter: retract mode set to old_z");
  }
  switch (b.g_mode[0]) {
    case 100:
      setup_g10(b);
      break;
    case 280:
    case 300:
      home(b.g_mode[0], b);
      break;
    case 281:
    case 301:
      save_home(b.g_mode[0]);
      break;
    case 520:
    case 920:
    case 921:
    case 922:
    case 923:
      axis_offsets(b.g_mode[0], b);
      break;
    default:
      break;
  }
  if (b.motion != -1) motion(b.motion, b);
}

void Interpreter::set_plane(int g) {
  plane_ = g == 170 ? Plane::XY : g == 180 ? Plane::XZ : Plane::YZ;
  canon_.print("SELECT_PLANE(CANON_PLANE_%s)", g == 170 ? "XY" : g == 180 ? "XZ" : "YZ");
}

void Interpreter::length_units(int g) {
  const bool inch = g == 200;
  canon_.print("USE_LENGTH_UNITS(%s)", inch ? "CANON_UNITS_INCHES" : "CANON_UNITS_MM");
  if (inch == inch_) return;
  // Everything the interpreter keeps in program units follows (LinuxCNC's convert_length_units); the
  // physical feed the canon layer holds does not change.
  const double f = inch ? 1.0 / kInchToMm : kInchToMm;
  inch_ = inch;
  for (int i = 0; i < 3; ++i) {
    pos_[static_cast<std::size_t>(i)] *= f;
    axis_offset_[static_cast<std::size_t>(i)] *= f;
    origin_offset_[static_cast<std::size_t>(i)] *= f;
    tool_offset_[static_cast<std::size_t>(i)] *= f;
  }
  feed_rate_ *= f;
}

void Interpreter::emit_control_mode(ControlMode mode, double tolerance) {
  control_ = mode;
  control_tolerance_ = tolerance;
  if (mode == ControlMode::ExactPath)
    canon_.print("SET_MOTION_CONTROL_MODE(CANON_EXACT_PATH)");
  else if (mode == ControlMode::ExactStop)
    canon_.print("SET_MOTION_CONTROL_MODE(CANON_EXACT_STOP)");
  else
    canon_.print("SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, %f)", tolerance);
}

void Interpreter::control_mode(int g, const Block& b) {
  if (g == 610) {
    emit_control_mode(ControlMode::ExactPath, 0.0);
  } else if (g == 611) {
    emit_control_mode(ControlMode::ExactStop, 0.0);
  } else {
    // G64 P (path tolerance) Q (naive CAM tolerance); an absent or negative value counts as none.
    const double p = b.has('P') ? b['P'] : -1.0;
    const double q = b.has('Q') ? b['Q'] : -1.0;
    emit_control_mode(ControlMode::Continuous, p >= 0.0 ? p : 0.0);
    naivecam_tolerance_ = q >= 0.0 ? q : p >= 0.0 ? p : 0.0;
    canon_.print("SET_NAIVECAM_TOLERANCE(%.4f)", naivecam_tolerance_);
  }
}

bool Interpreter::stop(const Block& b) {
  const int m = b.m_mode[4];
  if (m == -1) return false;
  if (m == 0) {
    canon_.print("PROGRAM_STOP()");
    return false;
  }
  if (m == 60) {
    canon_.print("PALLET_SHUTTLE()");
    canon_.print("PROGRAM_STOP()");
    return false;
  }
  if (m == 1) {
    canon_.print("OPTIONAL_PROGRAM_STOP()");
    return false;
  }
  // M2 / M30: LinuxCNC's resets (convert_stop), in its order.
  for (std::size_t i = 0; i < 6; ++i) pos_[i] += origin_offset_[i];
  rotate(pos_[0], pos_[1], rotation_xy_);
  origin_index_ = 1;
  params_[5220] = 1.0;
  for (std::size_t i = 0; i < 6; ++i) origin_offset_[i] = i < 3 ? from_user_len(params_[5221 + i]) : params_[5221 + i];
  rotation_xy_ = params_[5230];
  rotate(pos_[0], pos_[1], -rotation_xy_);
  for (std::size_t i = 0; i < 6; ++i) pos_[i] -= origin_offset_[i];
  canon_.print("SET_G5X_OFFSET(%d, %.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", 1, origin_offset_[0], origin_offset_[1],
               origin_offset_[2], origin_offset_[3], origin_offset_[4], origin_offset_[5]);
  canon_.print("SET_XY_ROTATION(%.4f)", rotation_xy_);
  if (plane_ != Plane::XY) {
    canon_.print("SELECT_PLANE(CANON_PLANE_XY)");
    plane_ = Plane::XY;
  }
  absolute_ = true;
  inverse_time_ = false;
  canon_.print("SET_FEED_MODE(0, 0)");
  feed_rate_ = 0.0;
  canon_.print("SET_FEED_RATE(%.4f)", 0.0);
  if (!feed_override_) {
    canon_.print("ENABLE_FEED_OVERRIDE()");
    feed_override_ = true;
  }
  speed_override_ = true;  // re-enabled too, but rs274 (2.9) prints no call for it
  canon_.print("STOP_SPINDLE_TURNING(0)");
  spindle_ = 0;
  canon_.print("SET_SPINDLE_MODE(0 %.4f)", 0.0);
  motion_mode_ = 10;
  if (mist_) {
    canon_.print("MIST_OFF()");
    mist_ = false;
  }
  if (flood_) {
    canon_.print("FLOOD_OFF()");
    flood_ = false;
  }
  if (m == 30) canon_.print("PALLET_SHUTTLE()");
  canon_.print("PROGRAM_END()");
  if (percent_mode_ && end_line_ >= prog_.lines.size())
    canon_.print("COMMENT(\"%s\")", "interpreter: percent sign missing from end of file");
  return true;
}

}  // namespace vmsim::program::gcode
