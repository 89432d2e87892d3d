#include "sysid/position_trace.hpp"

#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace vmsim::sysid {

int PositionTrace::axis_index(const std::string& name) const {
  for (std::size_t i = 0; i < axes.size(); ++i)
    if (axes[i] == name) return static_cast<int>(i);
  return -1;
}

void regularise_sampling(PositionTrace& tr, const std::vector<int>& lines) {
  const Eigen::Index n = tr.t_s.size();
  if (n < 2) throw core::Error(core::located(tr.source, 0, fmt::format("{} samples; a trace needs at least 2", n)));
  const auto line_of = [&](Eigen::Index k) { return k < static_cast<Eigen::Index>(lines.size()) ? lines[k] : 0; };
  for (Eigen::Index k = 1; k < n; ++k)
    if (!(tr.t_s[k] > tr.t_s[k - 1]))
      throw core::Error(
          core::located(tr.source, line_of(k),
                        fmt::format("t_s {} s does not increase (previous sample: {} s)", tr.t_s[k], tr.t_s[k - 1])));
  tr.period_s = (tr.t_s[n - 1] - tr.t_s[0]) / static_cast<double>(n - 1);
  tr.max_jitter_s = 0.0;
  for (Eigen::Index k = 1; k < n; ++k)
    tr.max_jitter_s = std::max(tr.max_jitter_s, std::abs(tr.t_s[k] - tr.t_s[k - 1] - tr.period_s));
  tr.resampled = tr.max_jitter_s > kJitterTolerance * tr.period_s;
  if (!tr.resampled) return;
  // Linear interpolation onto t0 + k T: the time stamps are strictly increasing, so one forward sweep finds each
  // grid point's interval.
  const Eigen::ArrayXd t = tr.t_s;
  const Eigen::MatrixXd c = tr.command, a = tr.actual;
  Eigen::Index j = 0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double tk = k + 1 == n ? t[n - 1] : t[0] + static_cast<double>(k) * tr.period_s;
    while (j + 2 < n && t[j + 1] < tk) ++j;
    const double w = std::clamp((tk - t[j]) / (t[j + 1] - t[j]), 0.0, 1.0);
    tr.t_s[k] = tk;
    tr.command.row(k) = (1.0 - w) * c.row(j) + w * c.row(j + 1);
    tr.actual.row(k) = (1.0 - w) * a.row(j) + w * a.row(j + 1);
  }
}

PositionTrace read_position_trace_csv(const std::filesystem::path& path) {
  core::CsvReader in(path);
  const std::string& file = in.name();
  PositionTrace tr;
  tr.source = file;
  if (!in.has_header())
    throw core::Error(core::located(file, 0, "no header row (expected t_s, <AXIS>_command_mm, <AXIS>_actual_mm, ...)"));
  const std::vector<std::string>& header = in.columns();
  const int header_line = in.header_line();

  // Columns: t_s, then <AXIS>_command_<unit> / <AXIS>_actual_<unit>.
  int t_col = -1;
  struct Cols {
    int command = -1, actual = -1;
    bool rotary = false;
  };
  std::map<std::string, Cols> cols;
  std::vector<std::string> order;
  for (std::size_t c = 0; c < header.size(); ++c) {
    const std::string& h = header[c];
    const auto col_error = [&](const std::string& msg) {
      throw core::Error(core::located(file, header_line, fmt::format("column {} '{}': {}", c + 1, h, msg)));
    };
    if (h == "t_s") {
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
      col_error(
          "unknown column (expected t_s or <AXIS>_command_<unit>, <AXIS>_actual_<unit> with AXIS in X Y Z A B C)");
    const bool rotary = std::string("ABC").find(axis[0]) != std::string::npos;
    if (unit != (rotary ? "deg" : "mm")) col_error(fmt::format("axis {} is given in {}", axis, rotary ? "deg" : "mm"));
    if (!cols.count(axis)) order.push_back(axis);
    Cols& cc = cols[axis];
    cc.rotary = rotary;
    (kind == "command" ? cc.command : cc.actual) = static_cast<int>(c);
  }
  if (t_col < 0) throw core::Error(core::located(file, header_line, "no t_s column"));
  if (order.empty())
    throw core::Error(core::located(file, header_line, "no axis columns (<AXIS>_command_mm, <AXIS>_actual_mm)"));
  for (const auto& a : order) {
    const Cols& cc = cols[a];
    if (cc.command < 0 || cc.actual < 0)
      throw core::Error(core::located(file, header_line,
                                      fmt::format("axis {} needs both {}_command_{} and {}_actual_{}", a, a,
                                                  cc.rotary ? "deg" : "mm", a, cc.rotary ? "deg" : "mm")));
  }

  std::vector<double> values;
  std::vector<int> lines;
  const std::size_t nc = header.size();
  while (in.next()) {
    for (std::size_t c = 0; c < nc; ++c) values.push_back(in.number(c));
    lines.push_back(in.line());
    if (values.size() > std::size_t{1} << 31) throw in.error("the trace is too large");
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
  regularise_sampling(tr, lines);
  return tr;
}

void write_position_trace_csv(const std::filesystem::path& path, const PositionTrace& tr,
                              const std::vector<std::string>& comment_lines) {
  core::CsvWriter out(path);
  for (const auto& l : comment_lines) out.comment(l);
  std::vector<std::string> h = {"t_s"};
  for (std::size_t a = 0; a < tr.axes.size(); ++a) {
    const char* u = tr.rotary[a] ? "deg" : "mm";
    h.push_back(fmt::format("{}_command_{}", tr.axes[a], u));
    h.push_back(fmt::format("{}_actual_{}", tr.axes[a], u));
  }
  out.header(h);
  std::string line;
  for (Eigen::Index k = 0; k < tr.t_s.size(); ++k) {
    line = fmt::format("{:.7f}", tr.t_s[k]);
    for (std::size_t a = 0; a < tr.axes.size(); ++a) {
      const double f = tr.rotary[a] ? core::units::kRadToDeg : 1.0;
      const auto ai = static_cast<Eigen::Index>(a);
      line += fmt::format(",{:.10f},{:.10f}", tr.command(k, ai) * f, tr.actual(k, ai) * f);
    }
    out.row(line);
  }
  out.commit();
}

}  // namespace vmsim::sysid
