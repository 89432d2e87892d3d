// The 840D standard cycles the CAM posts call: CYCLE832 (high-speed settings), CYCLE800 (swivel plane) and the
// drilling cycles CYCLE81/82/83, each as the settings or the motion it makes (Siemens, SINUMERIK 840D sl cycles
// programming manual: the cycles' parameters and their "Sequence" descriptions). MSG() is a call too.
#include "core/error.hpp"
#include "core/units.hpp"
#include "program/sinumerik_interp.hpp"

#include <cmath>

namespace vmsim::program::sinumerik {

namespace {
using core::units::kDegToRad;
}

bool Executor::has_arg(const Call& c, std::size_t i) const { return i < c.args.size() && c.args[i] != kNoExpr; }

double Executor::arg(const Call& c, std::size_t i, double fallback) const {
  if (i < c.string_args.size() && !c.string_args[i].empty())
    fail(c.name + ": argument " + std::to_string(i + 1) + " must be a number, not a string");
  return has_arg(c, i) ? eval(c.args[i]) : fallback;
}

void Executor::call(const Call& c, bool from_mcall) {
  if (c.name == "MSG") {
    if (c.args.size() > 1) fail("MSG takes one argument");
    std::string text;
    if (!c.string_args.empty() && !c.string_args[0].empty()) {
      text = c.string_args[0];
    } else if (!c.args.empty() && c.args[0] != kNoExpr) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%g", eval(c.args[0]));
      text = buf;
    }
    canon_.print("MESSAGE(\"%s\")", text.c_str());
    return;
  }
  if (from_mcall && c.name != "CYCLE81" && c.name != "CYCLE82" && c.name != "CYCLE83")
    fail("MCALL " + c.name + ": only the drilling cycles CYCLE81, CYCLE82, CYCLE83 are read as modal calls");
  if (c.name == "CYCLE832") return cycle832(c);
  if (c.name == "CYCLE800") return cycle800(c);
  if (c.name == "CYCLE81" || c.name == "CYCLE82" || c.name == "CYCLE83") return drilling_cycle(c);
  if (c.name == "WAITM" || c.name == "WAITE" || c.name == "WAITS" || c.name == "SETMS" || c.name == "GROUP_BEGIN" ||
      c.name == "GROUP_END")
    return not_modelled(c.name + "(): NC command without motion");
  fail(c.name +
       "(): subprogram or cycle not supported (vmsim reads CYCLE800, CYCLE81, CYCLE82, CYCLE83, CYCLE832 "
       "and MSG)");
}

// CYCLE832(_TOL, _TOLM, _OTOL): contour tolerance and machining technology (units digit of _TOLM: 0 deselect,
// 1 finishing, 2 semi-finishing, 3 roughing, 4 smooth finishing). The cycle selects continuous-path mode with
// tolerance-based smoothing (G642), the technology's dynamic response, SOFT and feedforward; deselection (no
// arguments, or technology 0) returns to G64 without a tolerance. In vmsim the tolerance is the interpolator's.
void Executor::cycle832(const Call& c) {
  const int technology = has_arg(c, 1) ? static_cast<int>(std::llround(arg(c, 1, 0))) % 10 : 0;
  if (c.args.empty() || technology == 0) {
    contour_tolerance_mm_ = 0.0;
    canon_.print("COMMENT(\"interpreter: CYCLE832 deselected\")");
    set_control_mode("CYCLE832 deselect (G64)", std::nullopt, false);
    return;
  }
  static const char* kNames[] = {"", "finishing", "semi-finishing", "roughing", "smooth finishing"};
  if (technology < 1 || technology > 4) fail("CYCLE832: machining type " + std::to_string(technology) + " is not 0..4");
  if (!has_arg(c, 0)) fail("CYCLE832: the contour tolerance (first argument) is missing");
  const double tol = arg(c, 0, 0) * (inch_ ? 25.4 : 1.0);
  if (!(tol > 0)) fail("CYCLE832: the contour tolerance must be positive");
  contour_tolerance_mm_ = tol;
  canon_.print("COMMENT(\"interpreter: CYCLE832 %s, tolerance %.4f mm: G642 SOFT FFWON\")", kNames[technology], tol);
  set_control_mode(std::string("CYCLE832 ") + kNames[technology], tol, false);
  canon_.print("SET_NAIVECAM_TOLERANCE(%.4f)", tol);
}

