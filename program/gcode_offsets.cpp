// Coordinate systems and offsets, as LinuxCNC keeps them: G54..G59.3 origins and XY rotation in the
// parameters (#5221...), G10 L2/L20, G92/G52 (#5210..#5216), tool length offsets (G43, G43.1, G43.2, G49),
// G28.1/G30.1 reference points. Parameters hold machine units, the interpreter program units.
#include "program/gcode_interp.hpp"
#include "core/units.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace vmsim::program::gcode {

namespace {
using core::units::kInchToMm;
}  // namespace

double Interpreter::to_user_len(double v) const {
  if (options_.inch_machine == inch_) return v;
  return options_.inch_machine ? v / kInchToMm : v * kInchToMm;
}

double Interpreter::from_user_len(double v) const {
  if (options_.inch_machine == inch_) return v;
  return options_.inch_machine ? v * kInchToMm : v / kInchToMm;
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
  canon_.print("SET_G92_OFFSET(%.4f, %.4f, %.4f, %.4f, %.4f, %.4f)", axis_offset_[0], axis_offset_[1], axis_offset_[2],
               axis_offset_[3], axis_offset_[4], axis_offset_[5]);
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

}  // namespace vmsim::program::gcode
