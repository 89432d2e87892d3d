#include "methods/compensated_program.hpp"

#include "core/arc.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <Eigen/Geometry>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

namespace vmsim::methods {

namespace {

using Index = Eigen::Index;
using core::Vec6;

// The points a move is written with, in axis coordinates (Vec6 by program axis): its end, or for arcs the ends of
// chords whose sag stays within tol, or of pieces of at most max_angle (the arc's frame, core/arc: the radius, the
// normal coordinate and any rotary axis linear in the swept angle, as the interpolator's arcs are).
std::vector<Vec6> move_points(const core::Move& m, const std::string& file, double tol, double max_angle = 0.0) {
  if (m.kind != core::MotionKind::Arc) return {m.end};
  const core::ArcFrame arc = core::arc_frame(m, file);
  const int chords = arc.chords(tol, max_angle);
  std::vector<Vec6> pts;
  pts.reserve(static_cast<std::size_t>(chords));
  for (int i = 1; i <= chords; ++i) pts.push_back(arc.point_at(static_cast<double>(i) / chords));
  return pts;
}

// Points of a move of a five-axis chain program written in the workpiece frame (CL or tool-centre-point): its end, or
// for an arc the axis-space image's own points (motion::toolpath_in_axis_space: via points on the exact image within
// its tolerance, or chords of the axis-space arc).
std::vector<Vec6> chain_move_points(const core::Move& am, const std::string& file, bool arc, double tol) {
  if (!arc) return {am.end};
  if (am.kind == core::MotionKind::Arc) return move_points(am, file, tol);
  std::vector<Vec6> pts = am.via;
  pts.push_back(am.end);
  return pts;
}

struct Context {
  const CompensatedProgramInput& in;
  Index ns = 0, na = 0;
  std::vector<Index> first, last;  // per move: the samples on it (-1: none)
  Eigen::MatrixXd delta;           // compensated - original setpoints, samples x axes
  Eigen::VectorXd q;

  explicit Context(const CompensatedProgramInput& i) : in(i) {
    if (!in.program || !in.axis_path || !in.setpoints || !in.compensated || !in.command_tip || !in.machine ||
        !in.kinematics)
      throw core::Error("compensated program: incomplete input");
    ns = in.setpoints->samples();
    na = in.setpoints->position.cols();
    delta = *in.compensated - in.setpoints->position;
    const std::size_t nm = in.program->moves.size();
    first.assign(nm, -1);
    last.assign(nm, -1);
    for (Index k = 0; k < ns; ++k) {
      const int mi = in.setpoints->move_index[k];
      if (mi < 0 || static_cast<std::size_t>(mi) >= nm) continue;
      if (first[static_cast<std::size_t>(mi)] < 0) first[static_cast<std::size_t>(mi)] = k;
      last[static_cast<std::size_t>(mi)] = k;
    }
    q.resize(na);
  }

  Eigen::VectorXd machine_axes(const Vec6& v) const {
    Eigen::VectorXd x(na);
    for (Index a = 0; a < na; ++a) x[a] = v[in.machine->axes[static_cast<std::size_t>(a)].program_axis];
    return x;
  }

  // The setpoint nearest (tool tip) to a point of move mi; with `end` the next move's samples count too (a programmed
  // vertex sits between the two moves' samples, inside a corner blend).
  Index nearest(const Eigen::Vector3d& tip, std::size_t mi, bool end) const {
    Index lo = -1, hi = -1;
    auto take = [&](std::size_t m) {
      if (m >= first.size() || first[m] < 0) return;
      lo = lo < 0 ? first[m] : std::min(lo, first[m]);
      hi = std::max(hi, last[m]);
    };
    take(mi);
    if (end) take(mi + 1);
    if (end && mi + 1 < first.size() && first[mi] >= 0 && first[mi + 1] >= 0) {
      // A programmed vertex lies where one move's samples give way to the next's: search around that place only (a
      // closed contour passes its first vertex again at the end, at rest, where the correction is nil).
      const Index w =
          std::max<Index>(5, std::min<Index>({500, (last[mi] - first[mi]) / 4, (last[mi + 1] - first[mi + 1]) / 4}));
      lo = std::max(lo, last[mi] - w);
      hi = std::min(hi, first[mi + 1] + w);
    }
    if (lo < 0) {
      // A move without samples of its own (no length): the samples around where the path is then.
      for (std::size_t m = mi; m-- > 0 && lo < 0;) take(m);
      if (lo < 0) lo = 0;
      hi = std::min(ns - 1, std::max(lo, hi) + 1);
    }
    Index best = lo;
    double bd = std::numeric_limits<double>::infinity();
    for (Index k = lo; k <= hi; ++k) {
      const double d = (in.command_tip->row(k).transpose() - tip).squaredNorm();
      if (d < bd) bd = d, best = k;
    }
    return best;
  }

