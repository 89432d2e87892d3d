// Block execution: evaluation of a line, LinuxCNC's modal groups and checks, and every non-motion code in
// LinuxCNC's order of execution (comment, feed mode, F, S, T, M codes, G codes, stops).
#include "core/gcode_interp.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace vmsim::core::gcode {

namespace {

constexpr double kMmPerInch = 25.4;

// LinuxCNC's predefined named parameters (#<_x>, #<_metric>, ...): read-only, computed when read.
enum class PredefKind : std::uint8_t {
  None, X, Y, Z, A, B, C, U, V, W, Line, MotionMode, Plane, Ccomp, Metric, Imperial, Absolute, Incremental,
  InverseTime, UnitsPerMinute, UnitsPerRev, CoordSystem, ToolOffset, RetractRPlane, RetractOldZ, SpindleRpmMode,
  SpindleCssMode, IjkAbsolute, LatheDiameter, LatheRadius, SpindleOn, SpindleCw, Mist, Flood, SpeedOverride,
  FeedOverride, AdaptiveFeed, FeedHold, Feed, Rpm, CurrentTool, CurrentPocket, SelectedTool, SelectedPocket,
  CallLevel, RemapLevel, Task, VMajor, VMinor
};

struct PredefName {
  const char* name;
  PredefKind kind;
};
constexpr PredefName kPredef[] = {
    {"_x", PredefKind::X}, {"_y", PredefKind::Y}, {"_z", PredefKind::Z}, {"_a", PredefKind::A},
    {"_b", PredefKind::B}, {"_c", PredefKind::C}, {"_u", PredefKind::U}, {"_v", PredefKind::V},
    {"_w", PredefKind::W}, {"_line", PredefKind::Line}, {"_motion_mode", PredefKind::MotionMode},
    {"_plane", PredefKind::Plane}, {"_ccomp", PredefKind::Ccomp}, {"_metric", PredefKind::Metric},
    {"_imperial", PredefKind::Imperial}, {"_absolute", PredefKind::Absolute},
    {"_incremental", PredefKind::Incremental}, {"_inverse_time", PredefKind::InverseTime},
    {"_units_per_minute", PredefKind::UnitsPerMinute}, {"_units_per_rev", PredefKind::UnitsPerRev},
    {"_coord_system", PredefKind::CoordSystem}, {"_tool_offset", PredefKind::ToolOffset},
    {"_retract_r_plane", PredefKind::RetractRPlane}, {"_retract_old_z", PredefKind::RetractOldZ},
    {"_spindle_rpm_mode", PredefKind::SpindleRpmMode}, {"_spindle_css_mode", PredefKind::SpindleCssMode},
    {"_ijk_absolute_mode", PredefKind::IjkAbsolute}, {"_lathe_diameter_mode", PredefKind::LatheDiameter},
    {"_lathe_radius_mode", PredefKind::LatheRadius}, {"_spindle_on", PredefKind::SpindleOn},
    {"_spindle_cw", PredefKind::SpindleCw}, {"_mist", PredefKind::Mist}, {"_flood", PredefKind::Flood},
    {"_speed_override", PredefKind::SpeedOverride}, {"_feed_override", PredefKind::FeedOverride},
    {"_adaptive_feed", PredefKind::AdaptiveFeed}, {"_feed_hold", PredefKind::FeedHold},
    {"_feed", PredefKind::Feed}, {"_rpm", PredefKind::Rpm}, {"_current_tool", PredefKind::CurrentTool},
    {"_current_pocket", PredefKind::CurrentPocket}, {"_selected_tool", PredefKind::SelectedTool},
    {"_selected_pocket", PredefKind::SelectedPocket}, {"_call_level", PredefKind::CallLevel},
    {"_remap_level", PredefKind::RemapLevel}, {"_task", PredefKind::Task}, {"_vmajor", PredefKind::VMajor},
    {"_vminor", PredefKind::VMinor},
};

// Modal groups of the G codes vmsim executes (LinuxCNC's numbering), -1 for anything else.
int g_group(int g) {
  switch (g) {
    case 40: case 100: case 280: case 281: case 300: case 301: case 520: case 530:
    case 920: case 921: case 922: case 923: return 0;
    case 0: case 10: case 20: case 30: case 730: case 800: case 810: case 820: case 830: case 850: case 890:
      return 1;
    case 170: case 180: case 190: return 2;
    case 900: case 910: return 3;
    case 901: case 911: return 4;
    case 930: case 940: return 5;
    case 200: case 210: return 6;
    case 400: return 7;
    case 430: case 431: case 432: case 490: return 8;
    case 980: case 990: return 10;
    case 540: case 550: case 560: case 570: case 580: case 590: case 591: case 592: case 593: return 12;
    case 610: case 611: case 640: return 13;
    case 960: case 970: return 14;
    default: return -1;
  }
}

const char* g_group_name(int group) {
  switch (group) {
    case 0: return "non-modal";
    case 1: return "motion";
    case 2: return "plane selection";
    case 3: return "distance mode";
    case 4: return "arc centre mode";
    case 5: return "feed mode";
    case 6: return "units";
    case 7: return "cutter compensation";
    case 8: return "tool length offset";
    case 10: return "canned cycle return";
    case 12: return "coordinate system";
    case 13: return "path control";
    case 14: return "spindle mode";
    default: return "?";
  }
}

// Why a G code LinuxCNC knows is not executed; nullptr if it is not one of those.
const char* g_unsupported(int g) {
  switch (g) {
    case 410: case 420: case 411: case 421:
      return "(cutter radius compensation) is not supported; post the program for the tool centre path "
             "(vmsim follows the programmed point) and use G40";
    case 50: case 51: case 52: case 53: return "(spline / NURBS motion) is not supported";
    case 70: case 80: return "(lathe diameter/radius mode) is not supported";
    case 330: case 331: case 760: return "(spindle-synchronised motion / threading) is not supported";
    case 382: case 383: case 384: case 385:
      return "(probing) is not supported: where the probe stops is not known before the machine runs";
    case 171: case 181: case 191: return "(U V W arc planes) is not supported";
    case 700: case 710: case 711: case 720: case 721: return "(lathe cycle) is not supported";
    case 740: case 840: case 860: case 870: case 880:
      return "(canned cycle) is not supported; vmsim executes G73 G81 G82 G83 G85 G89";
    case 950: return "(feed per revolution) is not supported; use G94 (units per minute) or G93 (inverse time)";
    default: return nullptr;
  }
}

int m_group(int m) {
  switch (m) {
    case 0: case 1: case 2: case 30: case 60: return 4;
    case 6: case 61: return 6;
    case 3: case 4: case 5: return 7;
    case 7: case 8: case 9: return 8;
    case 48: case 49: case 50: case 51: case 52: case 53: return 9;
    default: return -1;
  }
}

const char* m_unsupported(int m) {
  if (m == 19) return "(spindle orientation) is not supported";
  if (m >= 62 && m <= 68) return "(digital/analog I/O) is not supported";
  if (m >= 70 && m <= 73) return "(saving/restoring modal state) is not supported";
  if (m == 98 || m == 99) return "(Fanuc-style subroutine call/return) is not supported; use O-word subroutines";
  if (m >= 100 && m <= 199)
    return "is a user-defined M code; if it makes no motion, accept it with --no-motion-m (GcodeOptions::no_motion_mcodes)";
  return nullptr;
}

bool is_cycle(int g) { return g == 730 || g == 810 || g == 820 || g == 830 || g == 850 || g == 890; }

std::string fmt_num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// "G1", "T2.5": built by appending (GCC 12 warns falsely on "literal" + std::string temporaries).
std::string word(char letter, double v) {
  std::string s(1, letter);
  s += fmt_num(v);
  return s;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Construction and parameters

Interpreter::Interpreter(const ParsedProgram& program, std::string file, const GcodeOptions& options,
                         const ToolTable* tools)
    : prog_(program),
      file_(std::move(file)),
      options_(options),
      tools_(tools),
      params_(kNumParams, 0.0),
      globals_(program.names.size()),
      canon_(options.max_canon_calls, file_) {
  predef_.assign(program.names.size(), 0);
  for (std::size_t id = 0; id < program.names.size(); ++id)
    for (const PredefName& p : kPredef)
      if (program.names.name(static_cast<int>(id)) == p.name) predef_[id] = static_cast<std::uint8_t>(p.kind);
  // Globals the interpreter sets on subroutine returns (only names the program uses are interned).
  for (std::size_t id = 0; id < program.names.size(); ++id) {
    const std::string& name = program.names.name(static_cast<int>(id));
    if (name == "_value") value_id_ = static_cast<int>(id);
    if (name == "_value_returned") value_returned_id_ = static_cast<int>(id);
    if (name == "_value" || name == "_value_returned") globals_[id] = 0.0;
  }
  params_[5220] = 1.0;  // G54 active
  params_[5599] = 1.0;  // (debug, ...) messages on, as in LinuxCNC
  path_.source_path = file_;
  frames_.emplace_back();  // the main program's frame (its named locals, its repeat counters)
}

void Interpreter::fail(const std::string& message) const {
  const int number = line_ < prog_.lines.size() ? prog_.lines[line_].number : 0;
  throw Error(located(file_, number, message));
}

std::string Interpreter::g_name(int g10) const {
  std::string s = word('G', g10 / 10);
  if (g10 % 10) {
    s += '.';
    s += std::to_string(g10 % 10);
  }
  return s;
}

double Interpreter::numbered(double index) const {
  const double r = std::nearbyint(index);
  if (std::fabs(r - index) > 1e-4) throw ExprError("parameter number #" + fmt_num(index) + " is not a whole number");
  if (r < 1.0 || r >= kNumParams)
    throw ExprError("parameter number #" + fmt_num(index) + " is out of range (1 to " + std::to_string(kNumParams - 1) + ")");
  const int i = static_cast<int>(r);
  if (i >= 5420 && i <= 5428) return i <= 5425 ? pos_[static_cast<std::size_t>(i - 5420)] : 0.0;
  if (i >= 5400 && i <= 5413) {
    if (i == 5400) return current_tool_;
    const ToolEntry* t = tools_ != nullptr && current_tool_ != 0 ? tools_->find(current_tool_) : nullptr;
    if (t == nullptr) return 0.0;
    if (i >= 5401 && i <= 5406) return t->offset[i - 5401];
    if (i == 5410) return t->diameter;
    return 0.0;
  }
  return params_[static_cast<std::size_t>(i)];
}

double Interpreter::named(int id) const {
  const auto kind = static_cast<PredefKind>(predef_[static_cast<std::size_t>(id)]);
  const auto flag = [](bool b) { return b ? 1.0 : 0.0; };
  switch (kind) {
    case PredefKind::None: break;
    case PredefKind::X: return pos_[0];
    case PredefKind::Y: return pos_[1];
    case PredefKind::Z: return pos_[2];
    case PredefKind::A: return pos_[3];
    case PredefKind::B: return pos_[4];
    case PredefKind::C: return pos_[5];
    case PredefKind::U:
    case PredefKind::V:
    case PredefKind::W: return 0.0;
    case PredefKind::Line: return line_ < prog_.lines.size() ? prog_.lines[line_].number : 0;
    case PredefKind::MotionMode: return motion_mode_;
    case PredefKind::Plane: return plane_ == Plane::XY ? 170 : plane_ == Plane::XZ ? 180 : 190;
    case PredefKind::Ccomp: return 400;
    case PredefKind::Metric: return flag(!inch_);
    case PredefKind::Imperial: return flag(inch_);
    case PredefKind::Absolute: return flag(absolute_);
    case PredefKind::Incremental: return flag(!absolute_);
    case PredefKind::InverseTime: return flag(inverse_time_);
    case PredefKind::UnitsPerMinute: return flag(!inverse_time_);
    case PredefKind::UnitsPerRev: return 0.0;
    case PredefKind::CoordSystem: {
      static constexpr int kCodes[] = {540, 550, 560, 570, 580, 590, 591, 592, 593};
      return kCodes[origin_index_ - 1];
    }
    case PredefKind::ToolOffset: return flag(tlo_active_);
    case PredefKind::RetractRPlane: return flag(retract_r_plane_);
    case PredefKind::RetractOldZ: return flag(!retract_r_plane_);
    case PredefKind::SpindleRpmMode: return 1.0;
    case PredefKind::SpindleCssMode: return 0.0;
    case PredefKind::IjkAbsolute: return flag(ijk_absolute_);
    case PredefKind::LatheDiameter: return 0.0;
    case PredefKind::LatheRadius: return 1.0;
    case PredefKind::SpindleOn: return flag(spindle_ != 0);
    case PredefKind::SpindleCw: return flag(spindle_ == 1);
    case PredefKind::Mist: return flag(mist_);
    case PredefKind::Flood: return flag(flood_);
    case PredefKind::SpeedOverride: return flag(speed_override_);
    case PredefKind::FeedOverride: return flag(feed_override_);
    case PredefKind::AdaptiveFeed: return 0.0;
    case PredefKind::FeedHold: return 1.0;
    case PredefKind::Feed: return feed_rate_;
    case PredefKind::Rpm: return speed_;
    case PredefKind::CurrentTool:
    case PredefKind::CurrentPocket: return current_tool_;
    case PredefKind::SelectedTool:
    case PredefKind::SelectedPocket: return selected_tool_;
    case PredefKind::CallLevel: return static_cast<double>(frames_.size() - 1);
    case PredefKind::RemapLevel: return 0.0;
    // A simulated run is the machine's run (LinuxCNC's task), not a preview.
    case PredefKind::Task: return 1.0;
    case PredefKind::VMajor: return 2.0;
    case PredefKind::VMinor: return 9.0;
  }
  const std::string& name = prog_.names.name(id);
  if (name[0] == '_') {
    const auto& g = globals_[static_cast<std::size_t>(id)];
    if (!g) throw ExprError("named parameter #<" + name + "> is not defined");
    return *g;
  }
  const auto& locals = frames_.back().locals;
  const auto it = locals.find(id);
  if (it == locals.end()) throw ExprError("named parameter #<" + name + "> is not defined");
  return it->second;
}

bool Interpreter::exists(int id) const {
  if (static_cast<PredefKind>(predef_[static_cast<std::size_t>(id)]) != PredefKind::None) return true;
  if (prog_.names.name(id)[0] == '_') return globals_[static_cast<std::size_t>(id)].has_value();
  return frames_.back().locals.contains(id);
}

void Interpreter::apply_assignments(const SourceLine& line) {
  // LinuxCNC reads the whole line first (every value with the old parameters), then sets the parameters.
  struct Pending {
    int name;
    int index;
    double value;
  };
  if (line.assignments.empty()) return;
  // Up to 8 settings on the stack (loops run these lines millions of times), more on the heap.
  std::array<Pending, 8> small{};
  std::vector<Pending> large;
  const bool fits = line.assignments.size() <= small.size();
  if (!fits) large.resize(line.assignments.size());
  Pending* pending = fits ? small.data() : large.data();
  std::size_t n = 0;
  for (const Assignment& a : line.assignments) {
    Pending p{a.name, 0, 0.0};
    try {
      if (a.name < 0) {
        const double idx = prog_.exprs.evaluate(a.index, *this);
        const double r = std::nearbyint(idx);
        if (std::fabs(r - idx) > 1e-4) throw ExprError("parameter number #" + fmt_num(idx) + " is not a whole number");
        if (r < 1.0 || r >= kNumParams)
          throw ExprError("parameter number #" + fmt_num(idx) + " is out of range (1 to 5601)");
        p.index = static_cast<int>(r);
        if (p.index >= 5400 && p.index <= 5428) throw ExprError("parameter #" + std::to_string(p.index) + " is read-only");
      } else if (static_cast<PredefKind>(predef_[static_cast<std::size_t>(a.name)]) != PredefKind::None) {
        throw ExprError("#<" + prog_.names.name(a.name) + "> is a read-only predefined parameter");
      }
      p.value = prog_.exprs.evaluate(a.value, *this);
    } catch (const ExprError& e) {
      const std::string target = a.name >= 0 ? "#<" + prog_.names.name(a.name) + ">" : "#" + (p.index ? std::to_string(p.index) : std::string("..."));
      fail("setting " + target + ": " + e.what());
    }
    pending[n++] = p;
  }
  for (std::size_t k = 0; k < n; ++k) {
    const Pending& p = pending[k];
    if (p.name < 0) {
      params_[static_cast<std::size_t>(p.index)] = p.value;
    } else if (prog_.names.name(p.name)[0] == '_') {
      globals_[static_cast<std::size_t>(p.name)] = p.value;
    } else {
      frames_.back().locals[p.name] = p.value;
    }
  }
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
      fail(word('M', m) + " is not an M code LinuxCNC knows; if the machine remaps it to an action without motion, "
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
    feed_linear_mm_ = feed_rate_ * (inch_ ? kMmPerInch : 1.0);
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
  for (std::size_t i = start; i < text.size(); ++i) lc += static_cast<char>(std::tolower(static_cast<unsigned char>(text[i])));
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
          if (!std::isspace(static_cast<unsigned char>(s[k]))) name += static_cast<char>(std::tolower(static_cast<unsigned char>(s[k])));
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
  if (t == nullptr) fail(std::string(what) + ": tool " + std::to_string(number) + " is not in the tool table " + tools_->source_path);
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
    default: break;
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
    default: break;
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
    case 52: canon_.print(enable ? "ENABLE_ADAPTIVE_FEED()" : "DISABLE_ADAPTIVE_FEED()"); break;
    case 53: canon_.print(enable ? "ENABLE_FEED_HOLD()" : "DISABLE_FEED_HOLD()"); break;
    default: break;
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
    case 100: setup_g10(b); break;
    case 280:
    case 300: home(b.g_mode[0], b); break;
    case 281:
    case 301: save_home(b.g_mode[0]); break;
    case 520:
    case 920:
    case 921:
    case 922:
    case 923: axis_offsets(b.g_mode[0], b); break;
    default: break;
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
  const double f = inch ? 1.0 / kMmPerInch : kMmPerInch;
  inch_ = inch;
  for (int i = 0; i < 3; ++i) {
    pos_[static_cast<std::size_t>(i)] *= f;
    axis_offset_[static_cast<std::size_t>(i)] *= f;
    origin_offset_[static_cast<std::size_t>(i)] *= f;
    tool_offset_[static_cast<std::size_t>(i)] *= f;
  }
  feed_rate_ *= f;
}

double Interpreter::to_user_len(double v) const {
  if (options_.inch_machine == inch_) return v;
  return options_.inch_machine ? v / kMmPerInch : v * kMmPerInch;
}

double Interpreter::from_user_len(double v) const {
  if (options_.inch_machine == inch_) return v;
  return options_.inch_machine ? v * kMmPerInch : v / kMmPerInch;
}

double Interpreter::tool_offset_prog(const ToolEntry* t, int axis) const {
  if (t == nullptr) return 0.0;
  return axis < 3 ? from_user_len(t->offset[axis]) : t->offset[axis];
}

void Interpreter::tool_length_offset(int g, const Block& b) {
  Pos next{};
  if (g == 430 || g == 432) {
    int tool = current_tool_;
    if (b.has('H')) {
      const double h = b['H'];
      if (h < 0 || h != std::floor(h) || h > 1e9) fail("G43 H" + fmt_num(h) + ": H must be a tool number (0 or more)");
      // H0 means the tool in the spindle (LinuxCNC's pocket 0).
      if (h != 0.0) tool = static_cast<int>(h);
    } else if (g == 432) {
      fail("G43.2 needs an H word");
    }
    const ToolEntry* t = tool_entry(tool, g_name(g).c_str());
    if (g == 432) next = tool_offset_;
    for (int i = 0; i < 6; ++i) next[static_cast<std::size_t>(i)] += tool_offset_prog(t, i);
  } else if (g == 431) {
    next = tool_offset_;
    static constexpr char kAxes[] = "XYZABC";
    for (int i = 0; i < 6; ++i)
      if (b.has(kAxes[i])) next[static_cast<std::size_t>(i)] = b[kAxes[i]];
  }
  for (int i : {0, 1, 3, 4, 5})
    if (next[static_cast<std::size_t>(i)] != 0.0)
      fail(g_name(g) + ": tool offsets along " + std::string(1, "XYZABC"[i]) +
           " are not supported (only Z tool length offsets)");
  canon_.print("USE_TOOL_LENGTH_OFFSET(%.4f %.4f %.4f, %.4f %.4f %.4f, %.4f %.4f %.4f)", next[0], next[1], next[2],
               next[3], next[4], next[5], 0.0, 0.0, 0.0);
  // The controlled point moves with the offset; the machine does not (convert_tool_length_offset).
  double dx = tool_offset_[0] - next[0];
  double dy = tool_offset_[1] - next[1];
  rotate(dx, dy, -rotation_xy_);
  pos_[0] += dx;
  pos_[1] += dy;
  for (std::size_t i = 2; i < 6; ++i) pos_[i] += tool_offset_[i] - next[i];
  tool_offset_ = next;
  tlo_active_ = g != 490;
}

void Interpreter::rotate(double& x, double& y, double deg) {
  const double t = deg * std::numbers::pi / 180.0;  // LinuxCNC's D2R
  const double xx = x * std::cos(t) - y * std::sin(t);
  const double yy = x * std::sin(t) + y * std::cos(t);
  x = xx;
  y = yy;
}

void Interpreter::current_in_system(int system, Pos& p) const {
  // Where the current point would be in another coordinate system (find_current_in_system).
  p = pos_;
  for (std::size_t i = 0; i < 6; ++i) p[i] += axis_offset_[i];
  rotate(p[0], p[1], rotation_xy_);
  for (std::size_t i = 0; i < 6; ++i) p[i] += origin_offset_[i];
  const std::size_t base = 5201 + static_cast<std::size_t>(system) * 20;
  for (std::size_t i = 0; i < 6; ++i) {
    const double off = params_[base + i];
    p[i] -= i < 3 ? from_user_len(off) : off;
  }
  rotate(p[0], p[1], -params_[5210 + static_cast<std::size_t>(system) * 20]);
  if (params_[5210] != 0.0)
    for (std::size_t i = 0; i < 6; ++i) p[i] -= i < 3 ? from_user_len(params_[5211 + i]) : params_[5211 + i];
}

void Interpreter::coordinate_system(int g) {
  static constexpr int kCodes[] = {540, 550, 560, 570, 580, 590, 591, 592, 593};
  const int origin = static_cast<int>(std::find(std::begin(kCodes), std::end(kCodes), g) - std::begin(kCodes)) + 1;
  if (origin == origin_index_) {
    canon_.print("COMMENT(\"%s\")", "interpreter: continuing to use same coordinate system");
    return;
  }
  current_in_system(origin, pos_);
  origin_index_ = origin;
  params_[5220] = origin;
  const std::size_t base = 5201 + static_cast<std::size_t>(origin) * 20;
  for (std::size_t i = 0; i < 6; ++i) origin_offset_[i] = i < 3 ? from_user_len(params_[base + i]) : params_[base + i];
  rotation_xy_ = params_[base + 9];
  canon_.print("SET_G5X_OFFSET(%d, %.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", origin, origin_offset_[0], origin_offset_[1],
               origin_offset_[2], origin_offset_[3], origin_offset_[4], origin_offset_[5]);
  canon_.print("SET_G92_OFFSET(%.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", axis_offset_[0], axis_offset_[1], axis_offset_[2],
               axis_offset_[3], axis_offset_[4], axis_offset_[5]);
  canon_.print("SET_XY_ROTATION(%.4f)", rotation_xy_);
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

void Interpreter::setup_g10(const Block& b) {
  if (!b.has('L')) fail("G10 needs an L word (L2 or L20: set a coordinate system)");
  const double l = b['L'];
  if (l == 1.0 || l == 10.0 || l == 11.0) fail("G10 L" + fmt_num(l) + " (tool table editing) is not supported");
  if (l != 2.0 && l != 20.0) fail("G10 L" + fmt_num(l) + " is not supported (G10 L2 and G10 L20 are)");
  const bool l20 = l == 20.0;
  const double pw = b.has('P') ? b['P'] : -1.0;
  int p = static_cast<int>(std::clamp(pw, -1.0, 100.0) + 0.0001);
  if (pw < 0.0) p = 0;
  if (p < 0 || p > 9) fail("G10 L" + fmt_num(l) + " P" + fmt_num(pw) + ": P must be 0 (active system) to 9 (G59.3)");
  if (p == 0) p = origin_index_;
  Pos cur{};
  current_in_system(p, cur);
  const std::size_t base = 5201 + static_cast<std::size_t>(p) * 20;
  double r = 0.0;
  if (b.has('R')) {
    if (l20) fail("G10 L20 does not take an R word");
    r = b['R'];
    params_[base + 9] = r;
  } else {
    r = params_[base + 9];
  }
  double x = 0, y = 0;
  if (l20) {
    double oldx = cur[0], oldy = cur[1];
    x = b.has('X') ? b['X'] : cur[0];
    y = b.has('Y') ? b['Y'] : cur[1];
    rotate(oldx, oldy, r);
    rotate(x, y, r);
    x = oldx + from_user_len(params_[base + 0]) - x;
    y = oldy + from_user_len(params_[base + 1]) - y;
    params_[base + 0] = to_user_len(x);
    params_[base + 1] = to_user_len(y);
    if (p == origin_index_) {
      rotate(pos_[0], pos_[1], rotation_xy_);
      rotation_xy_ = 0.0;
    }
  } else {
    if (b.has('X')) params_[base + 0] = to_user_len(b['X']);
    if (b.has('Y')) params_[base + 1] = to_user_len(b['Y']);
    x = from_user_len(params_[base + 0]);
    y = from_user_len(params_[base + 1]);
  }
  Pos off{x, y, 0, 0, 0, 0};
  static constexpr char kAxes[] = "XYZABC";
  for (std::size_t i = 2; i < 6; ++i) {
    const bool len = i < 3;
    if (b.has(kAxes[i])) {
      double v = b[kAxes[i]];
      if (l20) v = cur[i] + (len ? from_user_len(params_[base + i]) : params_[base + i]) - v;
      params_[base + i] = len ? to_user_len(v) : v;
      off[i] = v;
    } else {
      off[i] = len ? from_user_len(params_[base + i]) : params_[base + i];
    }
  }
  if (p == origin_index_) {
    rotate(pos_[0], pos_[1], rotation_xy_);
    for (std::size_t i = 0; i < 6; ++i) pos_[i] += origin_offset_[i] - off[i];
    origin_offset_ = off;
    canon_.print("SET_G5X_OFFSET(%d, %.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", p, off[0], off[1], off[2], off[3], off[4],
                 off[5]);
    rotate(pos_[0], pos_[1], -r);
    rotation_xy_ = r;
    canon_.print("SET_XY_ROTATION(%.4f)", rotation_xy_);
  } else {
    canon_.print("COMMENT(\"%s\")", "interpreter: setting coordinate system origin");
  }
}

void Interpreter::axis_offsets(int g, const Block& b) {
  static constexpr char kAxes[] = "XYZABC";
  if (g == 520 || g == 920) {
    params_[5210] = 1.0;
    for (std::size_t i = 0; i < 6; ++i) {
      if (!b.has(kAxes[i])) continue;
      const double v = b[kAxes[i]];
      if (g == 520) {  // G52: the local offset itself
        pos_[i] += axis_offset_[i] - v;
        axis_offset_[i] = v;
      } else {  // G92: the offset that makes the current point read v
        axis_offset_[i] = pos_[i] + axis_offset_[i] - v;
        pos_[i] = v;
      }
    }
    for (std::size_t i = 0; i < 6; ++i) params_[5211 + i] = i < 3 ? to_user_len(axis_offset_[i]) : axis_offset_[i];
  } else if (g == 921 || g == 922) {
    params_[5210] = 0.0;
    for (std::size_t i = 0; i < 6; ++i) {
      pos_[i] += axis_offset_[i];
      axis_offset_[i] = 0.0;
    }
    if (g == 921)
      for (std::size_t i = 0; i < 6; ++i) params_[5211 + i] = 0.0;
  } else {  // G92.3: back to the offsets kept in the parameters
    params_[5210] = 1.0;
    for (std::size_t i = 0; i < 6; ++i) {
      const double v = i < 3 ? from_user_len(params_[5211 + i]) : params_[5211 + i];
      pos_[i] += axis_offset_[i] - v;
      axis_offset_[i] = v;
    }
  }
  canon_.print("SET_G92_OFFSET(%.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", axis_offset_[0], axis_offset_[1],
               axis_offset_[2], axis_offset_[3], axis_offset_[4], axis_offset_[5]);
}

void Interpreter::save_home(int g) {
  // G28.1 / G30.1: the current point in machine coordinates, in machine units (convert_savehome). Unlike
  // LinuxCNC 2.9 this applies the XY rotation (G10 L2 R), the inverse of what G28/G30 do with the point, so
  // the stored point is where the machine is.
  Pos m{};
  for (std::size_t i = 0; i < 6; ++i) m[i] = pos_[i] + axis_offset_[i];
  rotate(m[0], m[1], rotation_xy_);
  for (std::size_t i = 0; i < 6; ++i) m[i] += tool_offset_[i] + origin_offset_[i];
  const std::size_t base = g == 281 ? 5161 : 5181;
  for (std::size_t i = 0; i < 6; ++i) params_[base + i] = i < 3 ? to_user_len(m[i]) : m[i];
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

}  // namespace vmsim::core::gcode
