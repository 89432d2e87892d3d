#include "sysid/trace_formats.hpp"

#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <fmt/format.h>
#include <matio.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

namespace vmsim::sysid {

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r\n") + 1 - b);
}

bool starts_with(const std::string& s, const std::string& p) { return s.compare(0, p.size(), p) == 0; }

// The factor to mm or rad, and whether the unit is angular.
std::pair<double, bool> unit_factor(const std::string& file, const std::optional<std::string>& unit) {
  const std::string u = unit.value_or("mm");
  if (u == "mm") return {1.0, false};
  if (u == "m") return {1000.0, false};
  if (u == "in" || u == "inch") return {25.4, false};
  if (u == "deg") return {core::units::kDegToRad, true};
  if (u == "rad") return {1.0, true};
  throw core::Error(core::located(file, 0, fmt::format("unit '{}': expected mm, m, in, deg or rad", u)));
}

bool rotary_axis(const std::string& axis) { return axis == "A" || axis == "B" || axis == "C"; }

void check_axis_name(const std::string& where, const std::string& axis) {
  if (axis.size() != 1 || std::string("XYZABC").find(axis) == std::string::npos)
    throw core::Error(fmt::format("{}: axis '{}': expected one of X Y Z A B C", where, axis));
}

void check_unit_fits_axis(const std::string& file, const std::string& axis, bool angular,
                          const std::optional<std::string>& unit) {
  if (angular != rotary_axis(axis))
    throw core::Error(core::located(file, 0,
                                    fmt::format("axis {} is {}, the trace's unit is {}", axis,
                                                rotary_axis(axis) ? "rotary" : "linear", unit.value_or("mm"))));
}

struct MatCloser {
  void operator()(mat_t* m) const { Mat_Close(m); }
};
struct VarFree {
  void operator()(matvar_t* v) const { Mat_VarFree(v); }
};
using MatFile = std::unique_ptr<mat_t, MatCloser>;

MatFile open_mat(const std::filesystem::path& path) {
  MatFile m(Mat_Open(path.string().c_str(), MAT_ACC_RDONLY));
  if (!m)
    throw core::Error(core::located(path.string(), 0, "not a MATLAB .mat file libmatio can read (v4, v5 or v7.3)"));
  return m;
}

std::vector<std::string> names_in(mat_t* m) {
  std::vector<std::string> names;
  Mat_Rewind(m);
  while (matvar_t* v = Mat_VarReadNextInfo(m)) {
    if (v->name) names.emplace_back(v->name);
    Mat_VarFree(v);
  }
  Mat_Rewind(m);
  return names;
}

template <typename T>
void append_as_double(const void* data, std::size_t n, std::vector<double>& out) {
  const T* p = static_cast<const T*>(data);
  for (std::size_t i = 0; i < n; ++i) out.push_back(static_cast<double>(p[i]));
}

// The role's variable name, or an error listing the roles expected.
const std::string& role(const std::string& file, const std::map<std::string, std::string>& vars, const std::string& r,
                        const std::string& expected) {
  const auto it = vars.find(r);
  if (it == vars.end())
    throw core::Error(core::located(file, 0,
                                    fmt::format("--mat names no '{}' variable (expected {}; the file has: {})", r,
                                                expected, fmt::join(mat_variable_names(file), ", "))));
  return it->second;
}

void check_roles(const std::string& file, const std::map<std::string, std::string>& vars,
                 const std::set<std::string>& allowed) {
  for (const auto& [k, v] : vars)
    if (!allowed.count(k))
      throw core::Error(core::located(
          file, 0, fmt::format("--mat: '{}' is not a role here (expected {})", k, fmt::join(allowed, ", "))));
}