  // A point of move mi (axis coordinates) with the correction of its nearest setpoint: machine axes.
  Eigen::VectorXd corrected(const Vec6& v, std::size_t mi, bool end, double tlo, CompensatedProgram& out) {
    const Eigen::VectorXd qv = machine_axes(v);
    const motion::ToolPose p0 = in.kinematics->forward(qv, tlo);
    const Index k = nearest(p0.tip_mm, mi, end);
    Eigen::VectorXd q1 = qv + delta.row(k).transpose();
    const motion::ToolPose p1 = in.kinematics->forward(q1, tlo);
    out.largest_tip_correction_mm = std::max(out.largest_tip_correction_mm, (p1.tip_mm - p0.tip_mm).norm());
    out.largest_axis_correction_rad =
        std::max(out.largest_axis_correction_rad, std::atan2(p1.axis.cross(p0.axis).norm(), p1.axis.dot(p0.axis)));
    return q1;
  }
};

bool is_cl(const core::Move& m) { return m.tool_axis_start.has_value() || m.tool_axis_end.has_value(); }

std::string header(const CompensatedProgramInput& in, const char* open, const char* close) {
  std::string s;
  s += fmt::format("{}vmsim compensate: {}{}\n", open, in.title, close);
  s += fmt::format(
      "{}the predictive-compensation paper eq. 23: the original program's moves and feeds, each programmed point moved "
      "by the "
      "predicted contour error there{}\n",
      open, close);
  return s;
}

// G-code feed words around a G1's motion words: G93 / G94 before them when the mode changes, F after them when the
// value changes (every G93 block carries its F). `pieces`: the move is written as that many blocks (chords).
struct FeedState {
  std::optional<core::FeedMode> mode;
  double f = -1.0;
  std::string block(const core::Move& m, int pieces, const std::string& motion) {
    std::string pre;
    if (!mode || *mode != m.feed_mode) {
      pre = m.feed_mode == core::FeedMode::InverseTime ? "G93 " : "G94 ";
      mode = m.feed_mode;
      f = -1.0;
    }
    const double fv = m.feed_mode == core::FeedMode::InverseTime ? m.inverse_time_per_min * pieces : m.feed_mm_per_min;
    std::string post;
    if (m.feed_mode == core::FeedMode::InverseTime || fv != f) post = fmt::format(" F{:.9g}", fv);
    f = fv;
    return pre + motion + post;
  }
};

std::string rotary_words(const Context& c, const Eigen::VectorXd& q) {
  std::string w;
  for (Index a = 0; a < c.na; ++a) {
    const core::MachineAxis& ax = c.in.machine->axes[static_cast<std::size_t>(a)];
    if (ax.kind == core::AxisKind::Rotary) w += fmt::format(" {}{:.6f}", ax.name, q[a] * core::units::kRadToDeg);
  }
  return w;
}

}  // namespace

CompensatedProgram write_compensated_program(const CompensatedProgramInput& in) {
  Context c(in);
  CompensatedProgram out;
  const core::ToolPath& prog = *in.program;
  const core::ToolPath& ap = *in.axis_path;
  const bool chain = in.kinematics->family() != motion::KinematicFamily::Cartesian;
  const bool cl_program = !prog.moves.empty() && std::all_of(prog.moves.begin(), prog.moves.end(), is_cl);

  if (cl_program) {
    // APT CL: the initial pose (the first GOTO), then one GOTO per move.
    out.extension = "cl";
    std::string s = "PARTNO/VMSIM_COMPENSATED\n" + header(in, "$$ ", "");
    s += "UNITS/MM\nMULTAX/ON\n";
    if (prog.tool_diameter_mm > 0)
      s += fmt::format("CUTTER/{:.6f},{:.6f}\n", prog.tool_diameter_mm, prog.tool_corner_radius_mm);
    auto goto_words = [&](const Eigen::VectorXd& q, double tlo) {
      const motion::ToolPose p = in.kinematics->forward(q, tlo);
      return fmt::format("GOTO/{:.6f},{:.6f},{:.6f},{:.9f},{:.9f},{:.9f}\n", p.tip_mm.x(), p.tip_mm.y(), p.tip_mm.z(),
                         p.axis.x(), p.axis.y(), p.axis.z());
    };
    const double tlo0 = prog.moves.front().tool_length_offset_mm;
    s += goto_words(c.machine_axes(ap.initial_position) + c.delta.row(0).transpose(), tlo0);
    double feed = -1.0;
    for (std::size_t mi = 0; mi < prog.moves.size(); ++mi) {
      const core::Move& m = prog.moves[mi];
      // Arcs (CIRCLE/) as GOTOs through their image's points.
      const std::vector<Vec6> pts =
          chain_move_points(ap.moves[mi], ap.source_path, m.kind == core::MotionKind::Arc, in.chord_tolerance_mm);
      for (std::size_t i = 0; i < pts.size(); ++i) {
        if (m.rapid) {
          s += "RAPID\n";
        } else if (m.feed_mm_per_min != feed) {
          s += fmt::format("FEDRAT/MMPM,{:.6g}\n", m.feed_mm_per_min);
          feed = m.feed_mm_per_min;
        }
        s += goto_words(c.corrected(pts[i], mi, i + 1 == pts.size(), m.tool_length_offset_mm, out),
                        m.tool_length_offset_mm);
        ++out.blocks;
      }
    }
    s += "FINI\n";
    out.text = std::move(s);
    return out;
  }

  out.extension = "ngc";
  std::string s = header(in, "(", ")");
  s += "(X Y Z: the programmed point as the original program gives it, without tool length compensation)\n";
  s += "G21 G90 G17\n";
  FeedState fs;
  // Where the last block left the programmed point, in the words' coordinates (arcs' I J K are relative to it).
  Eigen::Vector3d last =
      prog.moves.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(prog.moves.front().start.head<3>());
  for (std::size_t mi = 0; mi < prog.moves.size(); ++mi) {
    const core::Move& m = prog.moves[mi];
    const core::Move& am = ap.moves[mi];
    const bool tcp = chain && (m.tcp || is_cl(m));
    // Arcs of 3-axis and joint programs stay arcs (G2/G3 about the programmed centre, to the corrected end: the radial
    // part of the correction at the ends, a steady radial lag whole; a spiral where the ends' corrections differ) so
    // the interpolator times them as the original's arcs; chords would slow it at every joint.
    const bool keep_arc = !tcp && m.kind == core::MotionKind::Arc;
    // (Arcs in pieces of at most 90 deg: a full circle's corrected end is not its corrected start.)
    const std::vector<Vec6> pts =
        tcp        ? chain_move_points(am, ap.source_path, m.kind == core::MotionKind::Arc, in.chord_tolerance_mm)
        : keep_arc ? move_points(am, ap.source_path, in.chord_tolerance_mm, 0.5 * core::units::kPi)
                   : move_points(am, ap.source_path, in.chord_tolerance_mm);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const double tlo = m.tool_length_offset_mm;
      const Eigen::VectorXd q = c.corrected(pts[i], mi, i + 1 == pts.size(), tlo, out);
      std::string w;
      Eigen::Vector3d xyz;
      if (chain && !tcp) {
        // Joint programming: the words are the axes (the reader adds the tool length offset to Z again).
        xyz = last;
        for (Index a = 0; a < c.na; ++a) {
          const core::MachineAxis& ax = in.machine->axes[static_cast<std::size_t>(a)];
          const double v = ax.kind == core::AxisKind::Rotary ? q[a] * core::units::kRadToDeg
                                                             : q[a] - (ax.program_axis == core::kZ ? tlo : 0.0);
          if (ax.kind == core::AxisKind::Linear && ax.program_axis <= core::kZ) xyz[ax.program_axis] = v;
          w += fmt::format("{}{}{:.6f}", w.empty() ? "" : " ", ax.name, v);
        }
      } else {
        const motion::ToolPose p = in.kinematics->forward(q, tlo);
        xyz = p.tip_mm;
        w = fmt::format("X{:.6f} Y{:.6f} Z{:.6f}", p.tip_mm.x(), p.tip_mm.y(), p.tip_mm.z());
        w += rotary_words(c, q);
      }
      if (keep_arc) {
        // I J K: the programmed centre relative to where this arc starts (the last block's corrected point).
        static constexpr char kWord[3] = {'I', 'J', 'K'};
        const core::PlaneAxes ax = core::plane_axes(m.plane);
        const int f = ax.axis1, g = ax.axis2;
        w += fmt::format(" {}{:.6f} {}{:.6f}", kWord[f], m.centre_mm[0] - last[f], kWord[g], m.centre_mm[1] - last[g]);
        const char* plane = m.plane == core::ArcPlane::XY ? "G17 " : m.plane == core::ArcPlane::ZX ? "G18 " : "G19 ";
        s += fs.block(m, static_cast<int>(pts.size()), plane + std::string(m.rotation < 0 ? "G2 " : "G3 ") + w) + "\n";
      } else {
        s += (m.rapid ? "G0 " + w : fs.block(m, static_cast<int>(pts.size()), "G1 " + w)) + "\n";
      }
      last = xyz;
      ++out.blocks;
    }
  }
  s += "G94\nM2\n";
  out.text = std::move(s);
  return out;
}

