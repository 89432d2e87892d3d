// APT CL (cutter location) files as CAM systems write them: CATIA "APT source", NX CLSF, Creo/Pro-E NCL,
// Mastercam, hyperMILL and PowerMILL APT output, and Autodesk's ISO 4343 APT posts.
//
// What a record looks like (ISO 4343, and what the CAM systems above actually write):
//   MAJOR/arg, arg, ...      e.g. GOTO  / 10.0000, 20.0000, 5.0000, 0.000000, 0.000000, 1.000000
//   MAJOR [free text]        e.g. RAPID, FINI, MULTAX, PARTNO my part (CATIA writes PARTNO without a slash)
//   $$ comment               anywhere on a line; the rest of the line is ignored
//   ... ,$                   a line ending in a single '$' continues on the next line
// Major words are case-insensitive; runs of blanks inside them collapse ("TOOL PATH/" in NX CLSF).
//
// Motion semantics (the CL file already holds the tool tip positions; nothing is offset here):
//   FROM/x,y,z[,i,j,k]        start point. Before any motion it is the initial position; later it is a rapid
//                             move to that point (what posts do with a from-move).
//   GOTO/x,y,z[,i,j,k]        straight move of the tool tip; i,j,k the tool axis (normalised here).
//   GODLTA/dx,dy,dz | /d      incremental move; /d moves d along the current tool axis.
//   GOHOME                    move back to the FROM/ point.
//   CIRCLE/xc,yc,zc,i,j,k,r[,...] then GOTO/   arc (or helix) to the GOTO end point about the axis (i,j,k),
//                             counter-clockwise about the axis (right-hand rule), as ISO 4343 and NX CLSF define
//                             it. NX appends tolerance and tool data after r; they are ignored. (Autodesk's
//                             MfgSuite and CAMplete APT posts write the opposite sense: such files must be
//                             re-posted with an ISO 4343 post.)
//   MOVARC/xc,yc,zc,i,j,k,r[,ANGLE,deg] then GOTO/   the same arc, as Autodesk's ISO 4343 post writes it; ANGLE
//                             gives the swept angle, which distinguishes full turns.
//   RAPID                     the next motion only is a rapid; the last FEDRAT/ applies again afterwards.
//   FEDRAT/f[,MMPM|IPM|PERMIN], FEDRAT/MMPM|IPM,f   feed per minute (no unit word: the file's UNITS).
//   TLAXIS/i,j,k              tool axis for GOTOs that give no i,j,k under MULTAX/OFF (default +Z).
//   MULTAX[/ON|/OFF]          the tool axis is modal: a GOTO without i,j,k keeps the last one given (NX CLSF writes it
//                             only when it changes, and no MULTAX); under MULTAX/OFF such a GOTO takes TLAXIS's.
//   UNITS/MM|INCHES           lengths and feeds that follow are in that unit; converted to mm here. A file without
//                             it is in AptOptions::default_unit ([job] program_units), else mm with a warning.
//   CUTTER/d[,r,...], TLDATA/MILL,d,r,l,...   tool diameter, corner radius (and length): ToolPath::tool_* the first
//                             one, ToolPath::program_tools every one the moves use. A record whose geometry differs
//                             from the tool in use starts a new tool (NX changes tools by TLDATA/ alone).
//   LOADTL/n, LOAD/TOOL,n     active tool number of the moves that follow. Numbering (Move::tool_number): the
//                             program's LOAD/TOOL numbers when it has any (a number whose geometry changes later
//                             gives the new geometry the next free number, with a warning); without LOAD/TOOL,
//                             several geometries are numbered 1, 2, ... in order of first appearance, and a single
//                             one stays tool 0 (no tool change, as G-code without T).
//   MSYS/x,y,z,xi,xj,xk,yi,yj,yk   NX: the frame (origin, X and Y directions) the coordinates that follow are in.
//                             The first MSYS/ frame is the workpiece frame; the data under a later, different one is
//                             carried into it.
//   INDIRV/i,j,k              checked and ignored: it aims the next GO command of part-program source, and CL
//                             files contain only GOTOs, which do not use it.
//   FINI                      end of the CL file; anything after it is not read.
//   CIRCLE/ about an axis not parallel to X, Y or Z (NX on tilted planes): chords in the circle's own plane, within
//                             kTiltedArcSag_mm (ToolPath arcs lie in XY, ZX or YZ).
//
// Accepted and ignored (kNonMotionWords below), because they neither move the tool nor change what the
// coordinates mean in the workpiece frame: PARTNO MACHIN MODE SELECT SELCTL TOOLNO TPRINT PPRINT PRINT INSERT
// SPINDL COOLNT END STOP OPSTOP OPSKIP PAINT "TOOL PATH" END-OF-PATH AUTOPS INTOL OUTTOL TOLER LINTOL
// CLEARP THICK OFSTNO SEQNO CLAMP HEAD TURRET LEADER REWIND NOPOST DISPLY PPLOT CSI_TOOL_PATH OPERATION PITCH;
// CUTCOM/OFF and CYCLE/OFF. NX's information window wraps the CLSF in a listing: its header lines
// ("Information listing created by<TAB>...", "Date<TAB>...", "Current work part<TAB>...", "Node name<TAB>...") and its
// last line ("Tool Path Listing has N lines.") are skipped.
// Known, without motion, but with an effect vmsim does not model (kUnmodelledWords): DELAY and DWELL (ToolPath
// carries no time), CUTCOM other than OFF (the controller's radius offset), ORIGIN (places the workpiece on the
// machine): errors, or warnings with AptOptions::lenient ([job] program_lenient).
//
// Refused with an error naming the line and the word: words that move the tool in a way this reader does not
// model (part-program GO commands, canned cycles, table rotations, CL transforms), and any word not listed
// here: a word that might move the tool must never be skipped silently.
#include "program/apt.hpp"

#include "core/error.hpp"
#include "core/units.hpp"