Eigen::ArrayXd to_array(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::ArrayXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

PositionTrace position_trace_from_mat(const std::filesystem::path& path, const TraceChannels& ch) {
  const std::string file = path.string();
  const std::string expected = "t, command, actual and optionally axis";
  check_roles(file, ch.variables, {"t", "command", "actual", "axis"});
  const std::string axis = ch.variables.count("axis") ? ch.variables.at("axis") : "X";
  check_axis_name(file + ": --mat axis", axis);
  const auto [factor, angular] = unit_factor(file, ch.unit);
  check_unit_fits_axis(file, axis, angular, ch.unit);
  const std::vector<double> t = read_mat_vector(path, role(file, ch.variables, "t", expected));
  const std::vector<double> c = read_mat_vector(path, role(file, ch.variables, "command", expected));
  const std::vector<double> a = read_mat_vector(path, role(file, ch.variables, "actual", expected));
  if (c.size() != t.size() || a.size() != t.size())
    throw core::Error(core::located(
        file, 0,
        fmt::format("t has {} samples, command {}, actual {}: they must be equal", t.size(), c.size(), a.size())));
  PositionTrace tr;
  tr.source = file;
  tr.axes = {axis};
  tr.rotary = {angular};
  tr.t_s = to_array(t);
  tr.command = to_array(c).matrix() * factor;
  tr.actual = to_array(a).matrix() * factor;
  regularise_sampling(tr);
  return tr;
}

// The pin carrying the encoder position of joint N when the user names none: joint.N.motor-pos-fb, else the one
// pin named like an encoder's position.
std::string default_actual_pin(const HalscopeLog& log, int joint) {
  const std::string fb = fmt::format("joint.{}.motor-pos-fb", joint);
  if (std::find(log.pins.begin(), log.pins.end(), fb) != log.pins.end()) return fb;
  std::vector<std::string> enc;
  for (const auto& p : log.pins)
    if (p.find("encoder") != std::string::npos && p.size() > 9 && p.compare(p.size() - 9, 9, ".position") == 0)
      enc.push_back(p);
  if (enc.size() == 1) return enc.front();
  throw core::Error(
      core::located(log.source, 0,
                    fmt::format("joint {}: {} and {} encoder position pins: name the actual position with --channel "
                                "AXIS=COMMAND_PIN,ACTUAL_PIN (pins present: {})",
                                joint, enc.empty() ? "no " + fb : fb + " absent",
                                enc.empty() ? "no" : std::to_string(enc.size()), fmt::join(log.pins, ", "))));
}

PositionTrace position_trace_from_halscope(const std::filesystem::path& path, const TraceChannels& ch) {
  const HalscopeLog log = read_halscope_log(path);
  std::vector<PinPair> pairs = ch.pins;
  if (pairs.empty()) {
    for (const auto& p : log.pins) {
      int joint = -1;
      char tail[32] = {};
      if (std::sscanf(p.c_str(), "joint.%d.%31s", &joint, tail) == 2 && std::string(tail) == "motor-pos-cmd") {
        if (joint < 0 || joint > 5)
          throw core::Error(core::located(log.source, 0,
                                          fmt::format("pin {}: joint {} has no default axis name; "
                                                      "give --channel AXIS=COMMAND_PIN,ACTUAL_PIN",
                                                      p, joint)));
        pairs.push_back({std::string(1, "XYZABC"[joint]), p, default_actual_pin(log, joint)});
      }
    }
    if (pairs.empty())
      throw core::Error(core::located(log.source, 0,
                                      fmt::format("no joint.N.motor-pos-cmd pin: name the channels with --channel "
                                                  "AXIS=COMMAND_PIN,ACTUAL_PIN (pins present: {})",
                                                  fmt::join(log.pins, ", "))));
  }
  const auto [factor, angular] = unit_factor(log.source, ch.unit);
  const auto column = [&](const std::string& pin) -> const std::vector<double>& {
    const auto it = std::find(log.pins.begin(), log.pins.end(), pin);
    if (it == log.pins.end())
      throw core::Error(core::located(log.source, log.first_sample_line,
                                      fmt::format("no pin '{}' (pins present: {})", pin, fmt::join(log.pins, ", "))));
    return log.values[static_cast<std::size_t>(it - log.pins.begin())];
  };
  PositionTrace tr;
  tr.source = log.source;
  const auto n = static_cast<Eigen::Index>(log.values.empty() ? 0 : log.values.front().size());
  tr.command.resize(n, static_cast<Eigen::Index>(pairs.size()));
  tr.actual.resize(n, static_cast<Eigen::Index>(pairs.size()));
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const PinPair& pp = pairs[i];
    check_unit_fits_axis(log.source, pp.axis, angular, ch.unit);
    if (std::find(tr.axes.begin(), tr.axes.end(), pp.axis) != tr.axes.end())
      throw core::Error(core::located(log.source, 0, fmt::format("axis {} is given two channels", pp.axis)));
    tr.axes.push_back(pp.axis);
    tr.rotary.push_back(angular);
    const auto ai = static_cast<Eigen::Index>(i);
    tr.command.col(ai) = to_array(column(pp.command)).matrix() * factor;
    tr.actual.col(ai) = to_array(column(pp.actual)).matrix() * factor;
  }
  tr.t_s = Eigen::ArrayXd::LinSpaced(n, 0.0, static_cast<double>(n - 1)) * log.period_s;
  regularise_sampling(tr);
  return tr;
}

}  // namespace