CompensatedProgram write_compensated_tcp_gcode(const CompensatedProgramInput& in) {
  Context c(in);
  if (in.kinematics->family() == motion::KinematicFamily::Cartesian)
    throw core::Error("compensated program: tool-centre-point G-code is for five-axis chains");
  CompensatedProgram out;
  out.extension = "ngc";
  const core::ToolPath& prog = *in.program;
  const core::ToolPath& ap = *in.axis_path;
  std::string s = header(in, "(", ")");
  s += "(tool-centre-point form: X Y Z the tool tip in the workpiece frame, the rotary words the rotary axes;)\n";
  s += "(run with the controller's five-axis transformation on: Siemens TRAORI, LinuxCNC M428; vmsim: [job] tcp = "
       "true)\n";
  s += "G21 G90 G17\n";
  auto words = [&](const Eigen::VectorXd& q, double tlo) {
    const motion::ToolPose p = in.kinematics->forward(q, tlo);
    return fmt::format("X{:.6f} Y{:.6f} Z{:.6f}", p.tip_mm.x(), p.tip_mm.y(), p.tip_mm.z()) + rotary_words(c, q);
  };
  if (!prog.moves.empty())
    s += "G0 " +
         words(c.machine_axes(ap.initial_position) + c.delta.row(0).transpose(),
               prog.moves.front().tool_length_offset_mm) +
         "\n";
  FeedState fs;
  for (std::size_t mi = 0; mi < prog.moves.size(); ++mi) {
    const core::Move& m = prog.moves[mi];
    const std::vector<Vec6> pts =
        chain_move_points(ap.moves[mi], ap.source_path, m.kind == core::MotionKind::Arc, in.chord_tolerance_mm);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const std::string motion =
          (m.rapid ? "G0 " : "G1 ") +
          words(c.corrected(pts[i], mi, i + 1 == pts.size(), m.tool_length_offset_mm, out), m.tool_length_offset_mm);
      s += (m.rapid ? motion : fs.block(m, static_cast<int>(pts.size()), motion)) + "\n";
      ++out.blocks;
    }
  }
  s += "G94\nM2\n";
  out.text = std::move(s);
  return out;
}

