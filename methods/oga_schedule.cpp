#include "methods/oga_schedule.hpp"

#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <map>

namespace vmsim::methods {

namespace {

using Index = Eigen::Index;
using core::units::kNaN;
constexpr const char* kMagic = "# vmsim gain schedule 1";
constexpr double kSetpointTolerance = 1e-6;  // mm or deg: the file holds 9 decimals

int axis_by_name(const core::Machine& m, const std::string& name) {
  for (std::size_t a = 0; a < m.axes.size(); ++a)
    if (m.axes[a].name == name) return static_cast<int>(a);
  return -1;
}

double file_unit(const core::MachineAxis& ax) {
  return ax.kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0;
}
const char* unit_name(const core::MachineAxis& ax) { return ax.kind == core::AxisKind::Rotary ? "deg" : "mm"; }

std::string gain(double v) { return std::isnan(v) ? "nan" : fmt::format("{:.17g}", v); }

}  // namespace

drives::GainSchedule to_gain_schedule(const GainTable& t, const core::Machine& m) {
  drives::GainSchedule g;
  const Index n = t.kv_1000_per_min.rows(), na = static_cast<Index>(m.axes.size());
  g.kv_per_s = Eigen::MatrixXd::Constant(n, na, kNaN);
  g.kf = Eigen::MatrixXd::Constant(n, na, kNaN);
  for (std::size_t c = 0; c < t.axis_names.size(); ++c) {
    const int a = axis_by_name(m, t.axis_names[c]);
    if (a < 0) throw core::Error(fmt::format("gain schedule: the machine has no axis {}", t.axis_names[c]));
    const Index ci = static_cast<Index>(c);
    for (Index k = 0; k < n; ++k) {
      g.kv_per_s(k, a) = t.kv_1000_per_min(k, ci) * core::units::kKvMPerMinPerMmToPerS;
      g.kf(k, a) = t.kf(k, ci);
    }
  }
  return g;
}

void write_gain_schedule(const std::filesystem::path& file, const GainTable& t, const core::Setpoints& sp,
                         const core::Machine& m, const std::string& job_name,
                         const std::vector<std::string>& comments) {
  const Index n = sp.samples();
  if (t.kv_1000_per_min.rows() != n || t.kf.rows() != n ||
      t.kv_1000_per_min.cols() != static_cast<Index>(t.axis_names.size()) || t.kf.cols() != t.kv_1000_per_min.cols())
    throw core::Error(
        fmt::format("gain schedule {}: {} rows for {} setpoints", file.string(), t.kv_1000_per_min.rows(), n));
  std::vector<int> axes;
  std::vector<std::string> header = {"row", "t_s"};
  for (const std::string& name : t.axis_names) {
    const int a = axis_by_name(m, name);
    if (a < 0) throw core::Error(fmt::format("gain schedule {}: the machine has no axis {}", file.string(), name));
    axes.push_back(a);
    header.push_back(fmt::format("{}_setpoint_{}", name, unit_name(m.axes[static_cast<std::size_t>(a)])));
    header.push_back(name + "_kv_1000_per_min");
    header.push_back(name + "_kf");
  }
  core::CsvWriter out(file);
  out.comment(std::string(kMagic + 2) +
              ": position-loop gains per setpoint row (Duong et al. OGA); Kv in (m/min)/mm, KF "
              "dimensionless");
  out.comment("job=" + job_name);
  out.comment(fmt::format("period_s={:.17g}", sp.period_s));
  out.comment(fmt::format("samples={}", n));
  for (const std::string& c : comments) out.comment(c);
  out.header(header);
  std::string line;
  for (Index k = 0; k < n; ++k) {
    line = fmt::format("{},{:.6f}", k, k * sp.period_s);
    for (std::size_t c = 0; c < axes.size(); ++c) {
      const core::MachineAxis& ax = m.axes[static_cast<std::size_t>(axes[c])];
      const Index ci = static_cast<Index>(c);
      line += fmt::format(",{:.9f},{},{}", sp.position(k, axes[c]) * file_unit(ax), gain(t.kv_1000_per_min(k, ci)),
                          gain(t.kf(k, ci)));
    }
    out.row(line);
  }
  out.commit();
}

GainTable read_gain_table(const std::filesystem::path& file, const core::Setpoints& sp, const core::Machine& m) {
  core::CsvReader in(file);
  const std::string& f = in.name();
  std::map<std::string, std::string> meta;
  const std::vector<core::CsvComment>& comments = in.comments();
  const bool magic = !comments.empty() && comments.front().line == 1 && comments.front().text.rfind(kMagic, 0) == 0;
  for (const core::CsvComment& c : comments)
    if (const auto kv = core::comment_key_value(c.text)) meta[std::string(kv->first)] = std::string(kv->second);
  if (!magic)
    throw core::Error(core::located(
        f, 1,
        std::string("not a vmsim gain schedule (expected a first line \"") + kMagic + ": ...\", as vmsim oga writes)"));
  if (!in.has_header()) throw core::Error(f + ": no column header (row,t_s,<axis>_setpoint_mm,...)");
  const std::vector<std::string>& head = in.columns();
  const int head_line = in.header_line();
  const auto number = [&](const std::string& key) {
    auto it = meta.find(key);
    if (it == meta.end()) throw core::Error(f + ": the header has no '# " + key + "=' line");
    const auto v = core::parse_number(it->second);
    if (!v) throw core::Error(f + ": '# " + key + "=" + it->second + "' is not a number");
    return *v;
  };
  const double te = number("period_s");
  const double samples = number("samples");
  if (std::abs(te - sp.period_s) > 1e-12 * sp.period_s)
    throw core::Error(
        fmt::format("{}: the schedule is for Te = {} s, the job's setpoints have Te = {} s", f, te, sp.period_s));
  if (samples != static_cast<double>(sp.samples()))
    throw core::Error(
        fmt::format("{}: the schedule has {} rows, the job's setpoints {}: it was computed for another "
                    "program, feed or interpolation (run vmsim oga on this job again)",
                    f, samples, sp.samples()));

  // Columns: row, t_s, then per axis <A>_setpoint_<unit>, <A>_kv_1000_per_min, <A>_kf.
  if (head.size() < 2 || head[0] != "row" || head[1] != "t_s" || (head.size() - 2) % 3 != 0)
    throw core::Error(core::located(f, head_line,
                                    "expected the columns row,t_s then <axis>_setpoint_<mm|deg>,"
                                    "<axis>_kv_1000_per_min,<axis>_kf for each scheduled axis"));
  GainTable t;
  std::vector<int> axes;
  for (std::size_t c = 2; c < head.size(); c += 3) {
    const std::string name = head[c].substr(0, head[c].find('_'));
    const int a = axis_by_name(m, name);
    if (a < 0)
      throw core::Error(
          core::located(f, head_line, fmt::format("column '{}': the machine has no axis {}", head[c], name)));
    const core::MachineAxis& ax = m.axes[static_cast<std::size_t>(a)];
    const std::string want[3] = {name + "_setpoint_" + unit_name(ax), name + "_kv_1000_per_min", name + "_kf"};
    for (int j = 0; j < 3; ++j)
      if (head[c + static_cast<std::size_t>(j)] != want[j])
        throw core::Error(core::located(f, head_line,
                                        fmt::format("column {} is '{}', expected '{}'", c + j + 1,
                                                    head[c + static_cast<std::size_t>(j)], want[j])));
    for (int b : axes)
      if (b == a) throw core::Error(core::located(f, head_line, fmt::format("axis {} appears twice", name)));
    axes.push_back(a);
    t.axis_names.push_back(name);
  }
  const Index n = sp.samples(), na = static_cast<Index>(axes.size());
  t.kv_1000_per_min.resize(n, na);
  t.kf.resize(n, na);
  Index k = 0;
  while (in.next()) {
    if (k >= n) throw in.error(fmt::format("more than the {} rows the header announces", n));
    if (in.number(0) != static_cast<double>(k))
      throw in.error(fmt::format("row {} where row {} was expected (one row per setpoint, in order)", in.cell(0), k));
    for (Index c = 0; c < na; ++c) {
      const std::size_t base = 2 + 3 * static_cast<std::size_t>(c);
      const core::MachineAxis& ax = m.axes[static_cast<std::size_t>(axes[static_cast<std::size_t>(c)])];
      const double x = in.number(base), own = sp.position(k, axes[static_cast<std::size_t>(c)]) * file_unit(ax);
      if (!(std::abs(x - own) <= kSetpointTolerance))
        throw in.error(
            fmt::format("row {}: {} setpoint {} {}, the job's is {:.9f} {}: the schedule belongs to another "
                        "path (run vmsim oga on this job again)",
                        k, ax.name, in.cell(base), unit_name(ax), own, unit_name(ax)));
      const double kv = in.number_or_nan(base + 1, true), kf = in.number_or_nan(base + 2, true);
      if (!std::isnan(kv) && !(kv > 0.0))
        throw in.error(fmt::format("{}: {} is not a gain (expected > 0 (m/min)/mm, or nan for the drive's own)",
                                   head[base + 1], in.cell(base + 1)));
      if (!std::isnan(kf) && !(kf >= 0.0))
        throw in.error(fmt::format("{}: {} is not a feedforward gain (expected >= 0, or nan for the drive's own)",
                                   head[base + 2], in.cell(base + 2)));
      t.kv_1000_per_min(k, c) = kv;
      t.kf(k, c) = kf;
    }
    ++k;
  }
  if (k != n) throw core::Error(fmt::format("{}: {} rows, the header announces {}", f, k, n));
  return t;
}

}  // namespace vmsim::methods