const char* trace_format_name(TraceFormat f) {
  switch (f) {
    case TraceFormat::Csv:
      return "csv";
    case TraceFormat::Halscope:
      return "halscope";
    case TraceFormat::Mat:
      return "mat";
  }
  return "?";
}

TraceFormat detect_trace_format(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::Error(core::located(path.string(), 0, "cannot open the trace"));
  std::string head(128, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  if (starts_with(head, "Sampling period is")) return TraceFormat::Halscope;
  if (starts_with(head, "MATLAB 5.0 MAT-file") || starts_with(head, "MATLAB 7.3 MAT-file")) return TraceFormat::Mat;
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".mat") return TraceFormat::Mat;
  return TraceFormat::Csv;
}

PinPair parse_pin_pair(const std::string& spec) {
  const auto eq = spec.find('=');
  const auto comma = spec.find(',', eq == std::string::npos ? 0 : eq);
  const auto bad = [&] {
    return core::Error(
        fmt::format("--channel '{}': expected AXIS=COMMAND_PIN,ACTUAL_PIN (e.g. "
                    "X=joint.0.motor-pos-cmd,joint.0.motor-pos-fb)",
                    spec));
  };
  if (eq == std::string::npos || comma == std::string::npos) throw bad();
  PinPair p{trim(spec.substr(0, eq)), trim(spec.substr(eq + 1, comma - eq - 1)), trim(spec.substr(comma + 1))};
  if (p.command.empty() || p.actual.empty() || p.actual.find(',') != std::string::npos) throw bad();
  check_axis_name("--channel '" + spec + "'", p.axis);
  return p;
}

std::map<std::string, std::string> parse_mat_variables(const std::string& spec) {
  std::map<std::string, std::string> vars;
  std::stringstream ss(spec);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto eq = item.find('=');
    const std::string k = eq == std::string::npos ? "" : trim(item.substr(0, eq));
    const std::string v = eq == std::string::npos ? "" : trim(item.substr(eq + 1));
    if (k.empty() || v.empty())
      throw core::Error(
          fmt::format("--mat '{}': item '{}': expected ROLE=VARIABLE (e.g. t=t,command=qg,actual=qm)", spec, item));
    if (!vars.emplace(k, v).second) throw core::Error(fmt::format("--mat '{}': '{}' is given twice", spec, k));
  }
  if (vars.empty()) throw core::Error("--mat: expected ROLE=VARIABLE,... (e.g. t=t,command=qg,actual=qm)");
  return vars;
}

std::vector<std::string> mat_variable_names(const std::filesystem::path& path) {
  const MatFile m = open_mat(path);
  return names_in(m.get());
}