std::string write_dense_program(const Eigen::MatrixXd& setpoints, const Eigen::VectorXd& tlo_mm,
                                const core::Machine& machine, const motion::Kinematics& kin, double te, bool five,
                                const std::string& title) {
  const Index ns = setpoints.rows(), na = static_cast<Index>(machine.axes.size());
  if (ns < 1 || setpoints.cols() != na || tlo_mm.size() != ns)
    throw core::Error(fmt::format("dense program: {} x {} setpoints, {} tool length offsets, {} machine axes", ns,
                                  setpoints.cols(), tlo_mm.size(), na));
  std::string s;
  s += fmt::format(
      "(vmsim compensate: {} - the predictive-compensation paper predictive contour-error compensation, "
      "dense form)\n",
      title);
  s += "(one block per interpolation period Te; X Y Z: tool tip in the workpiece frame, as the original program)\n";
  if (five)
    s += "(five-axis: tool-centre-point form, X Y Z the tip and A B C the rotary axes; vmsim: [job] tcp = true)\n";
  s += "G21 G90 G17\n";
  Eigen::VectorXd q(na);
  std::vector<int> rotary;
  for (Index a = 0; a < na; ++a)
    if (machine.axes[static_cast<std::size_t>(a)].kind == core::AxisKind::Rotary) rotary.push_back(static_cast<int>(a));
  auto words = [&](Index k) {
    q = setpoints.row(k).transpose();
    const motion::ToolPose pose = kin.forward(q, tlo_mm[k]);
    std::string w = fmt::format("X{:.6f} Y{:.6f} Z{:.6f}", pose.tip_mm.x(), pose.tip_mm.y(), pose.tip_mm.z());
    for (int a : rotary)
      if (five || (setpoints.col(a).array() != setpoints(0, a)).any())
        w += fmt::format(" {}{:.6f}", machine.axes[static_cast<std::size_t>(a)].name, q[a] * core::units::kRadToDeg);
    return w;
  };
  s += "G0 " + words(0) + "\nG93\n";
  const double f = 60.0 / te;
  for (Index k = 1; k < ns; ++k) s += fmt::format("G1 {} F{:.1f}\n", words(k), f);
  s += "G94\nM2\n";
  return s;
}

}  // namespace vmsim::methods