#include <Eigen/Geometry>

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace vmsim::program {

namespace {

constexpr std::string_view kNonMotionWords[] = {
    "PARTNO", "MACHIN", "MODE",   "SELECT", "SELCTL", "TOOLNO", "TPRINT",        "PPRINT",    "PRINT",       "INSERT",
    "SPINDL", "COOLNT", "END",    "STOP",   "OPSTOP", "OPSKIP", "PAINT",         "TOOL PATH", "END-OF-PATH", "AUTOPS",
    "INTOL",  "OUTTOL", "TOLER",  "LINTOL", "CLEARP", "THICK",  "OFSTNO",        "SEQNO",     "CLAMP",       "HEAD",
    "TURRET", "LEADER", "REWIND", "NOPOST", "DISPLY", "PPLOT",  "CSI_TOOL_PATH", "OPERATION", "PITCH"};

// Known, without motion, with an effect vmsim does not model: errors unless AptOptions::lenient (then warnings).
constexpr std::string_view kUnmodelledWords[] = {"DELAY", "DWELL", "CUTCOM", "ORIGIN"};

// Chord sag of CIRCLE/ records about a tilted axis (as the Sinumerik reader's oblique-plane arcs): 1 um, far below
// what a CL file's 4 decimals of an inch (2.5 um) resolve.
constexpr double kTiltedArcSag_mm = 1e-3;

// Words whose argument is free text: their arguments are not split or checked.
constexpr std::string_view kTextWords[] = {"PARTNO", "PPRINT", "TPRINT", "PRINT", "INSERT", "OPERATION"};

// Words that move the tool (or change what later coordinates mean) in ways this reader does not model.
constexpr std::string_view kUnsupportedMotionWords[] = {"GO",     "GOFWD",  "GOLFT",  "GORGT",  "GOBACK", "GOUP",
                                                        "GODOWN", "RETRCT", "TRACUT", "COPY",   "INDEX",  "TRANS",
                                                        "ROTABL", "ROTATE", "ROTHED", "THREAD", "PIVOTZ"};

template <std::size_t N>
bool contains(const std::string_view (&words)[N], std::string_view w) {
  return std::find(std::begin(words), std::end(words), w) != std::end(words);
}

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; };
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// For messages: a garbled file must not put control bytes or megabytes of text into an error message.
std::string printable(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  if (s.size() > 40) out += "...";
  return out;
}

// Numbers in messages: short, and readable for 1e300 as well as for 0.0001.
std::string num(double v) {
  std::ostringstream os;
  os.precision(6);
  os << v;
  return os.str();
}

// NX's information window (Tool Path > List, saved as .txt) puts a header of "key<TAB>value" lines before the CLSF and
// "Tool Path Listing has N lines." after it: part of the listing, not records.
bool nx_listing_line(std::string_view line) {
  for (std::string_view key : {"Information listing created by\t", "Date\t", "Current work part\t", "Node name\t"})
    if (line.substr(0, key.size()) == key) return true;
  line = trim(line);
  constexpr std::string_view head = "Tool Path Listing has ", tail = " lines.";
  if (line.size() <= head.size() + tail.size() || line.substr(0, head.size()) != head ||
      line.substr(line.size() - tail.size()) != tail)
    return false;
  const std::string_view n = line.substr(head.size(), line.size() - head.size() - tail.size());
  return std::all_of(n.begin(), n.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// A logical record: the text of one or more physical lines (continuations joined, comments removed).
struct Record {
  int line = 0;  // first physical line
  std::string text;
};

std::vector<Record> split_records(const std::string& content) {
  std::vector<Record> records;
  Record current;
  bool continuing = false;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos < content.size()) {
    std::size_t eol = content.find_first_of("\r\n", pos);
    if (eol == std::string::npos) eol = content.size();
    std::string_view line(content.data() + pos, eol - pos);
    ++line_no;
    // "\r\n", "\n" and a lone "\r" each end one line.
    pos = eol + 1;
    if (eol < content.size() && content[eol] == '\r' && pos < content.size() && content[pos] == '\n') ++pos;

    if (!continuing && nx_listing_line(line)) continue;
    if (auto c = line.find("$$"); c != std::string_view::npos) line = line.substr(0, c);
    line = trim(line);
    bool continues = false;
    if (!line.empty() && line.back() == '$') {
      continues = true;
      line.remove_suffix(1);
    }
    if (!continuing) {
      current = Record{line_no, std::string()};
    }
    current.text.append(line);
    continuing = continues;
    if (!continuing) {
      if (!trim(current.text).empty()) records.push_back(std::move(current));
      current = Record{};
    }
  }
  // A file that ends inside a continued record: the record is whatever was read (truncated files get an
  // error from the record's own checks, not a silent drop).
  if (continuing && !trim(current.text).empty()) records.push_back(std::move(current));
  return records;
}

enum class NumberStatus { Ok, NotANumber, OutOfRange, NotFinite };

NumberStatus parse_number(std::string_view s, double& out) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') {  // from_chars does not take a leading '+'
    s.remove_prefix(1);
    if (!s.empty() && (s.front() == '+' || s.front() == '-')) return NumberStatus::NotANumber;
  }
  if (s.empty()) return NumberStatus::NotANumber;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out, std::chars_format::general);
  if (ec == std::errc::result_out_of_range) return NumberStatus::OutOfRange;
  if (ec != std::errc() || ptr != s.data() + s.size()) return NumberStatus::NotANumber;
  if (!std::isfinite(out)) return NumberStatus::NotFinite;
  return NumberStatus::Ok;
}

struct Statement {
  int line = 0;
  std::string word;               // major word, upper case, blanks collapsed
  bool slash = false;             // the record had "WORD/..."
  std::string rest;               // text after the slash (or after the word when there is no slash)
  std::vector<std::string> args;  // rest split at commas, trimmed (upper case)
};

