#include "sysid/position_trace.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <map>

namespace vmsim::sysid {

int PositionTrace::axis_index(const std::string& name) const {
  for (std::size_t i = 0; i < axes.size(); ++i)
    if (axes[i] == name) return static_cast<int>(i);
  return -1;
}

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const auto comma = line.find(',', start);
    out.push_back(trim(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

}  // namespace

PositionTrace read_position_trace_csv(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::Error(core::located(file, 0, "cannot open the trace"));
  PositionTrace tr;
  tr.source = file;
  std::string line;
  int line_no = 0;
  std::vector<std::string> header;
  int header_line = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line_no == 1 && line.size() >= 3 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    header = split(t);
    header_line = line_no;
    break;
  }
  if (header.empty())
    throw core::Error(core::located(file, 0, "no header row (expected t_s, <AXIS>_command_mm, <AXIS>_actual_mm, ...)"));

  // Columns: t_s, then <AXIS>_command_<unit> / <AXIS>_actual_<unit>.
  int t_col = -1;
  struct Cols { int command = -1, actual = -1; bool rotary = false; };
  std::map<std::string, Cols> cols;
  std::vector<std::string> order;
  for (std::size_t c = 0; c < header.size(); ++c) {
    const std::string& h = header[c];
    const auto col_error = [&](const std::string& msg) {
      throw core::Error(core::located(file, header_line, fmt::format("column {} '{}': {}", c + 1, h, msg)));
    };
    if (h == "t_s") {
      if (t_col >= 0) col_error("appears twice");
      t_col = static_cast<int>(c);
      continue;
    }
    std::string axis, kind, unit;
    if (h.size() >= 2 && std::string("XYZABC").find(h[0]) != std::string::npos && h[1] == '_') {
      axis = h.substr(0, 1);
      const std::string rest = h.substr(2);
      const auto us = rest.find('_');
      if (us != std::string::npos) {
        kind = rest.substr(0, us);
        unit = rest.substr(us + 1);
      }
    }
    if (axis.empty() || (kind != "command" && kind != "actual"))
      col_error("unknown column (expected t_s or <AXIS>_command_<unit>, <AXIS>_actual_<unit> with AXIS in X Y Z A B C)");
    const bool rotary = std::string("ABC").find(axis[0]) != std::string::npos;
    if (unit != (rotary ? "deg" : "mm")) col_error(fmt::format("axis {} is given in {}", axis, rotary ? "deg" : "mm"));
    if (!cols.count(axis)) order.push_back(axis);
    Cols& cc = cols[axis];
    cc.rotary = rotary;
    int& slot = kind == "command" ? cc.command : cc.actual;
    if (slot >= 0) col_error("appears twice");
    slot = static_cast<int>(c);
  }
  if (t_col < 0) throw core::Error(core::located(file, header_line, "no t_s column"));
  if (order.empty()) throw core::Error(core::located(file, header_line, "no axis columns (<AXIS>_command_mm, <AXIS>_actual_mm)"));
  for (const auto& a : order) {
    const Cols& cc = cols[a];
    if (cc.command < 0 || cc.actual < 0)
      throw core::Error(core::located(file, header_line, fmt::format("axis {} needs both {}_command_{} and {}_actual_{}",
                                                                     a, a, cc.rotary ? "deg" : "mm", a, cc.rotary ? "deg" : "mm")));
  }

  std::vector<double> values;
  std::vector<int> lines;
  const std::size_t nc = header.size();
  while (std::getline(in, line)) {
    ++line_no;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::vector<std::string> f = split(t);
    if (f.size() != nc)
      throw core::Error(core::located(file, line_no, fmt::format("{} fields, the header has {}", f.size(), nc)));
    for (std::size_t c = 0; c < nc; ++c) {
      double v = 0.0;
      const char* b = f[c].data();
      const char* e = b + f[c].size();
      if (!f[c].empty() && *b == '+') ++b;
      const auto r = std::from_chars(b, e, v);
      if (f[c].empty() || r.ec != std::errc() || r.ptr != e || !std::isfinite(v))
        throw core::Error(core::located(file, line_no, fmt::format("column {} '{}': '{}' is not a finite number", c + 1,
                                                                   header[c], f[c])));
      values.push_back(v);
    }
    lines.push_back(line_no);
    if (values.size() > std::size_t{1} << 31) throw core::Error(core::located(file, line_no, "the trace is too large"));
  }
  const Eigen::Index n = static_cast<Eigen::Index>(lines.size());
  if (n < 2) throw core::Error(core::located(file, 0, fmt::format("{} samples; a trace needs at least 2", n)));
  const Eigen::Index na = static_cast<Eigen::Index>(order.size());
  tr.t_s.resize(n);
  tr.command.resize(n, na);
  tr.actual.resize(n, na);
  for (const auto& a : order) {
    tr.axes.push_back(a);
    tr.rotary.push_back(cols[a].rotary);
  }
  for (Eigen::Index k = 0; k < n; ++k) {
    const double* row = values.data() + static_cast<std::size_t>(k) * nc;
    tr.t_s[k] = row[t_col];
    for (Eigen::Index a = 0; a < na; ++a) {
      const Cols& cc = cols[order[static_cast<std::size_t>(a)]];
      const double f = cc.rotary ? core::units::kDegToRad : 1.0;
      tr.command(k, a) = row[cc.command] * f;
      tr.actual(k, a) = row[cc.actual] * f;
    }
  }
  tr.period_s = (tr.t_s[n - 1] - tr.t_s[0]) / static_cast<double>(n - 1);
  if (!(tr.period_s > 0.0))
    throw core::Error(core::located(file, lines[1], "t_s must increase"));
  for (Eigen::Index k = 1; k < n; ++k) {
    const double dt = tr.t_s[k] - tr.t_s[k - 1];
    if (std::abs(dt - tr.period_s) > 1e-6 * tr.period_s + 1e-9)
      throw core::Error(core::located(
          file, lines[static_cast<std::size_t>(k)],
          fmt::format("t_s steps by {} s here but {} s on average: identification needs a constant sampling period",
                      dt, tr.period_s)));
  }
  return tr;
}

void write_position_trace_csv(const std::filesystem::path& path, const PositionTrace& tr,
                              const std::vector<std::string>& comment_lines) {
  core::AtomicFile out(path);
  for (const auto& l : comment_lines) out.stream() << "# " << l << '\n';
  std::string h = "t_s";
  for (std::size_t a = 0; a < tr.axes.size(); ++a) {
    const char* u = tr.rotary[a] ? "deg" : "mm";
    h += fmt::format(",{0}_command_{1},{0}_actual_{1}", tr.axes[a], u);
  }
  out.stream() << h << '\n';
  std::string line;
  for (Eigen::Index k = 0; k < tr.t_s.size(); ++k) {
    line = fmt::format("{:.7f}", tr.t_s[k]);
    for (std::size_t a = 0; a < tr.axes.size(); ++a) {
      const double f = tr.rotary[a] ? core::units::kRadToDeg : 1.0;
      const auto ai = static_cast<Eigen::Index>(a);
      line += fmt::format(",{:.10f},{:.10f}", tr.command(k, ai) * f, tr.actual(k, ai) * f);
    }
    line += '\n';
    out.stream() << line;
  }
  out.commit();
}

}  // namespace vmsim::sysid