std::vector<double> read_mat_vector(const std::filesystem::path& path, const std::string& variable) {
  const std::string file = path.string();
  const MatFile m = open_mat(path);
  std::unique_ptr<matvar_t, VarFree> v(Mat_VarRead(m.get(), variable.c_str()));
  if (!v)
    throw core::Error(core::located(
        file, 0, fmt::format("no variable '{}' (the file has: {})", variable, fmt::join(names_in(m.get()), ", "))));
  const auto where = [&](const std::string& msg) { return core::Error(core::located(file, 0, variable + ": " + msg)); };
  if (v->rank != 2 || (v->dims[0] != 1 && v->dims[1] != 1))
    throw where(v->rank == 2
                    ? fmt::format("a {} x {} array; a vector (1 x n or n x 1) is expected", v->dims[0], v->dims[1])
                    : fmt::format("an array of rank {}; a vector is expected", v->rank));
  if (v->isComplex) throw where("complex values; a real vector is expected");
  const std::size_t n = v->dims[0] * v->dims[1];
  std::vector<double> out;
  out.reserve(n);
  switch (v->class_type) {
    case MAT_C_DOUBLE:
      append_as_double<double>(v->data, n, out);
      break;
    case MAT_C_SINGLE:
      append_as_double<float>(v->data, n, out);
      break;
    case MAT_C_INT8:
      append_as_double<std::int8_t>(v->data, n, out);
      break;
    case MAT_C_UINT8:
      append_as_double<std::uint8_t>(v->data, n, out);
      break;
    case MAT_C_INT16:
      append_as_double<std::int16_t>(v->data, n, out);
      break;
    case MAT_C_UINT16:
      append_as_double<std::uint16_t>(v->data, n, out);
      break;
    case MAT_C_INT32:
      append_as_double<std::int32_t>(v->data, n, out);
      break;
    case MAT_C_UINT32:
      append_as_double<std::uint32_t>(v->data, n, out);
      break;
    case MAT_C_INT64:
      append_as_double<std::int64_t>(v->data, n, out);
      break;
    case MAT_C_UINT64:
      append_as_double<std::uint64_t>(v->data, n, out);
      break;
    default:
      throw where("not a numeric array (a struct, cell, char or sparse array)");
  }
  if (n > 0 && !v->data) throw where("no data");
  for (std::size_t i = 0; i < out.size(); ++i)
    if (!std::isfinite(out[i])) throw where(fmt::format("element {} is not finite ({})", i + 1, out[i]));
  return out;
}

HalscopeLog read_halscope_log(const std::filesystem::path& path) {
  HalscopeLog log;
  log.source = path.string();
  std::ifstream in(path);
  if (!in) throw core::Error(core::located(log.source, 0, "cannot open the halscope log"));
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    line = trim(line);
    if (line.empty()) continue;
    if (log.period_s == 0.0) {
      long long ns = 0;
      char unit[16] = {};
      if (std::sscanf(line.c_str(), "Sampling period is %lld %15s", &ns, unit) != 2 || std::string(unit) != "nSec" ||
          ns <= 0)
        throw core::Error(core::located(log.source, line_no,
                                        fmt::format("expected the halscope header 'Sampling period is N nSec', found "
                                                    "'{}'",
                                                    line.substr(0, 60))));
      log.period_s = static_cast<double>(ns) * 1e-9;
      continue;
    }
    std::istringstream ss(line);
    std::string name, value;
    std::size_t ch = 0;
    const bool first = log.first_sample_line == 0;
    if (first) log.first_sample_line = line_no;
    while (ss >> name) {
      if (!(ss >> value))
        throw core::Error(core::located(log.source, line_no, fmt::format("pin '{}' has no value", name)));
      const auto x = core::parse_number(value);
      if (!x)
        throw core::Error(
            core::located(log.source, line_no, fmt::format("pin '{}': '{}' is not a finite number", name, value)));
      if (name == "(null)") continue;  // an unused scope channel
      if (first) {
        log.pins.push_back(name);
        log.values.emplace_back();
      } else if (ch >= log.pins.size() || log.pins[ch] != name) {
        throw core::Error(
            core::located(log.source, line_no,
                          fmt::format("channel {} is '{}' here but '{}' on line {}", ch + 1, name,
                                      ch < log.pins.size() ? log.pins[ch] : "(none)", log.first_sample_line)));
      }
      log.values[ch++].push_back(*x);
    }
    if (!first && ch != log.pins.size())
      throw core::Error(
          core::located(log.source, line_no,
                        fmt::format("{} channels here, {} on line {}", ch, log.pins.size(), log.first_sample_line)));
  }
  if (log.period_s == 0.0) throw core::Error(core::located(log.source, 0, "empty: no halscope header"));
  if (log.pins.empty()) throw core::Error(core::located(log.source, 0, "no samples"));
  // halscope ends its log with one line of zeros on every channel: not a sample.
  bool all_zero = true;
  for (const auto& v : log.values) all_zero = all_zero && v.back() == 0.0;
  if (all_zero && log.values.front().size() > 1) {
    for (auto& v : log.values) v.pop_back();
    log.dropped_zero_line = true;
  }
  return log;
}