Statement parse_statement(const Record& r) {
  Statement st;
  st.line = r.line;
  std::string_view text = trim(r.text);
  // Free-text words first: CATIA's "PARTNO part/1" must not be split at the slash inside its text.
  const std::size_t token_end = std::min(text.find_first_of(" \t/"), text.size());
  if (contains(kTextWords, upper(text.substr(0, token_end)))) {
    st.word = upper(text.substr(0, token_end));
    std::string_view rest = trim(text.substr(token_end));
    st.slash = !rest.empty() && rest.front() == '/';
    if (st.slash) rest.remove_prefix(1);
    st.rest = std::string(trim(rest));
    return st;
  }
  const std::size_t slash = text.find('/');
  std::string_view word;
  if (slash != std::string_view::npos) {
    st.slash = true;
    word = trim(text.substr(0, slash));
    st.rest = std::string(trim(text.substr(slash + 1)));
  } else {
    const std::size_t blank = text.find_first_of(" \t");
    word = text.substr(0, blank);
    if (blank != std::string_view::npos) st.rest = std::string(trim(text.substr(blank)));
  }
  // Collapse blank runs inside the word ("TOOL  PATH" -> "TOOL PATH").
  bool blank = false;
  for (char c : word) {
    if (c == ' ' || c == '\t') {
      blank = true;
      continue;
    }
    if (blank && !st.word.empty()) st.word += ' ';
    blank = false;
    st.word += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  if (st.slash) {
    std::string_view rest = st.rest;
    while (true) {
      const std::size_t comma = rest.find(',');
      st.args.push_back(upper(trim(rest.substr(0, comma))));
      if (comma == std::string_view::npos) break;
      rest.remove_prefix(comma + 1);
    }
    if (st.args.size() == 1 && st.args[0].empty()) st.args.clear();  // "WORD/" with nothing after it
  }
  return st;
}

struct PlaneAxes {
  core::ArcPlane plane;
  int first, second, normal;  // indices into x y z
};

class AptReader {
 public:
  AptReader(std::string file, const AptOptions& options) : file_(std::move(file)), options_(options) {
    path_.source_path = file_;
    inches_ = options_.default_unit == LengthUnit::Inch;
  }

  core::ToolPath read(const std::string& content) {
    for (const Record& rec : split_records(content)) {
      const Statement st = parse_statement(rec);
      if (!handle(st)) break;  // FINI
    }
    if (!units_line_ && !options_.default_unit)
      warn(0,
           "no UNITS/ record and no [job] program_units: lengths read as mm (NX CLSF files of inch parts have no "
           "UNITS/; give program_units = \"inch\" in the job)");
    if (pending_arc_)
      fail(pending_arc_->line,
           pending_arc_->word + "/ is not followed by its GOTO/ end point (expected GOTO/x,y,z after it)");
    if (!position_) {
      throw core::Error(core::located(
          file_, 0, "no FROM/ or GOTO/ record: nothing to machine (expected an APT CL file with GOTO/x,y,z records)"));
    }
    if (!multi_axis_file_) {
      for (core::Move& m : path_.moves) m.tool_axis_start = m.tool_axis_end = std::nullopt;
    }
    number_tools();
    return std::move(path_);
  }

 private:
  struct PendingArc {
    int line = 0;
    std::string word;
    Eigen::Vector3d centre;
    Eigen::Vector3d axis;  // unit
    double radius = 0;
    std::optional<double> sweep_deg;  // MOVARC/...,ANGLE,deg
  };

  [[noreturn]] void fail(int line, const std::string& message) const {
    throw core::Error(core::located(file_, line, message));
  }
  void warn(int line, const std::string& message) { path_.warnings.push_back(core::located(file_, line, message)); }

  // Into the workpiece frame (the first MSYS/ frame) from the frame of the current MSYS/.
  Eigen::Vector3d to_work(const Eigen::Vector3d& p) const { return frame_r_ * p + frame_o_; }
  Eigen::Vector3d to_work_dir(const Eigen::Vector3d& d) const { return frame_r_ * d; }

  double number(const Statement& st, std::size_t i, const char* expected) const {
    if (i >= st.args.size())
      fail(st.line, st.word + "/ has " + std::to_string(st.args.size()) + " values (expected " + expected + ")");
    double v = 0;
    switch (parse_number(st.args[i], v)) {
      case NumberStatus::Ok:
        return v;
      case NumberStatus::OutOfRange:
        fail(st.line, st.word + "/ value " + std::to_string(i + 1) + " \"" + printable(st.args[i]) +
                          "\" is out of the range of a double (expected " + expected + ")");
      case NumberStatus::NotFinite:
        fail(st.line, st.word + "/ value " + std::to_string(i + 1) + " \"" + printable(st.args[i]) +
                          "\" is not a finite number (expected " + expected + ")");
      case NumberStatus::NotANumber:
        break;
    }
    fail(st.line, st.word + "/ value " + std::to_string(i + 1) + " \"" + printable(st.args[i]) +
                      "\" is not a number (expected " + expected + ")");
  }

  std::vector<double> numbers(const Statement& st, const char* expected) const {
    std::vector<double> v;
    for (std::size_t i = 0; i < st.args.size(); ++i) v.push_back(number(st, i, expected));
    return v;
  }

  Eigen::Vector3d unit_axis(const Statement& st, double i, double j, double k) const {
    Eigen::Vector3d a(i, j, k);
    const double n = a.norm();
    // Components up to 1e300 keep the norm finite; beyond that (or for a zero vector) there is no direction.
    if (!(n > 1e-12) || !std::isfinite(n))
      fail(st.line, st.word + "/ axis vector (" + num(i) + ", " + num(j) + ", " + num(k) + ") has " +
                        (std::isfinite(n) ? "zero length" : "no finite length") + " (expected a direction i, j, k)");
    return a / n;
  }

  void no_args(const Statement& st) const {
    if (st.slash || !st.rest.empty())
      fail(st.line, st.word + " takes no arguments, found \"" + printable(st.rest) + "\"");
  }

  double length_unit() const { return inches_ ? core::units::kInchToMm : 1.0; }

  // One straight move (or the initial position) to `target` with tool axis `axis`.
  void go(const Statement& st, const Eigen::Vector3d& target, const Eigen::Vector3d& axis) {
    const bool rapid = rapid_next_;
    rapid_next_ = false;
    if (pending_arc_) {
      arc_to(st, target, axis);
      return;
    }
    if (!position_) {
      position_ = target;
      axis_ = axis;
      path_.initial_position.head<3>() = target;
      return;
    }
    core::Move m = make_move(st, rapid, axis);
    m.end.head<3>() = target;
    // Zero-length moves are dropped; a move that only turns the tool axis is kept, as the five-axis machine
    // has to move its rotary axes for it.
    const bool turns = (axis - axis_).norm() > 1e-12;
    if ((target - *position_).norm() > 1e-9 || turns) push_move(m);
    position_ = target;
    axis_ = axis;
  }

  core::Move make_move(const Statement& st, bool rapid, const Eigen::Vector3d& axis) const {
    if (!rapid && !(feed_mm_per_min_ > 0))
      fail(st.line, st.word + "/ cuts at feed before any FEDRAT/ (expected FEDRAT/f or RAPID before it)");
    core::Move m;
    m.rapid = rapid;
    m.start.head<3>() = *position_;
    m.end.head<3>() = *position_;
    m.feed_mode = core::FeedMode::UnitsPerMinute;
    m.feed_mm_per_min = rapid ? 0.0 : feed_mm_per_min_;  // rapids carry no programmed feed: the machine's rapid rate
    m.tool_axis_start = axis_;
    m.tool_axis_end = axis;
    m.tool_number = tool_number_;
    m.source_line = st.line;
    return m;
  }

  void arc_to(const Statement& st, const Eigen::Vector3d& target, const Eigen::Vector3d& axis) {
    const PendingArc arc = *pending_arc_;
    pending_arc_.reset();
    const std::string where = arc.word + "/ on line " + std::to_string(arc.line);
    // ToolPath arcs lie in XY, ZX or YZ (LinuxCNC ARC_FEED); an arc about another axis becomes chords in its plane.
    int m = 0;
    arc.axis.cwiseAbs().maxCoeff(&m);
    for (int i = 0; i < 3; ++i)
      if (i != m && std::abs(arc.axis[i]) > 1e-6) {
        tilted_arc_to(st, arc, target, axis);
        return;
      }
    static constexpr PlaneAxes kPlanes[3] = {
        {core::ArcPlane::YZ, 1, 2, 0}, {core::ArcPlane::ZX, 2, 0, 1}, {core::ArcPlane::XY, 0, 1, 2}};
    const PlaneAxes p = kPlanes[m];
    const Eigen::Vector2d c(arc.centre[p.first], arc.centre[p.second]);
    const Eigen::Vector2d s((*position_)[p.first], (*position_)[p.second]);
    const Eigen::Vector2d e(target[p.first], target[p.second]);
    const double rs = (s - c).norm(), re = (e - c).norm();
    // CAM systems print 4 to 6 decimals; a radius off by more than 10 µm (or 0.1 %) is a different arc.
    const double tol = std::max(0.01, 1e-3 * arc.radius);
    if (std::abs(rs - arc.radius) > tol)
      fail(st.line, "arc start is " + num(rs) + " mm from the centre of " + where + ", radius " + num(arc.radius) +
                        " mm (expected the tool on the circle when the arc starts)");
    if (std::abs(re - arc.radius) > tol)
      fail(st.line, "GOTO/ end point is " + num(re) + " mm from the centre of " + where + ", radius " +
                        num(arc.radius) + " mm (expected the arc's end point on its circle)");
    // Counter-clockwise about the axis (ISO 4343): positive rotation when the axis points along +normal.
    int turns = 1;
    if (arc.sweep_deg) turns = std::max(1, static_cast<int>(std::ceil(*arc.sweep_deg / 360.0 - 1e-9)));
    core::Move mv = make_move(st, false, axis);
    mv.source_line = arc.line;  // the arc is the CIRCLE/ record's; its GOTO/ only gives the end point
    mv.kind = core::MotionKind::Arc;
    mv.plane = p.plane;
    mv.centre_mm = c;
    mv.rotation = arc.axis[m] > 0 ? turns : -turns;
    mv.end.head<3>() = target;
    push_move(mv);  // start == end is a full circle, never a zero-length move
    position_ = target;
    axis_ = axis;
  }

  // An arc (or helix) about a tilted axis n, counter-clockwise about n (ISO 4343): chords within kTiltedArcSag_mm of
  // it, the height along n and the radius linear in the swept angle (as core/arc for the coordinate planes), the tool
  // axis along the great circle between its end values.
  void tilted_arc_to(const Statement& st, const PendingArc& arc, const Eigen::Vector3d& target,
                     const Eigen::Vector3d& axis) {
    const std::string where = arc.word + "/ on line " + std::to_string(arc.line);
    const Eigen::Vector3d& n = arc.axis;
    const Eigen::Vector3d rs3 = *position_ - arc.centre, re3 = target - arc.centre;
    const double hs = n.dot(rs3), he = n.dot(re3);
    const Eigen::Vector3d us = rs3 - hs * n, ue = re3 - he * n;
    const double rs = us.norm(), re = ue.norm();
    const double tol = std::max(0.01, 1e-3 * arc.radius);
    if (std::abs(rs - arc.radius) > tol)
      fail(st.line, "arc start is " + num(rs) + " mm from the axis of " + where + ", radius " + num(arc.radius) +
                        " mm (expected the tool on the circle when the arc starts)");
    if (std::abs(re - arc.radius) > tol)
      fail(st.line, "GOTO/ end point is " + num(re) + " mm from the axis of " + where + ", radius " + num(arc.radius) +
                        " mm (expected the arc's end point on its circle)");
    // Angle from us to ue about n, counter-clockwise, in (0, 2 pi]; a whole turn when they coincide.
    const Eigen::Vector3d e1 = us / rs, e2 = n.cross(e1);
    double sweep = std::atan2(ue.dot(e2), ue.dot(e1));
    if (sweep <= 1e-12) sweep += 2 * core::units::kPi;
    if (arc.sweep_deg) {
      const int turns = std::max(1, static_cast<int>(std::ceil(*arc.sweep_deg / 360.0 - 1e-9)));
      sweep += 2 * core::units::kPi * (turns - 1);
    }
    const double r_max = std::max(rs, re);
    const double step = 2 * std::acos(std::max(0.0, 1 - kTiltedArcSag_mm / r_max));
    const int chords = std::max(1, static_cast<int>(std::ceil(sweep / std::max(step, 1e-6))));
    if (chords > 100'000)
      fail(arc.line, where + " needs more than 100 000 chords of 1 um sag (expected a radius below 2 km)");
    const Eigen::Vector3d a0 = axis_;
    const double turn = std::atan2(a0.cross(axis).norm(), a0.dot(axis));
    for (int k = 1; k <= chords; ++k) {
      const double f = static_cast<double>(k) / chords, ang = f * sweep, r = rs + f * (re - rs);
      Eigen::Vector3d p = arc.centre + (hs + f * (he - hs)) * n + r * (std::cos(ang) * e1 + std::sin(ang) * e2);
      if (k == chords) p = target;
      Eigen::Vector3d ax = axis;
      if (k < chords && turn > 1e-12) {
        // Spherical interpolation of the tool axis (a great circle, as the kinematics turn it).
        const double st_ = std::sin(turn);
        ax = (std::sin((1 - f) * turn) * a0 + std::sin(f * turn) * axis) / st_;
      }
      core::Move mv = make_move(st, false, ax);
      mv.source_line = arc.line;
      mv.end.head<3>() = p;
      push_move(mv);
      position_ = p;
      axis_ = ax;
    }
  }

  // Returns false at FINI.
  bool handle(const Statement& st) {
    const std::string& w = st.word;
    if (w == "GOTO" || w == "FROM") {
      const std::vector<double> v = numbers(st, "x, y, z[, i, j, k]");
      if (v.size() != 3 && v.size() != 6)
        fail(st.line, w + "/ has " + std::to_string(v.size()) + " values (expected x, y, z or x, y, z, i, j, k)");
      const Eigen::Vector3d p = to_work(Eigen::Vector3d(v[0], v[1], v[2]) * length_unit());
      // The tool axis is modal (NX writes it only when it changes); MULTAX/OFF: TLAXIS's.
      Eigen::Vector3d axis = multax_off_ ? tlaxis_ : last_given_axis_;
      if (v.size() == 6) {
        axis = last_given_axis_ = to_work_dir(unit_axis(st, v[3], v[4], v[5]));
        multi_axis_file_ = true;
      }
      if (!p.allFinite()) fail(st.line, w + "/ position is out of range after the unit conversion");
      if (w == "FROM") {
        if (pending_arc_)
          fail(st.line, "FROM/ follows " + pending_arc_->word + "/ on line " + std::to_string(pending_arc_->line) +
                            " (expected GOTO/ with the arc's end point)");
        if (!position_) {
          rapid_next_ = false;
          from_ = p;
          go(st, p, axis);
          return true;
        }
        from_ = p;
        rapid_next_ = true;  // a later FROM/ is a rapid to the new start point
      }
      go(st, p, axis);
      return true;
    }
    if (w == "GODLTA") {
      if (!position_) fail(st.line, "GODLTA/ before any FROM/ or GOTO/ (expected a start position first)");
      if (pending_arc_)
        fail(st.line, "GODLTA/ follows " + pending_arc_->word + "/ (expected GOTO/ with the arc's end point)");
      const std::vector<double> v = numbers(st, "dx, dy, dz or a distance along the tool axis");
      Eigen::Vector3d d;
      if (v.size() == 3)
        d = to_work_dir(Eigen::Vector3d(v[0], v[1], v[2]) * length_unit());
      else if (v.size() == 1)
        d = axis_ * v[0] * length_unit();
      else
        fail(st.line, "GODLTA/ has " + std::to_string(v.size()) +
                          " values (expected dx, dy, dz or one distance along the tool axis)");
      const Eigen::Vector3d target = *position_ + d;
      if (!target.allFinite()) fail(st.line, "GODLTA/ moves out of the range of a double");
      go(st, target, axis_);
      return true;
    }
    if (w == "GOHOME") {
      no_args(st);
      if (!from_) fail(st.line, "GOHOME without a FROM/ point (expected FROM/x,y,z earlier in the file)");
      if (pending_arc_)
        fail(st.line, "GOHOME follows " + pending_arc_->word + "/ (expected GOTO/ with the arc's end point)");
      go(st, *from_, axis_);
      return true;
    }
    if (w == "CIRCLE" || w == "MOVARC") {
      if (!position_) fail(st.line, w + "/ before any FROM/ or GOTO/ (expected the arc's start position first)");
      if (pending_arc_)
        fail(st.line, w + "/ follows " + pending_arc_->word + "/ on line " + std::to_string(pending_arc_->line) +
                          " without its GOTO/ end point");
      if (rapid_next_)
        fail(st.line, w + "/ follows RAPID (expected RAPID to be followed by GOTO/; arcs are cut at feed)");
      const char* expected = "xc, yc, zc, i, j, k, r";
      if (st.args.size() < 7)
        fail(st.line, w + "/ has " + std::to_string(st.args.size()) + " values (expected " + expected + ")");
      PendingArc arc;
      arc.line = st.line;
      arc.word = w;
      double v[7];
      for (int i = 0; i < 7; ++i) v[i] = number(st, static_cast<std::size_t>(i), expected);
      arc.centre = to_work(Eigen::Vector3d(v[0], v[1], v[2]) * length_unit());
      arc.axis = to_work_dir(unit_axis(st, v[3], v[4], v[5]));
      arc.radius = v[6] * length_unit();
      if (!(arc.radius > 0) || !std::isfinite(arc.radius) || !arc.centre.allFinite())
        fail(st.line, w + "/ radius " + printable(st.args[6]) + " is not a positive finite length (expected r > 0)");
      if (w == "MOVARC" && st.args.size() > 7) {
        if (st.args.size() != 9 || st.args[7] != "ANGLE")
          fail(st.line, "MOVARC/ after the radius expects ANGLE, degrees; found \"" + printable(st.args[7]) + "\"");
        const double deg = number(st, 8, "the swept angle in degrees");
        // The turn count becomes an int (Move::rotation); a million turns is already no real program.
        if (!(deg > 0) || deg > 360e6)
          fail(st.line, "MOVARC/ ANGLE " + printable(st.args[8]) +
                            " is out of range (expected the swept angle in degrees, > 0 and at most a million turns)");
        arc.sweep_deg = deg;
      }
      // CIRCLE/ values after r (NX: tolerance, thickness, tool diameter and corner radius) do not change the arc.
      pending_arc_ = arc;
      return true;
    }
    if (w == "RAPID") {
      // "RAPID" alone (ISO 4343); some posts write "RAPID/" or "RAPID/ON".
      if (!(st.args.empty() || (st.args.size() == 1 && st.args[0] == "ON")) || (!st.slash && !st.rest.empty()))
        fail(st.line, "RAPID takes no values, found \"" + printable(st.rest) + "\"");
      if (pending_arc_)
        fail(st.line, "RAPID follows " + pending_arc_->word + "/ on line " + std::to_string(pending_arc_->line) +
                          " (expected GOTO/ with the arc's end point)");
      rapid_next_ = true;
      return true;
    }
    if (w == "FEDRAT") {
      fedrat(st);
      return true;
    }
    if (w == "UNITS") {
      if (st.args.size() != 1) fail(st.line, "UNITS/ expects one word (MM or INCHES)");
      bool inches = false;
      if (st.args[0] == "MM")
        inches = false;
      else if (st.args[0] == "INCHES" || st.args[0] == "INCH")
        inches = true;
      else
        fail(st.line, "UNITS/" + printable(st.args[0]) + " is not a unit (expected UNITS/MM or UNITS/INCHES)");
      if (!units_line_ && options_.default_unit && (*options_.default_unit == LengthUnit::Inch) != inches)
        warn(st.line, std::string("UNITS/") + st.args[0] + " differs from [job] program_units (" +
                          (inches ? "mm" : "inch") + "): the file's own UNITS/ is used");
      inches_ = inches;
      units_line_ = st.line;
      return true;
    }
    if (w == "MULTAX") {
      if (st.args.empty() && st.rest.empty())
        multax_off_ = false;  // CATIA writes a bare MULTAX
      else if (st.args.size() == 1 && st.args[0] == "ON")
        multax_off_ = false;
      else if (st.args.size() == 1 && st.args[0] == "OFF")
        multax_off_ = true;
      else
        fail(st.line, "MULTAX/" + printable(st.rest) + " (expected MULTAX, MULTAX/ON or MULTAX/OFF)");
      return true;
    }
    if (w == "TLAXIS") {
      if (st.args.size() != 3)
        fail(st.line, "TLAXIS/ has " + std::to_string(st.args.size()) + " values (expected the tool axis i, j, k)");
      const Eigen::Vector3d a =
          to_work_dir(unit_axis(st, number(st, 0, "i, j, k"), number(st, 1, "i, j, k"), number(st, 2, "i, j, k")));
      tlaxis_ = last_given_axis_ = a;
      multi_axis_file_ = true;
      return true;
    }
    if (w == "INDIRV") {
      if (st.args.size() != 3)
        fail(st.line, "INDIRV/ has " + std::to_string(st.args.size()) + " values (expected a direction i, j, k)");
      (void)unit_axis(st, number(st, 0, "i, j, k"), number(st, 1, "i, j, k"), number(st, 2, "i, j, k"));
      return true;
    }
    if (w == "CUTTER") {
      const char* expected = "d[, r, ...] with 0 <= r <= d/2";
      if (st.args.empty()) fail(st.line, std::string("CUTTER/ has no values (expected ") + expected + ")");
      const double d = number(st, 0, expected) * length_unit();
      const double r = st.args.size() > 1 && !st.args[1].empty() ? number(st, 1, expected) * length_unit() : 0.0;
      set_tool(st, d, r, 0.0, expected);
      return true;
    }
    if (w == "TLDATA") {
      // NX CLSF: TLDATA/MILL,d,r,length,taper,tip[,...]; other tool kinds carry no milling geometry.
      if (!st.args.empty() && st.args[0] == "MILL") {
        const char* expected = "MILL, d, r, length, ... with 0 <= r <= d/2";
        const double d = number(st, 1, expected) * length_unit();
        const double r = number(st, 2, expected) * length_unit();
        const double l = st.args.size() > 3 ? number(st, 3, expected) * length_unit() : 0.0;
        if (!(l >= 0)) fail(st.line, "TLDATA/ tool length " + num(l) + " mm is negative (expected " + expected + ")");
        set_tool(st, d, r, l, expected);
      }
      return true;
    }
    if (w == "LOADTL" || (w == "LOAD" && !st.args.empty() && st.args[0] == "TOOL")) {
      const std::size_t i = w == "LOAD" ? 1 : 0;
      const double n = number(st, i, "a tool number");
      if (!(n >= 0 && n <= 1e9) || n != std::floor(n))
        fail(st.line,
             w + "/ tool number " + printable(st.args[i]) + " is not a whole number >= 0 (expected a tool number)");
      tool_number_ = static_cast<int>(n);
      program_numbers_tools_ = true;
      return true;
    }
    if (w == "CYCLE") {
      if (st.args.size() == 1 && st.args[0] == "OFF") return true;
      fail(st.line, "CYCLE/" + printable(st.rest) +
                        ": canned cycles move the tool in ways the CL file does not spell out (expected the CAM system "
                        "to output the cycle as GOTO/ moves)");
    }
    if (w == "FINI") return false;
    if (contains(kUnsupportedMotionWords, w))
      fail(st.line, "'" + w +
                        "' moves the tool in a way vmsim does not read (expected CL motion records: GOTO/, "
                        "GODLTA/, CIRCLE/ or MOVARC/ with GOTO/, FROM/, GOHOME; part-program source must go through "
                        "the CAM system's APT processor first)");
    if (w == "MSYS") {
      msys(st);
      return true;
    }
    if (w == "CUTCOM" && st.args.size() == 1 && st.args[0] == "OFF") return true;
    if (contains(kUnmodelledWords, w)) {
      const std::string what = "'" + w + "' has an effect vmsim does not model (" +
                               (w == "CUTCOM"   ? std::string("the controller's cutter radius offset")
                                : w == "ORIGIN" ? std::string("the workpiece's place on the machine")
                                                : std::string("a dwell: the cycle time leaves it out")) +
                               ")";
      if (!options_.lenient) fail(st.line, what + " ([job] program_lenient = true reads it with a warning)");
      warn(st.line, what + ": ignored");
      return true;
    }
    if (contains(kNonMotionWords, w)) return true;
    if (w.empty())
      fail(st.line, "record \"" + printable(trim(st.rest)) + "\" has no major word (expected WORD/values)");
    fail(st.line, "unknown APT major word '" + printable(w) +
                      "' (expected a CL record vmsim knows, e.g. GOTO/, FEDRAT/, CIRCLE/; a word that might move the "
                      "tool is never skipped, the accepted ones are listed in core/apt.cpp)");
  }

  // The tool geometry of the moves that follow (ToolPath::tool_* keeps the program's first one); the moves' tool
  // numbers are given at the end (number_tools), when it is known whether the program numbers its tools.
  void set_tool(const Statement& st, double d, double r, double length, const char* expected) {
    if (!(d >= 0) || !std::isfinite(d) || !(r >= 0) || !std::isfinite(r) || r > d / 2 + 1e-9)
      fail(st.line,
           st.word + "/ diameter " + num(d) + " mm, corner radius " + num(r) + " mm (expected " + expected + ")");
    if (path_.tool_line == 0) {
      path_.tool_diameter_mm = d;
      path_.tool_corner_radius_mm = r;
      path_.tool_length_mm = length;
      path_.tool_line = st.line;
    }
    // Same geometry: diameter and corner radius within 1 nm, and the length where both records give one (CUTTER/ has
    // none).
    const auto same = [&](const core::ProgramTool& g) {
      return std::abs(g.diameter_mm - d) <= 1e-6 && std::abs(g.corner_radius_mm - r) <= 1e-6 &&
             (g.length_mm == 0 || length == 0 || std::abs(g.length_mm - length) <= 1e-6);
    };
    geometry_line_ = st.line;
    for (std::size_t k = 0; k < geometries_.size(); ++k)
      if (same(geometries_[k])) {
        geometry_ = static_cast<int>(k);
        return;
      }
    core::ProgramTool g;
    g.diameter_mm = d;
    g.corner_radius_mm = r;
    g.length_mm = length;
    g.line = st.line;
    geometries_.push_back(g);
    geometry_ = static_cast<int>(geometries_.size()) - 1;
  }

  void push_move(const core::Move& m) {
    path_.moves.push_back(m);
    move_geometry_.push_back(geometry_);
    move_geometry_line_.push_back(geometry_line_);
  }

  // Each move's tool number from the LOAD/TOOL number and the geometry in force at it (the header's rules), and
  // ToolPath::program_tools. Done at the end: NX writes TLDATA/ before the LOAD/TOOL of its operation, and whether the
  // program numbers its tools at all is known only then.
  void number_tools() {
    if (geometries_.empty()) return;  // no tool geometry: the LOAD/TOOL numbers as read
    std::vector<char> used(geometries_.size(), 0);
    int max_number = 0;
    for (std::size_t k = 0; k < path_.moves.size(); ++k) {
      if (move_geometry_[k] >= 0) used[static_cast<std::size_t>(move_geometry_[k])] = 1;
      max_number = std::max(max_number, path_.moves[k].tool_number);
    }
    const bool single = std::count(used.begin(), used.end(), 1) <= 1;
    std::map<std::pair<int, int>, int> number_of;  // (LOAD/TOOL number, geometry) -> tool number
    std::map<int, int> geometry_of;                // tool number -> geometry
    int next = max_number + 1;
    int previous = -1;
    for (std::size_t k = 0; k < path_.moves.size(); ++k) {
      core::Move& m = path_.moves[k];
      const int g = move_geometry_[k];
      if (g < 0) continue;  // before any tool geometry: the LOAD/TOOL number alone
      const auto key = std::make_pair(m.tool_number, g);
      auto it = number_of.find(key);
      if (it == number_of.end()) {
        int n = 0;
        if (program_numbers_tools_) {
          n = m.tool_number;
          if (geometry_of.count(n)) {
            const core::ProgramTool& was = geometries_[static_cast<std::size_t>(geometry_of[n])];
            warn(move_geometry_line_[k],
                 fmt::format("{}tool {} (D{} R{} mm) is now D{} R{} mm: a different tool, numbered {} here",
                             n == 0 ? "before any LOAD/TOOL, " : "", n, num(was.diameter_mm), num(was.corner_radius_mm),
                             num(geometries_[static_cast<std::size_t>(g)].diameter_mm),
                             num(geometries_[static_cast<std::size_t>(g)].corner_radius_mm), next));
            n = next++;
          }
        } else if (!single) {
          n = static_cast<int>(geometry_of.size()) + 1;
        }
        geometry_of.emplace(n, g);
        it = number_of.emplace(key, n).first;
        core::ProgramTool t = geometries_[static_cast<std::size_t>(g)];
        t.number = n;
        t.numbered_by_program = program_numbers_tools_ && n == m.tool_number;
        path_.program_tools.push_back(t);
      }
      m.tool_number = it->second;
      if (m.tool_number != previous)
        for (core::ProgramTool& t : path_.program_tools)
          if (t.number == m.tool_number) t.stretch_lines.push_back(move_geometry_line_[k]);
      previous = m.tool_number;
    }
  }

  // MSYS/x,y,z,xi,xj,xk,yi,yj,yk: the frame of the data that follows, in NX's absolute frame. The first one is the
  // workpiece frame; a later one maps its data into it (p_work = R1^T (o + R p - o1)).
  void msys(const Statement& st) {
    const char* expected = "x, y, z, xi, xj, xk, yi, yj, yk: an origin and two unit directions at right angles";
    if (st.args.size() != 9)
      fail(st.line, "MSYS/ has " + std::to_string(st.args.size()) + " values (expected " + expected + ")");
    double v[9];
    for (int i = 0; i < 9; ++i) v[i] = number(st, static_cast<std::size_t>(i), expected);
    const Eigen::Vector3d o = Eigen::Vector3d(v[0], v[1], v[2]) * length_unit();
    const Eigen::Vector3d x(v[3], v[4], v[5]), y(v[6], v[7], v[8]);
    // 7 decimals printed: unit length and right angle within 1e-5.
    if (std::abs(x.norm() - 1) > 1e-5 || std::abs(y.norm() - 1) > 1e-5 || std::abs(x.dot(y)) > 1e-5)
      fail(st.line, "MSYS/ directions are not unit vectors at right angles (expected " + std::string(expected) + ")");
    Eigen::Matrix3d r;
    r.col(0) = x.normalized();
    r.col(2) = x.cross(y).normalized();
    r.col(1) = r.col(2).cross(r.col(0));
    if (!msys_first_) {
      msys_first_ = std::make_pair(r, o);
      return;
    }
    const auto& [r1, o1] = *msys_first_;
    frame_r_ = r1.transpose() * r;
    frame_o_ = r1.transpose() * (o - o1);
  }

  void fedrat(const Statement& st) {
    const char* expected = "FEDRAT/f, FEDRAT/f,MMPM|IPM or FEDRAT/MMPM|IPM,f";
    std::optional<double> f;
    std::optional<double> unit;  // mm per unit of the value
    for (std::size_t i = 0; i < st.args.size(); ++i) {
      const std::string& a = st.args[i];
      if (a == "MMPM")
        unit = 1.0;
      else if (a == "IPM")
        unit = core::units::kInchToMm;
      else if (a == "PERMIN")
        unit = length_unit();
      else if (a == "MMPR" || a == "IPR" || a == "PERREV" || a == "INVERS")
        fail(st.line, "FEDRAT/ " + a + " feeds are not supported (expected a feed per minute: " + expected + ")");
      else if (!f)
        f = number(st, i, expected);
      else
        fail(st.line, "FEDRAT/ has an unexpected value \"" + printable(a) + "\" (expected " + expected + ")");
    }
    if (!f) fail(st.line, std::string("FEDRAT/ has no feed value (expected ") + expected + ")");
    const double mm_per_min = *f * unit.value_or(length_unit());
    if (!(mm_per_min > 0) || !std::isfinite(mm_per_min))
      fail(st.line, "FEDRAT/ feed " + num(*f) + " is not positive (expected a feed > 0; use RAPID for rapids)");
    feed_mm_per_min_ = mm_per_min;
  }

  std::string file_;
  core::ToolPath path_;
  std::optional<Eigen::Vector3d> position_;  // tool tip, mm
  std::optional<Eigen::Vector3d> from_;
  Eigen::Vector3d axis_ = Eigen::Vector3d::UnitZ();             // current tool axis
  Eigen::Vector3d tlaxis_ = Eigen::Vector3d::UnitZ();           // axis of GOTOs without i,j,k under MULTAX/OFF
  Eigen::Vector3d last_given_axis_ = Eigen::Vector3d::UnitZ();  // ... and under MULTAX/ON: the last one given
  bool multax_off_ = false;
  AptOptions options_;
  int units_line_ = 0;  // line of the UNITS/ record in force, 0: none yet
  std::optional<std::pair<Eigen::Matrix3d, Eigen::Vector3d>> msys_first_;
  Eigen::Matrix3d frame_r_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d frame_o_ = Eigen::Vector3d::Zero();
  bool multi_axis_file_ = false;
  bool inches_ = false;
  bool rapid_next_ = false;
  double feed_mm_per_min_ = 0.0;
  int tool_number_ = 0;
  bool program_numbers_tools_ = false;                   // a LOAD/TOOL or LOADTL record
  std::vector<core::ProgramTool> geometries_;            // distinct tool geometries, in order of their records
  int geometry_ = -1, geometry_line_ = 0;                // the geometry in force and the record that set it
  std::vector<int> move_geometry_, move_geometry_line_;  // per move
  std::optional<PendingArc> pending_arc_;
};

}  // namespace

core::ToolPath read_apt_text(const std::string& text, const std::string& name, const AptOptions& options) {
  return AptReader(name, options).read(text);
}

bool looks_like_apt(std::string_view text) {
  static constexpr std::string_view kFirstWords[] = {"TOOL PATH", "TLDATA", "MSYS",   "UNITS", "MULTAX", "CUTTER",
                                                     "FROM",      "GOTO",   "LOADTL", "LOAD",  "MACHIN", "PPRINT",
                                                     "FEDRAT",    "SPINDL", "TLAXIS", "PAINT", "CLEARP", "RAPID"};
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find_first_of("\r\n", pos);
    if (eol == std::string_view::npos) eol = text.size();
    const std::string_view raw = text.substr(pos, eol - pos);
    pos = eol + 1;
    const std::string_view line = trim(raw);
    if (line.empty() || line.substr(0, 2) == "$$" || nx_listing_line(raw)) continue;
    const std::string u = upper(line.substr(0, std::min<std::size_t>(line.size(), 16)));
    if (u.rfind("PARTNO", 0) == 0) return true;
    const std::size_t slash = line.find('/');
    if (slash == std::string_view::npos || slash == 0) return false;
    Statement st = parse_statement(Record{0, std::string(line)});
    return contains(kFirstWords, st.word);
  }
  return false;
}

core::ToolPath read_apt(const std::filesystem::path& program, const AptOptions& options) {
  const std::string file = program.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(program, ec))
    throw core::Error(core::located(file, 0, "cannot open APT CL file (it does not exist or is not a regular file)"));
  std::ifstream in(program, std::ios::binary);
  if (!in) throw core::Error(core::located(file, 0, "cannot open APT CL file for reading"));
  std::ostringstream ss;
  ss << in.rdbuf();
  return AptReader(file, options).read(ss.str());
}

}  // namespace vmsim::program