// CYCLE800(_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR, _FR_I, _DMODE): swivel plane.
// No arguments (or _TC "0"): the swivel frame is removed. Otherwise the frame is TRANS _X0.. (reference point),
// the rotations axis by axis (_MODE bits 7-6 = 00; bits 1-0, 3-2, 5-4 name the axes of _A, _B, _C: 01 X, 10 Y,
// 11 Z), then TRANS _X1.. (zero of the swivelled plane); the rotary axes turn so that the tool axis is the frame's Z
// (G17), the solution nearest to the rotary axes' positions. The retraction _FR goes to positions in the
// controller's swivel data record, which the program does not give: only _FR = 0 is read.
void Executor::cycle800(const Call& c) {
  const bool reset = c.args.empty() || (c.string_args.size() > 1 && c.string_args[1] == "0");
  if (reset) {
    const bool was_tcp = tcp();
    swivel_ = Frame{};
    swivel_active_ = false;
    if (was_tcp && !tcp() && options_.machine) cur_ = options_.machine->joint_of_tip(cur_);
    canon_.print("COMMENT(\"interpreter: CYCLE800 swivel frame removed\")");
    return;
  }
  if (traori_) fail("CYCLE800 under TRAORI: swivel with TRAFOOF (or use TRAORI with frames)");
  if (arg(c, 0, 0) != 0)
    fail("CYCLE800: retraction _FR=" + std::to_string(static_cast<int>(arg(c, 0, 0))) +
         " moves to positions in the controller's swivel data, which the program does not give; program _FR=0 and "
         "the retraction as moves");
  const int mode = static_cast<int>(std::llround(arg(c, 3, 57)));
  if (((mode >> 6) & 3) != 0)
    fail("CYCLE800: swivel mode _MODE=" + std::to_string(mode) +
         " is not axis by axis (bits 7-6 = 00): solid, "
         "projection and direct rotary angles are not supported");
  Frame r;
  const double ang[3] = {arg(c, 7, 0), arg(c, 8, 0), arg(c, 9, 0)};
  for (int i = 0; i < 3; ++i) {
    const int code = (mode >> (2 * i)) & 3;
    if (code == 0) {
      if (ang[i] != 0) fail("CYCLE800: _MODE names no axis for rotation " + std::to_string(i + 1));
      continue;
    }
    r = r.then(Frame::rotation_about(code - 1, ang[i]));
  }
  const double len = inch_ ? 25.4 : 1.0;
  const Eigen::Vector3d x0(arg(c, 4, 0) * len, arg(c, 5, 0) * len, arg(c, 6, 0) * len);
  const Eigen::Vector3d x1(arg(c, 10, 0) * len, arg(c, 11, 0) * len, arg(c, 12, 0) * len);
  const Frame swivel = Frame::translation(x0).then(r).then(Frame::translation(x1));
  if (!options_.machine)
    fail(
        "CYCLE800 turns the rotary axes through the machine's kinematics: read the program with a machine "
        "(a job with a chain machine file)");
  const Eigen::Vector3d tool_axis = swivel.rotation.col(2);
  // The rotary axes turn (the linear axes stand still), as a joint rapid move; then the swivelled plane's moves are
  // tool-centre-point moves with the rotary axes fixed.
  const bool was_tcp = tcp();
  if (was_tcp) cur_ = options_.machine->joint_of_tip(cur_);
  swivel_active_ = false;
  core::Vec6 end = cur_;
  end.tail<3>() = options_.machine->rotary_for_tool_axis(tool_axis, cur_);
  canon_.print("COMMENT(\"interpreter: CYCLE800 swivel: tool axis (%.4f, %.4f, %.4f)\")", tool_axis.x(), tool_axis.y(),
               tool_axis.z());
  line_to(true, end);
  swivel_ = swivel;
  swivel_active_ = true;
  cur_.head<3>() = options_.machine->tip_of_joint(cur_);
}

// The drilling motion along the plane's normal axis of the programmed frame, the point in the plane held.
void Executor::drill_to(double normal_prog, bool rapid) {
  const Frame frame = total_frame();
  Eigen::Vector3d p = programmed(frame);
  const int n = plane_ == 18 ? 1 : plane_ == 19 ? 0 : 2;
  p[n] = normal_prog;
  core::Vec6 end = cur_;
  end.head<3>() = frame.apply(p);
  line_to(rapid, end);
}