PositionTrace read_position_trace(const std::filesystem::path& path, const TraceChannels& channels) {
  const TraceFormat f = detect_trace_format(path);
  if (f != TraceFormat::Halscope && !channels.pins.empty())
    throw core::Error(
        core::located(path.string(), 0, "--channel names halscope pins; this trace is not a halscope log"));
  if (f != TraceFormat::Mat && !channels.variables.empty())
    throw core::Error(core::located(path.string(), 0, "--mat names .mat variables; this trace is not a .mat file"));
  switch (f) {
    case TraceFormat::Halscope:
      return position_trace_from_halscope(path, channels);
    case TraceFormat::Mat:
      if (channels.variables.empty())
        throw core::Error(core::located(path.string(), 0,
                                        fmt::format("a .mat trace needs --mat t=VAR,command=VAR,actual=VAR (the file "
                                                    "has: {})",
                                                    fmt::join(mat_variable_names(path), ", "))));
      return position_trace_from_mat(path, channels);
    case TraceFormat::Csv:
      if (channels.unit)
        throw core::Error(core::located(path.string(), 0, "--trace-unit: a CSV trace names its units in its header"));
      return read_position_trace_csv(path);
  }
  return {};
}

AxisTrace read_axis_trace(const std::filesystem::path& path, const TraceChannels& channels,
                          std::vector<std::string>* ignored) {
  const TraceFormat f = detect_trace_format(path);
  const std::string file = path.string();
  if (f == TraceFormat::Halscope)
    throw core::Error(core::located(file, 0,
                                    "identify-friction reads a CSV or .mat trace; a halscope log carries no "
                                    "current"));
  if (f == TraceFormat::Csv) {
    if (!channels.variables.empty())
      throw core::Error(core::located(file, 0, "--mat names .mat variables; this trace is not a .mat file"));
    if (channels.unit)
      throw core::Error(core::located(file, 0, "--trace-unit: a CSV trace names its units in its header"));
    return read_axis_trace_csv(path, ignored);
  }
  const std::string expected = "t, control and one of position, velocity";
  if (channels.variables.empty())
    throw core::Error(core::located(file, 0,
                                    fmt::format("a .mat trace needs --mat t=VAR,position=VAR,control=VAR (the "
                                                "file has: {})",
                                                fmt::join(mat_variable_names(path), ", "))));
  check_roles(file, channels.variables, {"t", "position", "velocity", "control"});
  const bool has_pos = channels.variables.count("position") > 0, has_vel = channels.variables.count("velocity") > 0;
  if (has_pos == has_vel)
    throw core::Error(core::located(file, 0, "--mat: give exactly one of position=VAR and velocity=VAR"));
  const auto [factor, angular] = unit_factor(file, channels.unit);
  AxisTrace tr;
  tr.source = file;
  tr.rotary = angular;
  const std::vector<double> t = read_mat_vector(path, role(file, channels.variables, "t", expected));
  const std::vector<double> m = read_mat_vector(path, channels.variables.at(has_pos ? "position" : "velocity"));
  const std::vector<double> c = read_mat_vector(path, role(file, channels.variables, "control", expected));
  if (m.size() != t.size() || c.size() != t.size())
    throw core::Error(core::located(file, 0,
                                    fmt::format("t has {} samples, {} {}, control {}: they must be equal", t.size(),
                                                has_pos ? "position" : "velocity", m.size(), c.size())));
  if (t.size() < 3)
    throw core::Error(core::located(file, 0, fmt::format("only {} samples; a trace needs many more", t.size())));
  for (std::size_t k = 1; k < t.size(); ++k)
    if (!(t[k] > t[k - 1]))
      throw core::Error(core::located(
          file, 0, fmt::format("t: sample {} ({} s) does not increase (previous: {} s)", k + 1, t[k], t[k - 1])));
  tr.t_s = to_array(t);
  (has_pos ? tr.position : tr.velocity) = to_array(m) * factor;
  tr.current_A = to_array(c);
  return tr;
}

}  // namespace vmsim::sysid
