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

// How far a piece of a compensated arc may leave the corrected points between its ends (see arc_pieces): a tenth of
// a micrometre, below the contour errors the compensation removes (several micrometres on a circle at 3 m/min).
constexpr double kArcPieceToleranceMm = 0.1e-3;
// The smallest kink between two pieces of a compensated arc (see arc_pieces): five times the 1e-6 rad below which the
// interpolator takes a junction for tangent, well above what the words' 1e-6 mm rounding makes of it (~1e-7 rad).
constexpr double kMinKinkRad = 5e-6;

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
// value changes (every G93 block carries its F). `pieces`: the move is written as that many blocks (chords), or the
// move's length over the block's (a piece of an arc).
struct FeedState {
  std::optional<core::FeedMode> mode;
  double f = -1.0;
  std::string block(const core::Move& m, double pieces, const std::string& motion) {
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

// A piece of an arc as written: the words of its corrected end, that end in the words' coordinates, and the move's
// sweep over the piece's (the inverse-time feed of the piece).
struct ArcPiece {
  std::string words;
  Eigen::Vector3d end;
  double pieces = 1.0;
};

// Where the last arc piece written ended, for the next arc of the same circle (its centre, plane and direction).
struct ArcChain {
  bool open = false;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  core::ArcPlane plane = core::ArcPlane::XY;
  bool ccw = true;
  double slope = 0.0;  // d(radius)/d(angle) of the last piece, mm/rad
};

// The pieces a programmed arc is written in. A correction that varies along an arc needs more than new end points:
// each piece is an arc about the programmed centre from one corrected point to the next, its radius (and the normal
// coordinate of a helix) linear in the swept angle between theirs (LinuxCNC's and core/arc's spiral), so a piece holds
// the correction exactly at its ends and by linear interpolation between them. A piece ends where the corrected points
// of a fine grid (8 per longest piece) would leave it by more than kArcPieceToleranceMm, and spans at most
// arc_piece_max_angle_rad: where two pieces meet at a kink (their radii change at different rates) the interpolator
// blends the corner over up to half of each, and a long blend leaves the arc by up to the interpolation tolerance
// (the cause of the 90-degree pieces' 26.7 um on a circle). And every kink is at least kMinKinkRad: the interpolator
// (motion/smooth_path) stops the axes at a junction tangent within 1e-6 rad but not within 1e-9 whose curvature jumps
// (its rounding target is then below what a blend resolves), which the 1e-6 mm rounding of the words alone makes of
// pieces of one circle; where the correction would leave a smaller kink, the piece's end moves radially by the
// few nanometres that make it kMinKinkRad. `last`: where the previous block ended (this arc's start).
template <class Words>
std::vector<ArcPiece> arc_pieces(Context& c, const core::Move& m, const core::Move& am, const std::string& file,
                                 const std::string& axis_file, std::size_t mi, const Eigen::Vector3d& last,
                                 const Words& words, ArcChain& chain, CompensatedProgram& out) {
  const core::ArcFrame wf = core::arc_frame(m, file);        // the words' coordinates: centre, plane, angles
  const core::ArcFrame af = core::arc_frame(am, axis_file);  // axis space: the points corrected
  const int longest = wf.chords(0.0, arc_piece_max_angle_rad(std::max(wf.start_radius_mm, wf.end_radius_mm)));
  const int n = 8 * longest;
  std::vector<Eigen::Vector3d> p(static_cast<std::size_t>(n) + 1);
  std::vector<Eigen::VectorXd> q(p.size());
  std::vector<double> phi(p.size()), rho(p.size());
  const double c1 = wf.centre_mm[0], c2 = wf.centre_mm[1];
  for (int i = 0; i <= n; ++i) {
    const auto u = static_cast<std::size_t>(i);
    if (i == 0) {
      p[0] = last;
    } else {
      q[u] = c.corrected(af.point_at(static_cast<double>(i) / n), mi, i == n, m.tool_length_offset_mm, out);
      (void)words(q[u], p[u]);
    }
    // The angle unwrapped along the sweep: the programmed point's plus the correction's (far below pi).
    const double nominal = wf.angle_at(static_cast<double>(i) / n);
    const double d = std::atan2(p[u][wf.axis2] - c2, p[u][wf.axis1] - c1) - nominal;
    phi[u] = nominal + std::remainder(d, 2 * core::units::kPi);
    rho[u] = std::hypot(p[u][wf.axis1] - c1, p[u][wf.axis2] - c2);
  }
  const double max_angle = std::abs(wf.sweep_rad) / longest * (1 + 1e-9);
  // The largest distance of the grid points strictly between a and b from the piece a -> b.
  auto deviation = [&](std::size_t a, std::size_t b) {
    double worst = 0.0;
    for (std::size_t i = a + 1; i < b; ++i) {
      const double g = (phi[i] - phi[a]) / (phi[b] - phi[a]);
      worst =
          std::max(worst, std::hypot(rho[i] - (rho[a] + g * (rho[b] - rho[a])),
                                     p[i][wf.normal] - (p[a][wf.normal] + g * (p[b][wf.normal] - p[a][wf.normal]))));
    }
    return worst;
  };
  const bool ccw = wf.sweep_rad > 0;
  const bool same_circle = chain.open && chain.plane == m.plane && chain.ccw == ccw &&
                           (chain.centre - wf.centre_mm).norm() <= 1e-9 * std::max(1.0, wf.start_radius_mm);
  bool has_prev = same_circle;
  double prev_slope = chain.slope;
  double start_rho = rho[0];
  std::vector<ArcPiece> pieces;
  for (std::size_t a = 0, size = p.size(); a + 1 < size;) {
    std::size_t b = a + 1;
    while (b + 1 < size && std::abs(phi[b + 1] - phi[a]) <= max_angle && deviation(a, b + 1) <= kArcPieceToleranceMm)
      ++b;
    const double span = phi[b] - phi[a];
    double slope = (rho[b] - start_rho) / span;
    Eigen::VectorXd qb = q[b];
    if (has_prev && std::abs(slope - prev_slope) < kMinKinkRad * rho[b]) {
      // Too small a kink: the end moves radially so that the slopes differ by twice kMinKinkRad.
      const double want = prev_slope + (slope >= prev_slope ? 2.0 : -2.0) * kMinKinkRad * rho[b];
      const double dr = (want - slope) * span;
      const double ca = std::cos(phi[b]), sa = std::sin(phi[b]);
      for (Index ax = 0; ax < c.na; ++ax) {
        const int pa = c.in.machine->axes[static_cast<std::size_t>(ax)].program_axis;
        if (c.in.machine->axes[static_cast<std::size_t>(ax)].kind != core::AxisKind::Linear) continue;
        if (pa == wf.axis1) qb[ax] += dr * ca;
        if (pa == wf.axis2) qb[ax] += dr * sa;
      }
      slope = want;
    }
    ArcPiece piece;
    piece.words = words(qb, piece.end);
    piece.pieces = std::abs(wf.sweep_rad / span);
    pieces.push_back(std::move(piece));
    start_rho = std::hypot(pieces.back().end[wf.axis1] - c1, pieces.back().end[wf.axis2] - c2);
    prev_slope = slope;
    has_prev = true;
    a = b;
  }
  chain = {true, wf.centre_mm, m.plane, ccw, prev_slope};
  return pieces;
}

}  // namespace

double arc_piece_max_angle_rad(double radius_mm) {
  // A G2 quintic over an arc of angle phi (the interpolator's blend, its tangent length the chord) leaves it by about
  // 0.5 R phi^6 (measured from 1 to 20 degrees): phi for 0.01 um, at most a quarter turn.
  constexpr double kBlendDeviationMm = 1e-5;
  return std::clamp(std::pow(2.0 * kBlendDeviationMm / std::max(radius_mm, 1e-9), 1.0 / 6.0), 1e-3,
                    0.5 * core::units::kPi);
}

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
  ArcChain arc_chain;
  // Where the last block left the programmed point, in the words' coordinates (arcs' I J K are relative to it).
  Eigen::Vector3d last =
      prog.moves.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(prog.moves.front().start.head<3>());
  for (std::size_t mi = 0; mi < prog.moves.size(); ++mi) {
    const core::Move& m = prog.moves[mi];
    const core::Move& am = ap.moves[mi];
    const bool tcp = chain && (m.tcp || is_cl(m));
    const double tlo = m.tool_length_offset_mm;
    // The words of a block to machine axes q, and the programmed point they name (the words' coordinates).
    auto words = [&](const Eigen::VectorXd& q, Eigen::Vector3d& xyz) {
      std::string w;
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
        return w;
      }
      const motion::ToolPose p = in.kinematics->forward(q, tlo);
      xyz = p.tip_mm;
      return fmt::format("X{:.6f} Y{:.6f} Z{:.6f}", p.tip_mm.x(), p.tip_mm.y(), p.tip_mm.z()) + rotary_words(c, q);
    };
    if (!tcp && m.kind == core::MotionKind::Arc) {
      // Arcs of 3-axis and joint programs stay arcs, so the interpolator times them as the original's arcs (chords
      // would slow it at every joint), in pieces about the programmed centre that follow the correction (below).
      for (const ArcPiece& piece :
           arc_pieces(c, m, am, prog.source_path, ap.source_path, mi, last, words, arc_chain, out)) {
        // I J K: the programmed centre relative to where this piece starts (the last block's corrected point).
        static constexpr char kWord[3] = {'I', 'J', 'K'};
        const core::PlaneAxes ax = core::plane_axes(m.plane);
        const int f = ax.axis1, g = ax.axis2;
        const std::string w = piece.words + fmt::format(" {}{:.6f} {}{:.6f}", kWord[f], m.centre_mm[0] - last[f],
                                                        kWord[g], m.centre_mm[1] - last[g]);
        const char* plane = m.plane == core::ArcPlane::XY ? "G17 " : m.plane == core::ArcPlane::ZX ? "G18 " : "G19 ";
        s += fs.block(m, piece.pieces, plane + std::string(m.rotation < 0 ? "G2 " : "G3 ") + w) + "\n";
        last = piece.end;
        ++out.blocks;
      }
      continue;
    }
    arc_chain.open = false;
    const std::vector<Vec6> pts =
        tcp ? chain_move_points(am, ap.source_path, m.kind == core::MotionKind::Arc, in.chord_tolerance_mm)
            : move_points(am, ap.source_path, in.chord_tolerance_mm);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      Eigen::Vector3d xyz;
      const std::string w = words(c.corrected(pts[i], mi, i + 1 == pts.size(), tlo, out), xyz);
      s += (m.rapid ? "G0 " + w : fs.block(m, static_cast<int>(pts.size()), "G1 " + w)) + "\n";
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
