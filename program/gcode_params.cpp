// Parameters: numbered (#1..#5601, with the computed ones LinuxCNC derives from the state), named (locals of
// the call level, globals with a leading '_', the predefined read-only #<_x>, #<_metric>, ...), and the
// read-then-set rule of a line's parameter settings.
#include "program/gcode_interp.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace vmsim::program::gcode {

namespace {

// LinuxCNC's predefined named parameters (#<_x>, #<_metric>, ...): read-only, computed when read.
enum class PredefKind : std::uint8_t {
  None,
  X,
  Y,
  Z,
  A,
  B,
  C,
  U,
  V,
  W,
  Line,
  MotionMode,
  Plane,
  Ccomp,
  Metric,
  Imperial,
  Absolute,
  Incremental,
  InverseTime,
  UnitsPerMinute,
  UnitsPerRev,
  CoordSystem,
  ToolOffset,
  RetractRPlane,
  RetractOldZ,
  SpindleRpmMode,
  SpindleCssMode,
  IjkAbsolute,
  LatheDiameter,
  LatheRadius,
  SpindleOn,
  SpindleCw,
  Mist,
  Flood,
  SpeedOverride,
  FeedOverride,
  AdaptiveFeed,
  FeedHold,
  Feed,
  Rpm,
  CurrentTool,
  CurrentPocket,
  SelectedTool,
  SelectedPocket,
  CallLevel,
  RemapLevel,
  Task,
  VMajor,
  VMinor
};

struct PredefName {
  const char* name;
  PredefKind kind;
};
constexpr PredefName kPredef[] = {
    {"_x", PredefKind::X},
    {"_y", PredefKind::Y},
    {"_z", PredefKind::Z},
    {"_a", PredefKind::A},
    {"_b", PredefKind::B},
    {"_c", PredefKind::C},
    {"_u", PredefKind::U},
    {"_v", PredefKind::V},
    {"_w", PredefKind::W},
    {"_line", PredefKind::Line},
    {"_motion_mode", PredefKind::MotionMode},
    {"_plane", PredefKind::Plane},
    {"_ccomp", PredefKind::Ccomp},
    {"_metric", PredefKind::Metric},
    {"_imperial", PredefKind::Imperial},
    {"_absolute", PredefKind::Absolute},
    {"_incremental", PredefKind::Incremental},
    {"_inverse_time", PredefKind::InverseTime},
    {"_units_per_minute", PredefKind::UnitsPerMinute},
    {"_units_per_rev", PredefKind::UnitsPerRev},
    {"_coord_system", PredefKind::CoordSystem},
    {"_tool_offset", PredefKind::ToolOffset},
    {"_retract_r_plane", PredefKind::RetractRPlane},
    {"_retract_old_z", PredefKind::RetractOldZ},
    {"_spindle_rpm_mode", PredefKind::SpindleRpmMode},
    {"_spindle_css_mode", PredefKind::SpindleCssMode},
    {"_ijk_absolute_mode", PredefKind::IjkAbsolute},
    {"_lathe_diameter_mode", PredefKind::LatheDiameter},
    {"_lathe_radius_mode", PredefKind::LatheRadius},
    {"_spindle_on", PredefKind::SpindleOn},
    {"_spindle_cw", PredefKind::SpindleCw},
    {"_mist", PredefKind::Mist},
    {"_flood", PredefKind::Flood},
    {"_speed_override", PredefKind::SpeedOverride},
    {"_feed_override", PredefKind::FeedOverride},
    {"_adaptive_feed", PredefKind::AdaptiveFeed},
    {"_feed_hold", PredefKind::FeedHold},
    {"_feed", PredefKind::Feed},
    {"_rpm", PredefKind::Rpm},
    {"_current_tool", PredefKind::CurrentTool},
    {"_current_pocket", PredefKind::CurrentPocket},
    {"_selected_tool", PredefKind::SelectedTool},
    {"_selected_pocket", PredefKind::SelectedPocket},
    {"_call_level", PredefKind::CallLevel},
    {"_remap_level", PredefKind::RemapLevel},
    {"_task", PredefKind::Task},
    {"_vmajor", PredefKind::VMajor},
    {"_vminor", PredefKind::VMinor},
};

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
      // Straight-line code makes at most a few calls per line; the budget on top is what loops may add.
      canon_(options.max_canon_calls + std::min<std::size_t>(program.lines.size(), SIZE_MAX / 32) * 16, file_) {
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
  if (options.start_mm)
    for (std::size_t i = 0; i < 3; ++i) pos_[i] = (*options.start_mm)[i];  // programs start in G21: mm
  params_[5220] = 1.0;                                                     // G54 active
  params_[5599] = 1.0;                                                     // (debug, ...) messages on, as in LinuxCNC
  path_.source_path = file_;
  frames_.emplace_back();  // the main program's frame (its named locals, its repeat counters)
}

double Interpreter::numbered(double index) const {
  const double r = std::nearbyint(index);
  if (std::fabs(r - index) > 1e-4) throw ExprError("parameter number #" + fmt_num(index) + " is not a whole number");
  if (r < 1.0 || r >= kNumParams)
    throw ExprError("parameter number #" + fmt_num(index) + " is out of range (1 to " + std::to_string(kNumParams - 1) +
                    ")");
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
    case PredefKind::None:
      break;
    case PredefKind::X:
      return pos_[0];
    case PredefKind::Y:
      return pos_[1];
    case PredefKind::Z:
      return pos_[2];
    case PredefKind::A:
      return pos_[3];
    case PredefKind::B:
      return pos_[4];
    case PredefKind::C:
      return pos_[5];
    case PredefKind::U:
    case PredefKind::V:
    case PredefKind::W:
      return 0.0;
    case PredefKind::Line:
      return line_ < prog_.lines.size() ? prog_.lines[line_].number : 0;
    case PredefKind::MotionMode:
      return motion_mode_;
    case PredefKind::Plane:
      return plane_ == Plane::XY ? 170 : plane_ == Plane::XZ ? 180 : 190;
    case PredefKind::Ccomp:
      return 400;
    case PredefKind::Metric:
      return flag(!inch_);
    case PredefKind::Imperial:
      return flag(inch_);
    case PredefKind::Absolute:
      return flag(absolute_);
    case PredefKind::Incremental:
      return flag(!absolute_);
    case PredefKind::InverseTime:
      return flag(inverse_time_);
    case PredefKind::UnitsPerMinute:
      return flag(!inverse_time_);
    case PredefKind::UnitsPerRev:
      return 0.0;
    case PredefKind::CoordSystem: {
      static constexpr int kCodes[] = {540, 550, 560, 570, 580, 590, 591, 592, 593};
      return kCodes[origin_index_ - 1];
    }
    case PredefKind::ToolOffset:
      return flag(tlo_active_);
    case PredefKind::RetractRPlane:
      return flag(retract_r_plane_);
    case PredefKind::RetractOldZ:
      return flag(!retract_r_plane_);
    case PredefKind::SpindleRpmMode:
      return 1.0;
    case PredefKind::SpindleCssMode:
      return 0.0;
    case PredefKind::IjkAbsolute:
      return flag(ijk_absolute_);
    case PredefKind::LatheDiameter:
      return 0.0;
    case PredefKind::LatheRadius:
      return 1.0;
    case PredefKind::SpindleOn:
      return flag(spindle_ != 0);
    case PredefKind::SpindleCw:
      return flag(spindle_ == 1);
    case PredefKind::Mist:
      return flag(mist_);
    case PredefKind::Flood:
      return flag(flood_);
    case PredefKind::SpeedOverride:
      return flag(speed_override_);
    case PredefKind::FeedOverride:
      return flag(feed_override_);
    case PredefKind::AdaptiveFeed:
      return 0.0;
    case PredefKind::FeedHold:
      return 1.0;
    case PredefKind::Feed:
      return feed_rate_;
    case PredefKind::Rpm:
      return speed_;
    case PredefKind::CurrentTool:
    case PredefKind::CurrentPocket:
      return current_tool_;
    case PredefKind::SelectedTool:
    case PredefKind::SelectedPocket:
      return selected_tool_;
    case PredefKind::CallLevel:
      return static_cast<double>(frames_.size() - 1);
    case PredefKind::RemapLevel:
      return 0.0;
    // A simulated run is the machine's run (LinuxCNC's task), not a preview.
    case PredefKind::Task:
      return 1.0;
    case PredefKind::VMajor:
      return 2.0;
    case PredefKind::VMinor:
      return 9.0;
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
        if (p.index >= 5400 && p.index <= 5428)
          throw ExprError("parameter #" + std::to_string(p.index) + " is read-only");
      } else if (static_cast<PredefKind>(predef_[static_cast<std::size_t>(a.name)]) != PredefKind::None) {
        throw ExprError("#<" + prog_.names.name(a.name) + "> is a read-only predefined parameter");
      }
      p.value = prog_.exprs.evaluate(a.value, *this);
    } catch (const ExprError& e) {
      const std::string target = a.name >= 0 ? "#<" + prog_.names.name(a.name) + ">"
                                             : "#" + (p.index ? std::to_string(p.index) : std::string("..."));
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

}  // namespace vmsim::program::gcode