// CYCLE81(RTP, RFP, SDIS, DP, DPR), CYCLE82(.., DTB), CYCLE83(RTP, RFP, SDIS, DP, DPR, FDEP, FDPR, DAM, DTB, DTS, FRF,
// VARI, _AXN, _MDEP, _VRT, _DTD, _DIS1) at the current point of the plane:
//   G0 to the reference plane plus the safety distance; G1 to the final depth (DPR, relative to the reference plane,
//   wins over DP when both are given) at the programmed feed; CYCLE82 dwells DTB s there; G0 back to the retraction
//   plane RTP. CYCLE83 drills in steps: the first to FDEP (or FDPR below the reference plane) at FRF times the feed,
//   each next one DAM shorter (never shorter than DAM; DAM = 0: equal steps), dwelling DTB at each depth; VARI = 0
//   (chip breaking) backs off _VRT (1 mm when 0) after each step, VARI = 1 (chip removal) returns to the safety plane
//   with G0, dwells DTS, and comes back with G0 to the last depth less the anticipation distance _DIS1 (when 0: 0.6 mm
//   up to 30 mm of depth, else depth / 50, at most 7 mm).
void Executor::drilling_cycle(const Call& c) {
  ++result_.stats.cycle_calls;
  for (std::size_t i = 0; i < c.string_args.size(); ++i)
    if (!c.string_args[i].empty()) fail(c.name + ": argument " + std::to_string(i + 1) + " must be a number");
  const double len = inch_ ? 25.4 : 1.0;
  if (!has_arg(c, 0) || !has_arg(c, 1)) fail(c.name + ": the retraction plane RTP and reference plane RFP are needed");
  const double rtp = arg(c, 0, 0) * len, rfp = arg(c, 1, 0) * len, sdis = std::fabs(arg(c, 2, 0)) * len;
  double depth = 0.0;
  if (has_arg(c, 4) && arg(c, 4, 0) != 0) {
    depth = rfp - std::fabs(arg(c, 4, 0)) * len;
  } else if (has_arg(c, 3)) {
    depth = arg(c, 3, 0) * len;
  } else {
    fail(c.name + ": the final depth (DP or DPR) is missing");
  }
  const double dir = depth < rfp ? -1.0 : 1.0;  // drilling direction along the normal
  if (std::fabs(depth - rfp) < 1e-9) fail(c.name + ": the final depth is the reference plane");
  if ((rtp - rfp) * dir > 0) fail(c.name + ": the retraction plane RTP lies beyond the reference plane, in the hole");
  const double safety = rfp - dir * sdis;
  canon_.print("COMMENT(\"interpreter: %s\")", c.name.c_str());
  if (feed_mm_per_min_ <= 0) fail(c.name + ": drilling needs a feed: program F first");
  drill_to(safety, true);
  if (c.name != "CYCLE83") {
    drill_to(depth, false);
    if (c.name == "CYCLE82" && arg(c, 5, 0) > 0) canon_.print("DWELL(%.4f)", arg(c, 5, 0));
    drill_to(rtp, true);
    return;
  }
  double first = 0.0;
  if (has_arg(c, 6) && arg(c, 6, 0) != 0) {
    first = rfp + dir * std::fabs(arg(c, 6, 0)) * len;
  } else if (has_arg(c, 5)) {
    first = arg(c, 5, 0) * len;
  } else {
    fail("CYCLE83: the first drilling depth (FDEP or FDPR) is missing");
  }
  const double dam = std::fabs(arg(c, 7, 0)) * len, dtb = arg(c, 8, 0), dts = arg(c, 9, 0);
  const double frf = arg(c, 10, 1.0);
  const int vari = static_cast<int>(std::llround(arg(c, 11, 0)));
  const double vrt = arg(c, 14, 0) > 0 ? arg(c, 14, 0) * len : 1.0;
  double dis1 = arg(c, 16, 0) * len;
  if (vari != 0 && vari != 1) fail("CYCLE83: VARI must be 0 (chip breaking) or 1 (chip removal)");
  if (!(frf > 0 && frf <= 1)) fail("CYCLE83: the feed factor FRF must be in (0, 1]");
  const double total = std::fabs(depth - rfp);
  if (dis1 <= 0) dis1 = total <= 30 ? 0.6 : std::min(7.0, total / 50);
  double step = std::fabs(first - rfp);
  if (step <= 0) fail("CYCLE83: the first drilling depth is the reference plane");
  const double programmed_feed = feed_mm_per_min_;
  double reached = rfp;  // the deepest point drilled so far, along the normal
  for (bool first_step = true;; first_step = false) {
    double target = first_step ? first : reached + dir * step;
    if ((target - depth) * dir > 0) target = depth;
    if (!first_step && vari == 1) drill_to(reached - dir * dis1, true);
    if (first_step && frf != 1.0) {
      feed_mm_per_min_ = programmed_feed * frf;
      canon_.print("SET_FEED_RATE(%.4f)", feed_mm_per_min_);
    }
    drill_to(target, false);
    if (first_step && frf != 1.0) {
      feed_mm_per_min_ = programmed_feed;
      canon_.print("SET_FEED_RATE(%.4f)", feed_mm_per_min_);
    }
    if (dtb > 0) canon_.print("DWELL(%.4f)", dtb);
    reached = target;
    if (std::fabs(reached - depth) < 1e-9) break;
    if (vari == 0) {
      drill_to(reached - dir * vrt, true);
    } else {
      drill_to(safety, true);
      if (dts > 0) canon_.print("DWELL(%.4f)", dts);
    }
    if (dam > 0) step = std::max(step - dam, dam);
  }
  drill_to(rtp, true);
}

}  // namespace vmsim::program::sinumerik
