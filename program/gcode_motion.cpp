// Motion: straight moves, arcs and helices, canned cycles, G28/G30, and the ToolPath they make.
#include "core/error.hpp"
#include "core/units.hpp"
#include "program/gcode_interp.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace vmsim::program::gcode {

namespace {

using core::units::kPiLong;
using core::units::kInchToMm;

// LinuxCNC's arc tolerances (interp_internal.hh), in program units.
constexpr double kRadiusToleranceInch = 0.00005;  // R-format: how far the end may be beyond the diameter
constexpr double kRadiusToleranceMm = kRadiusToleranceInch * kInchToMm;
constexpr double kCenterToleranceInch = 2 * 0.001 * std::numbers::sqrt2;  // centre format: |r_start - r_end|
constexpr double kCenterToleranceMm = 2 * 0.01 * std::numbers::sqrt2;
constexpr double kSpiralRelativeTolerance = 0.001;
constexpr double kTiny = 1e-12;  // arc_data_r: a semicircle's rounding

// Plane axes: first and second coordinate of the arc or cycle plane, and the axis normal to it.
struct PlaneAxes {
  std::size_t a, b, c;
  char la, lb, lc;
};
PlaneAxes axes_of(Plane p) {
  switch (p) {
    case Plane::XY:
      return {0, 1, 2, 'X', 'Y', 'Z'};
    case Plane::XZ:
      return {2, 0, 1, 'Z', 'X', 'Y'};
    case Plane::YZ:
      return {1, 2, 0, 'Y', 'Z', 'X'};
  }
  return {0, 1, 2, 'X', 'Y', 'Z'};
}

const char* plane_name(Plane p) { return p == Plane::XY ? "XY (G17)" : p == Plane::XZ ? "XZ (G18)" : "YZ (G19)"; }

// Angle swept from (x1, y1) to (x2, y2) about the centre, positive counter-clockwise (find_turn).
double find_turn(double x1, double y1, double cx, double cy, int turn, double x2, double y2) {
  if (turn == 0) return 0.0;
  // Doubles rounded where LinuxCNC rounds them, its 2*M_PIl sums in long double.
  double alpha = std::atan2(y1 - cy, x1 - cx);
  double beta = std::atan2(y2 - cy, x2 - cx);
  if (turn > 0) {
    if (beta <= alpha) beta = static_cast<double>(beta + 2 * kPiLong);
    return static_cast<double>((beta - alpha) + (turn - 1) * (2 * kPiLong));
  }
  if (alpha <= beta) alpha = static_cast<double>(alpha + 2 * kPiLong);
  return static_cast<double>((beta - alpha) + (turn + 1) * (2 * kPiLong));
}

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Frames and the ToolPath

core::Vec6 Interpreter::machine(const Pos& p) const {
  // The workpiece frame of the ToolPath: G92 offset, XY rotation (G10 L2 R), G5x origin; not the tool
  // length offset (Move::tool_length_offset_mm carries it). mm and radians.
  double x = p[0] + axis_offset_[0];
  double y = p[1] + axis_offset_[1];
  rotate(x, y, rotation_xy_);
  x += origin_offset_[0];
  y += origin_offset_[1];
  const double z = p[2] + axis_offset_[2] + origin_offset_[2];
  const double u = inch_ ? kInchToMm : 1.0;
  constexpr double kRad = std::numbers::pi / 180.0;
  core::Vec6 v;
  v << x * u, y * u, z * u, (p[3] + axis_offset_[3] + origin_offset_[3]) * kRad,
      (p[4] + axis_offset_[4] + origin_offset_[4]) * kRad, (p[5] + axis_offset_[5] + origin_offset_[5]) * kRad;
  return v;
}

void Interpreter::start_move(core::Move& m, const Pos& end) {
  const double unit = inch_ ? kInchToMm : 1.0;
  m.tool_number = current_tool_;
  m.tool_length_offset_mm = tool_offset_[2] * unit;
  // A new length offset moves the controlled point (along Z), not the machine.
  m.start = tip_;
  m.start[core::kZ] += tip_tlo_mm_ - m.tool_length_offset_mm;
  m.end = machine(end);
  m.source_line = prog_.lines[line_].number;
  tip_ = m.end;
  tip_tlo_mm_ = m.tool_length_offset_mm;
}

void Interpreter::record_line(bool rapid, const Pos& end) {
  core::Move m;
  m.kind = core::MotionKind::Line;
  m.rapid = rapid;
  start_move(m, end);
  // Zero-length moves stay in the canonical calls (rs274 prints them) but carry nothing for the machine.
  if ((m.end - m.start).cwiseAbs().maxCoeff() <= 1e-9) return;
  constexpr double kTinyMove = 1e-7;  // LinuxCNC's find_straight_length: does X, Y or Z move?
  const bool linear = std::fabs(end[0] - pos_[0]) > kTinyMove || std::fabs(end[1] - pos_[1]) > kTinyMove ||
                      std::fabs(end[2] - pos_[2]) > kTinyMove;
  if (!rapid) {
    if (inverse_time_) {
      m.feed_mode = core::FeedMode::InverseTime;
      m.inverse_time_per_min = block_f_;
      m.feed_mm_per_min = linear ? feed_rate_ * (inch_ ? kInchToMm : 1.0) : feed_rate_;
    } else {
      m.feed_mm_per_min = linear ? feed_linear_mm_ : feed_angular_deg_;
    }
    if (!diameter_from_feed_) {
      diameter_from_feed_ = true;
      if (const ToolEntry* t = tools_ != nullptr && current_tool_ != 0 ? tools_->find(current_tool_) : nullptr)
        path_.tool_diameter_mm = options_.inch_machine ? t->diameter * kInchToMm : t->diameter;
    }
  }
  path_.moves.push_back(m);
}

void Interpreter::record_arc(const Pos& end, Plane plane, double c1, double c2, int turn) {
  if (rotation_xy_ != 0.0 && plane != Plane::XY)
    fail("an arc in the " + std::string(plane_name(plane)) +
         " plane with a rotated coordinate system (G10 L2 R) is not supported");
  core::Move m;
  m.kind = core::MotionKind::Arc;
  start_move(m, end);
  const PlaneAxes ax = axes_of(plane);
  Pos centre = pos_;
  centre[ax.a] = c1;
  centre[ax.b] = c2;
  const core::Vec6 c = machine(centre);
  m.centre_mm = Eigen::Vector2d(c[static_cast<Eigen::Index>(ax.a)], c[static_cast<Eigen::Index>(ax.b)]);
  m.plane = plane == Plane::XY ? core::ArcPlane::XY : plane == Plane::XZ ? core::ArcPlane::ZX : core::ArcPlane::YZ;
  m.rotation = turn;
  if (inverse_time_) {
    m.feed_mode = core::FeedMode::InverseTime;
    m.inverse_time_per_min = block_f_;
    m.feed_mm_per_min = feed_rate_ * (inch_ ? kInchToMm : 1.0);
  } else {
    m.feed_mm_per_min = feed_linear_mm_;
  }
  if (!diameter_from_feed_) {
    diameter_from_feed_ = true;
    if (const ToolEntry* t = tools_ != nullptr && current_tool_ != 0 ? tools_->find(current_tool_) : nullptr)
      path_.tool_diameter_mm = options_.inch_machine ? t->diameter * kInchToMm : t->diameter;
  }
  path_.moves.push_back(m);
}

void Interpreter::traverse_to(const Pos& e) {
  canon_.axes_call("STRAIGHT_TRAVERSE", e.data(), 6);
  record_line(true, e);
  pos_ = e;
}

void Interpreter::feed_to(const Pos& e) {
  canon_.axes_call("STRAIGHT_FEED", e.data(), 6);
  record_line(false, e);
  pos_ = e;
}

void Interpreter::set_inverse_time_rate(double length) {
  // G93: the interpreter turns "this move takes 1/F minutes" into a feed rate (inverse_time_rate_*), with
  // LinuxCNC's lower bound of 0.1 so that a zero-length move still gets a feed.
  feed_rate_ = std::max(0.1, length * block_f_);
  canon_.axes_call("SET_FEED_RATE", &feed_rate_, 1);
}

// ---------------------------------------------------------------------------------------------------------------
// Motion dispatch and end points

void Interpreter::motion(int g, Block& b) {
  const bool cycle_code = g == 730 || g == 810 || g == 820 || g == 830 || g == 850 || g == 890;
  if (!cycle_code) cycle_il_flag_ = false;  // the "initial level" lasts while cycles follow each other
  switch (g) {
    case 0:
    case 10:
      straight(g, b);
      break;
    case 20:
    case 30:
      arc(g, b);
      break;
    case 800:
      canon_.print("COMMENT(\"%s\")", "interpreter: motion mode set to none");
      motion_mode_ = 800;
      break;
    default:
      cycle(g, b);
      break;
  }
}

Pos Interpreter::find_ends(const Block& b) const {
  static constexpr char kAxes[] = "XYZABC";
  Pos e = pos_;
  if (b.g_mode[0] == 530) {
    // G53: the words are machine coordinates; express them in the active system (find_ends).
    double cx = pos_[0] + axis_offset_[0];
    double cy = pos_[1] + axis_offset_[1];
    rotate(cx, cy, rotation_xy_);
    double px = b.has('X') ? b['X'] - origin_offset_[0] - tool_offset_[0] : cx;
    double py = b.has('Y') ? b['Y'] - origin_offset_[1] - tool_offset_[1] : cy;
    rotate(px, py, -rotation_xy_);
    e[0] = px - axis_offset_[0];
    e[1] = py - axis_offset_[1];
    if (b.has('Z')) e[2] = b['Z'] - origin_offset_[2] - axis_offset_[2] - tool_offset_[2];
    for (std::size_t i = 3; i < 6; ++i)
      if (b.has(kAxes[i])) e[i] = b[kAxes[i]] - origin_offset_[i] - axis_offset_[i];
  } else if (absolute_) {
    for (std::size_t i = 0; i < 6; ++i)
      if (b.has(kAxes[i])) e[i] = b[kAxes[i]];
  } else {
    for (std::size_t i = 0; i < 6; ++i)
      if (b.has(kAxes[i])) e[i] += b[kAxes[i]];
  }
  return e;
}

void Interpreter::straight(int g, const Block& b) {
  if (g == 10) {
    if (!inverse_time_ && feed_rate_ == 0.0) fail("G1 with a zero feed rate (no F word given yet)");
    if (inverse_time_ && !b.has('F')) fail("G1 under G93 (inverse time) needs an F word on every move");
  }
  motion_mode_ = g;
  const Pos end = find_ends(b);
  if (g == 10 && inverse_time_) {
    // find_straight_length: the XYZ distance, or the rotary one when X, Y and Z do not move.
    constexpr double kTinyMove = 1e-7;
    double length;
    if (std::fabs(pos_[0] - end[0]) > kTinyMove || std::fabs(pos_[1] - end[1]) > kTinyMove ||
        std::fabs(pos_[2] - end[2]) > kTinyMove)
      length = std::sqrt(std::pow(end[0] - pos_[0], 2) + std::pow(end[1] - pos_[1], 2) + std::pow(end[2] - pos_[2], 2));
    else
      length = std::sqrt(std::pow(end[3] - pos_[3], 2) + std::pow(end[4] - pos_[4], 2) + std::pow(end[5] - pos_[5], 2));
    set_inverse_time_rate(length);
  }
  if (g == 0)
    traverse_to(end);
  else
    feed_to(end);
}

// ---------------------------------------------------------------------------------------------------------------
// Arcs and helices (convert_arc, arc_data_ijk, arc_data_r)

void Interpreter::arc(int g, const Block& b) {
  const std::string code = g_name(g);
  const bool ijk = b.has('I') || b.has('J') || b.has('K');
  if (!b.has('R') && !ijk) fail(code + " needs R (radius) or I/J/K (centre) words");
  if (b.has('R') && ijk) fail(code + " has both R and I/J/K words: give one arc format");
  if (!inverse_time_ && feed_rate_ == 0.0) fail(code + " with a zero feed rate (no F word given yet)");
  if (inverse_time_ && !b.has('F')) fail(code + " under G93 (inverse time) needs an F word on every move");

  const PlaneAxes ax = axes_of(plane_);
  // Centre offsets per plane: XY (I, J), XZ (K, I), YZ (J, K); the third letter is not allowed.
  const char l1 = plane_ == Plane::XY ? 'I' : plane_ == Plane::XZ ? 'K' : 'J';
  const char l2 = plane_ == Plane::XY ? 'J' : plane_ == Plane::XZ ? 'I' : 'K';
  const char bad = plane_ == Plane::XY ? 'K' : plane_ == Plane::XZ ? 'J' : 'I';
  double off1 = 0.0, off2 = 0.0;
  if (ijk) {
    if (b.has(bad)) fail(std::string(1, bad) + " word in an arc in the " + plane_name(plane_) + " plane");
    if (!b.has(l1) && ijk_absolute_) fail(std::string(1, l1) + " word missing in an absolute-centre arc (G90.1)");
    if (!b.has(l2) && ijk_absolute_) fail(std::string(1, l2) + " word missing in an absolute-centre arc (G90.1)");
    off1 = b.has(l1) ? b[l1] : 0.0;
    off2 = b.has(l2) ? b[l2] : 0.0;
  } else if (!b.has(ax.la) && !b.has(ax.lb)) {
    fail(code + " R: " + std::string(1, ax.la) + " and " + std::string(1, ax.lb) +
         " words are both missing (an R arc cannot be a full circle)");
  }
  int turns = 1;
  if (b.has('P')) {
    const double p = std::floor(b['P'] + 0.5);  // LinuxCNC's round_to_int
    if (p < 1.0) fail(code + " P" + num(b['P']) + ": P (number of turns) must be 1 or more");
    if (p > 1e6) fail(code + " P" + num(b['P']) + ": too many turns");
    turns = static_cast<int>(p);
  }
  const Pos end = find_ends(b);
  motion_mode_ = g;

  const double x1 = pos_[ax.a], y1 = pos_[ax.b];
  const double x2 = end[ax.a], y2 = end[ax.b];
  const char a = ax.la, c = ax.lb;
  double cx = 0.0, cy = 0.0;
  const int turn = g == 20 ? -turns : turns;
  if (b.has('R')) {
    const double radius = b['R'];
    const double tolerance = inch_ ? kRadiusToleranceInch : kRadiusToleranceMm;
    if (x2 == x1 && y2 == y1) fail(code + " R: the end point is the start point (use I/J/K for a full circle)");
    const double abs_radius = std::fabs(radius);
    const double mid_x = (x2 + x1) / 2.0;
    const double mid_y = (y2 + y1) / 2.0;
    double half_length = std::hypot(mid_x - x2, mid_y - y2);
    if (half_length - abs_radius > tolerance)
      fail(code + " R" + num(radius) + ": radius too small to reach the end point (chord/2 = " + num(half_length) +
           ")");
    if (half_length / abs_radius > 1 - kTiny) half_length = abs_radius;  // a semicircle, within rounding
    const long double base = std::atan2(y2 - y1, x2 - x1);
    // R > 0: the short arc (up to a semicircle), R < 0: the long one.
    const double theta = static_cast<double>((g == 20) == (radius > 0) ? base - kPiLong / 2 : base + kPiLong / 2);
    const double turn2 = std::asin(half_length / abs_radius);
    const double offset = abs_radius * std::cos(turn2);
    cx = mid_x + offset * std::cos(theta);
    cy = mid_y + offset * std::sin(theta);
  } else {
    const double radius_tolerance = inch_ ? kRadiusToleranceInch : kRadiusToleranceMm;
    const double spiral_tolerance = inch_ ? kCenterToleranceInch : kCenterToleranceMm;
    cx = ijk_absolute_ ? off1 : x1 + off1;
    cy = ijk_absolute_ ? off2 : y1 + off2;
    const double r1 = std::hypot(cx - x1, cy - y1);
    const double r2 = std::hypot(cx - x2, cy - y2);
    const std::string detail = "start=(" + std::string(1, a) + num(x1) + "," + c + num(y1) + ") centre=(" + a +
                               num(cx) + "," + c + num(cy) + ") end=(" + a + num(x2) + "," + c + num(y2) +
                               ") r1=" + num(r1) + " r2=" + num(r2);
    if (r1 < radius_tolerance || r2 < radius_tolerance) fail(code + ": zero-radius arc: " + detail);
    const double abs_err = std::fabs(r1 - r2);
    const double rel_err = abs_err / std::max(r1, r2);
    if (abs_err > spiral_tolerance || rel_err > kSpiralRelativeTolerance)
      fail(code + ": radius to the end differs from radius to the start by " + num(abs_err) + " (LinuxCNC allows " +
           num(spiral_tolerance) + " and 0.1%): " + detail);
  }
  if (inverse_time_) {
    // find_arc_length: the helix length in the plane and along its axis.
    const double radius = std::hypot(cx - x1, cy - y1);
    const double theta = find_turn(x1, y1, cx, cy, turn, x2, y2);
    const double z1 = pos_[ax.c], z2 = end[ax.c];
    set_inverse_time_rate(z2 == z1 ? radius * std::fabs(theta) : std::hypot(radius * theta, z2 - z1));
  }
  const double plane4[4] = {x2, y2, cx, cy};
  const double rest4[4] = {end[ax.c], end[3], end[4], end[5]};
  canon_.arc_call(plane4, turn, rest4);
  record_arc(end, plane_, cx, cy, turn);
  pos_ = end;
}

// ---------------------------------------------------------------------------------------------------------------
// Canned cycles (convert_cycle, convert_cycle_xy/yz/zx and the cycle bodies of LinuxCNC 2.9)

void Interpreter::cycle(int g, Block& b) {
  const std::string code = g_name(g);
  if (inverse_time_) fail(code + ": canned cycles cannot run under G93 (inverse time feed)");
  if (feed_rate_ == 0.0) fail(code + " with a zero feed rate (no F word given yet)");
  for (const char r : {'A', 'B', 'C'})
    if (b.has(r)) fail(code + ": rotary axes (" + std::string(1, r) + ") cannot move in a canned cycle");
  double r_word = 0.0;
  if (b.has('R'))
    r_word = b['R'];
  else if (motion_mode_ == g)
    r_word = cycle_r_;
  else
    fail(code + " needs an R word (retract plane) when the cycle starts");
  long long repeats = 1;
  if (b.has('L')) {
    const double l = b['L'];
    if (l != std::floor(l) || l < 1.0) fail(code + " L" + num(l) + ": L (repeats) must be a whole number of 1 or more");
    repeats = static_cast<long long>(std::min(l, 1e12));
  }
  const PlaneAxes ax = axes_of(plane_);
  double current_cc = pos_[ax.c];
  if (motion_mode_ != g && !b.has(ax.lc))
    fail(code + " in the " + plane_name(plane_) + " plane needs a " + std::string(1, ax.lc) +
         " word (hole bottom) when the cycle starts");
  const double cc_word = b.has(ax.lc) ? b[ax.lc] : cycle_cc_;
  double old_cc;
  if (cycle_il_flag_) {
    old_cc = cycle_il_;  // the initial level of the first cycle in a row (G98 returns there)
  } else {
    old_cc = cycle_il_ = current_cc;
    cycle_il_flag_ = true;
  }
  double aa, bb, aa_increment = 0.0, bb_increment = 0.0, r, cc;
  if (absolute_) {
    r = r_word;
    cc = cc_word;
    aa = b.has(ax.la) ? b[ax.la] : pos_[ax.a];
    bb = b.has(ax.lb) ? b[ax.lb] : pos_[ax.b];
  } else {
    // G91: X Y step from hole to hole, R is relative to the initial level, Z to R.
    if (b.has(ax.la)) aa_increment = b[ax.la];
    if (b.has(ax.lb)) bb_increment = b[ax.lb];
    r = r_word + old_cc;
    cc = r + cc_word;
    aa = pos_[ax.a];
    bb = pos_[ax.b];
  }
  if (r < cc)
    fail(code + ": the R plane (" + num(r) + ") is below the hole bottom " + std::string(1, ax.lc) + " (" + num(cc) +
         ")");

  double dwell = 0.0, delta = 0.0;
  if (g == 820 || g == 890) {
    if (motion_mode_ != g && !b.has('P')) fail(code + " needs a P word (dwell time) when the cycle starts");
    dwell = b.has('P') ? b['P'] : cycle_p_;
  }
  if (g == 730 || g == 830) {
    if (motion_mode_ != g && !b.has('Q')) fail(code + " needs a Q word (peck depth) when the cycle starts");
    delta = b.has('Q') ? b['Q'] : cycle_q_;
    if (delta <= 0.0) fail(code + " Q" + num(delta) + ": the peck depth Q must be more than 0");
  }

  const auto move = [&](bool rapid, double a1, double b1, double c1) {
    Pos p = pos_;
    p[ax.a] = a1;
    p[ax.b] = b1;
    p[ax.c] = c1;
    if (rapid)
      traverse_to(p);
    else
      feed_to(p);
  };
  // First move of a cycle (maybe): below the R plane, go up to it at the current position.
  if (old_cc < r) {
    Pos p = pos_;
    p[ax.c] = r;
    traverse_to(p);
    old_cc = r;
    current_cc = old_cc;
  }
  const double clear_cc = retract_r_plane_ ? r : old_cc;
  // Say at once when the repeats and pecks asked for cannot fit the bound on canonical calls, rather than
  // after making millions of them (L999999999, or Q far smaller than the depth).
  const double pecks = (g == 730 || g == 830) ? std::max(0.0, std::ceil((r - cc) / delta)) : 0.0;
  const double per_hole = 4.0 + 3.0 * pecks;
  if (static_cast<double>(repeats) * per_hole > static_cast<double>(canon_.remaining()))
    fail(code + ": " + std::to_string(repeats) + (repeats == 1 ? " hole" : " holes") +
         (pecks > 0 ? " of " + num(pecks) + " pecks each" : std::string()) + " would make more than the " +
         std::to_string(canon_.remaining()) + " canonical calls left: possible endless loop");
  const ControlMode saved_mode = control_;
  const double saved_tolerance = control_tolerance_;
  if (saved_mode != ControlMode::ExactPath) emit_control_mode(ControlMode::ExactPath, 0.0);

  // G73 and G83 back off this much above the last peck before feeding again (G83_RAPID_DELTA).
  const double rapid_delta = inch_ ? 0.010 : 0.010 * kInchToMm;
  for (long long repeat = repeats; repeat > 0; --repeat) {
    aa += aa_increment;
    bb += bb_increment;
    if (repeat == repeats && current_cc > r) {
      move(true, aa, bb, current_cc);
      move(true, aa, bb, r);
    } else {
      move(true, aa, bb, clear_cc);  // later holes: already at the clearance level
      if (clear_cc > r) move(true, aa, bb, r);
    }
    switch (g) {
      case 810:  // drill: feed down, rapid out
        move(false, aa, bb, cc);
        move(true, aa, bb, clear_cc);
        break;
      case 820:  // drill with dwell
        move(false, aa, bb, cc);
        canon_.print("DWELL(%.4f)", dwell);
        move(true, aa, bb, clear_cc);
        break;
      case 830:  // peck drill: out to R after every peck
        for (double depth = r - delta; depth > cc; depth -= delta) {
          move(false, aa, bb, depth);
          move(true, aa, bb, r);
          move(true, aa, bb, depth + rapid_delta);
        }
        move(false, aa, bb, cc);
        move(true, aa, bb, clear_cc);
        break;
      case 730:  // chip break: back off a little after every peck
        for (double depth = r - delta; depth > cc; depth -= delta) {
          move(false, aa, bb, depth);
          move(true, aa, bb, depth + rapid_delta);
        }
        move(false, aa, bb, cc);
        move(true, aa, bb, clear_cc);
        break;
      case 850:  // bore: feed in, feed out to R
        move(false, aa, bb, cc);
        move(false, aa, bb, r);
        move(true, aa, bb, clear_cc);
        break;
      case 890:  // bore with dwell: feed in, dwell, feed out to the clearance level
        move(false, aa, bb, cc);
        canon_.print("DWELL(%.4f)", dwell);
        move(false, aa, bb, clear_cc);
        break;
      default:
        fail(code + " is not a canned cycle vmsim executes");
    }
  }
  cycle_cc_ = cc_word;
  if (g == 820 || g == 890) cycle_p_ = dwell;
  if (g == 730 || g == 830) cycle_q_ = delta;
  if (saved_mode != ControlMode::ExactPath) {
    emit_control_mode(saved_mode, saved_tolerance);
    canon_.print("SET_NAIVECAM_TOLERANCE(%.4f)", naivecam_tolerance_);
  }
  cycle_r_ = r_word;
  motion_mode_ = g;
}

// ---------------------------------------------------------------------------------------------------------------
// G28 / G30: through the programmed point to the stored reference point (convert_home)

void Interpreter::home(int g, const Block& b) {
  Pos end = find_ends(b);
  traverse_to(end);
  const std::size_t base = g == 280 ? 5161 : 5181;
  // The reference point is in machine coordinates and units (find_relative).
  Pos h{};
  double hx = from_user_len(params_[base + 0]) - origin_offset_[0] - tool_offset_[0];
  double hy = from_user_len(params_[base + 1]) - origin_offset_[1] - tool_offset_[1];
  rotate(hx, hy, -rotation_xy_);
  h[0] = hx - axis_offset_[0];
  h[1] = hy - axis_offset_[1];
  h[2] = from_user_len(params_[base + 2]) - origin_offset_[2] - axis_offset_[2] - tool_offset_[2];
  for (std::size_t i = 3; i < 6; ++i) h[i] = params_[base + i] - origin_offset_[i] - axis_offset_[i];
  static constexpr char kAxes[] = "XYZABC";
  if (b.has_axis()) {
    for (std::size_t i = 0; i < 6; ++i)
      if (b.has(kAxes[i])) end[i] = h[i];  // only the axes named go to the reference point
  } else {
    end = h;
  }
  traverse_to(end);
}

}  // namespace vmsim::program::gcode
