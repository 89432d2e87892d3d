#include "sim/signals.hpp"

#include "core/csv.hpp"
#include "core/error.hpp"
#include "motion/kinematics.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace vmsim::sim {

namespace {

using core::units::kNaN;

// Folds one signal at a time into per-bin minima and maxima; `value(k)` is called for k = 0, 1, ... in order, so
// it may carry state from one sample to the next (differences, running sums).
class Binner {
 public:
  Binner(Eigen::Index samples, Eigen::Index max_bins) : n_(samples) {
    bs_ = std::max<Eigen::Index>(1, (samples + max_bins - 1) / std::max<Eigen::Index>(1, max_bins));
    bins_ = (samples + bs_ - 1) / bs_;
  }
  template <class F>
  void add(const std::string& name, F&& value) {
    Eigen::ArrayXd lo = Eigen::ArrayXd::Constant(bins_, kNaN), hi = lo;
    for (Eigen::Index k = 0; k < n_; ++k) {
      const double v = value(k);
      if (!std::isfinite(v)) continue;
      const Eigen::Index b = k / bs_;
      if (std::isnan(lo[b]))
        lo[b] = hi[b] = v;
      else
        lo[b] = std::min(lo[b], v), hi[b] = std::max(hi[b], v);
    }
    names_.push_back(name);
    lo_.push_back(std::move(lo));
    hi_.push_back(std::move(hi));
  }
  void finish(BinnedSignals& out) const {
    out.samples = n_;
    out.bin_samples = bs_;
    out.names = names_;
    out.min.resize(bins_, static_cast<Eigen::Index>(names_.size()));
    out.max.resize(bins_, static_cast<Eigen::Index>(names_.size()));
    for (std::size_t c = 0; c < names_.size(); ++c) {
      out.min.col(static_cast<Eigen::Index>(c)) = lo_[c];
      out.max.col(static_cast<Eigen::Index>(c)) = hi_[c];
    }
  }

 private:
  Eigen::Index n_, bs_ = 1, bins_ = 0;
  std::vector<std::string> names_;
  std::vector<Eigen::ArrayXd> lo_, hi_;
};

std::string number(double v) { return std::isfinite(v) ? fmt::format("{:.7g}", v) : "nan"; }

}  // namespace

int BinnedSignals::find(const std::string& name) const {
  for (std::size_t k = 0; k < names.size(); ++k)
    if (names[k] == name) return static_cast<int>(k);
  return -1;
}

std::optional<double> BinnedSignals::limit(const std::string& name) const {
  const auto it = limits.find(name);
  if (it == limits.end()) return std::nullopt;
  return it->second;
}

BinnedSignals motion_signals(const core::Job& job, const core::ToolPath& program, const core::Setpoints& sp,
                             const drives::AxisResponse& resp, const motion::ContourError& ce, double feed_scale,
                             Eigen::Index max_bins) {
  const core::Machine& machine = job.machine;
  const Eigen::Index n = resp.samples(), ns = sp.samples();
  if (n == 0 || ns == 0) throw core::Error("signals: the run has no samples");
  if (ce.signed_mm.size() != n)
    throw core::Error(fmt::format("signals: {} contour-error samples for {} drive samples", ce.signed_mm.size(), n));
  const double te = sp.period_s;
  BinnedSignals out;
  out.job = job.name;
  out.period_s = te;
  Binner bin(n, max_bins);

  auto move_of = [&](Eigen::Index k) { return sp.move_index[std::min(k, ns - 1)]; };
  auto cutting = [&](Eigen::Index k) {
    const int mi = move_of(k);
    return mi >= 0 && !program.moves[static_cast<std::size_t>(mi)].rapid;
  };
  auto tlo = [&](Eigen::Index k) {
    const int mi = move_of(k);
    return mi >= 0 ? program.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
  };

  bin.add("t_s", [&](Eigen::Index k) { return static_cast<double>(k) * te; });
  for (std::size_t a = 0; a < machine.axes.size(); ++a) {
    const core::MachineAxis& ax = machine.axes[a];
    const auto ai = static_cast<Eigen::Index>(a);
    const bool moves = sp.position.col(ai).maxCoeff() - sp.position.col(ai).minCoeff() > 1e-9;
    if (!moves) {
      out.held_axes.push_back(ax.name);
      continue;
    }
    const bool rotary = ax.kind == core::AxisKind::Rotary;
    const double f = rotary ? core::units::kRadToDeg : 1.0;
    const std::string u = rotary ? "deg" : "mm", A = ax.name;
    out.axes.emplace_back(A, u);
    // Setpoints as the drives receive them: held at the last one while the axes settle, at rest before the first.
    auto x = [&, ai](Eigen::Index k) { return sp.position(std::clamp<Eigen::Index>(k, 0, ns - 1), ai); };
    bin.add(A + "_setpoint_" + u, [&, f](Eigen::Index k) { return x(k) * f; });
    bin.add(A + "_actual_" + u, [&, f, ai](Eigen::Index k) { return resp.position(k, ai) * f; });
    bin.add(A + "_tracking_error_" + u, [&, f, ai](Eigen::Index k) { return (x(k) - resp.position(k, ai)) * f; });
    bin.add(A + "_velocity_setpoint_" + u + "_per_s", [&, f](Eigen::Index k) { return (x(k) - x(k - 1)) / te * f; });
    bin.add(A + "_velocity_actual_" + u + "_per_s", [&, f, ai](Eigen::Index k) { return resp.velocity(k, ai) * f; });
    bin.add(A + "_acceleration_setpoint_" + u + "_per_s2",
            [&, f](Eigen::Index k) { return (x(k) - 2 * x(k - 1) + x(k - 2)) / (te * te) * f; });
    bin.add(A + "_acceleration_actual_" + u + "_per_s2",
            [&, f, ai](Eigen::Index k) { return resp.acceleration(k, ai) * f; });
    bin.add(A + "_jerk_setpoint_" + u + "_per_s3",
            [&, f](Eigen::Index k) { return (x(k) - 3 * x(k - 1) + 3 * x(k - 2) - x(k - 3)) / (te * te * te) * f; });
    bin.add(A + "_jerk_actual_" + u + "_per_s3", [&, f, ai](Eigen::Index k) { return resp.jerk(k, ai) * f; });
    bin.add(A + "_current_A", [&, ai](Eigen::Index k) { return resp.current_mean_A(k, ai); });
    bin.add(A + "_current_peak_A", [&, ai](Eigen::Index k) { return resp.current_peak_A(k, ai); });
    out.limits[A + "_velocity_" + u + "_per_s"] = ax.max_velocity * f;
    out.limits[A + "_acceleration_" + u + "_per_s2"] = ax.max_acceleration * f;
    out.limits[A + "_jerk_" + u + "_per_s3"] = ax.max_jerk * f;
    if (ax.drive) out.limits[A + "_current_A"] = ax.drive->current_limit_A;
  }

  bin.add("feed_programmed_mm_per_min", [&](Eigen::Index k) {
    if (k >= ns || !cutting(k)) return kNaN;
    const core::Move& mv = program.moves[static_cast<std::size_t>(move_of(k))];
    return mv.feed_mode == core::FeedMode::UnitsPerMinute ? mv.feed_mm_per_min * feed_scale : kNaN;
  });
  bin.add("path_speed_setpoint_mm_per_min",
          [&](Eigen::Index k) { return k < ns ? sp.path_speed_mm_per_s[k] * 60 : 0.0; });
  const auto kin = motion::make_kinematics(machine);
  {
    Eigen::Vector3d prev = Eigen::Vector3d::Zero();
    bin.add("path_speed_actual_mm_per_min", [&](Eigen::Index k) {
      const Eigen::Vector3d p = kin->forward(resp.position.row(k).transpose(), tlo(k)).tip_mm;
      const double v = k == 0 ? 0.0 : (p - prev).norm() / te * 60;
      prev = p;
      return v;
    });
  }
  bin.add("contour_error_mm", [&](Eigen::Index k) { return cutting(k) ? ce.signed_mm[k] : kNaN; });
  {
    Eigen::Vector3d prev = Eigen::Vector3d::Zero();
    double s = 0;
    bin.add("cutting_path_mm", [&](Eigen::Index k) {
      const Eigen::Vector3d p = kin->forward(sp.position.row(std::min(k, ns - 1)).transpose(), tlo(k)).tip_mm;
      if (k > 0 && cutting(k)) s += (p - prev).norm();
      prev = p;
      return s;
    });
  }
  bin.add("cutting", [&](Eigen::Index k) { return cutting(k) ? 1.0 : 0.0; });
  bin.finish(out);
  return out;
}

void write_signals(const std::filesystem::path& file, const BinnedSignals& s) {
  core::CsvWriter out(file);
  out.comment(
      "vmsim signals 1: per-bin minimum and maximum of each signal (columns NAME.min, NAME.max) over bins of "
      "bin_samples consecutive samples, so that peaks survive the decimation; nan: undefined over the whole bin");
  out.comment("job=" + s.job);
  out.comment(fmt::format("period_s={:.9g}", s.period_s));
  out.comment(fmt::format("samples={}", s.samples));
  out.comment(fmt::format("bin_samples={}", s.bin_samples));
  std::string axes, held;
  for (const auto& [name, unit] : s.axes) axes += (axes.empty() ? "" : ",") + name + ":" + unit;
  for (const auto& name : s.held_axes) held += (held.empty() ? "" : ",") + name;
  out.comment("axes=" + axes);
  out.comment("held_axes=" + held);
  for (const auto& [name, v] : s.limits) out.comment("limit " + name + '=' + fmt::format("{:.9g}", v));
  std::vector<std::string> header;
  for (const std::string& n : s.names) {
    header.push_back(n + ".min");
    header.push_back(n + ".max");
  }
  out.header(header);
  std::string line;
  for (Eigen::Index b = 0; b < s.bins(); ++b) {
    line.clear();
    for (Eigen::Index c = 0; c < static_cast<Eigen::Index>(s.names.size()); ++c) {
      if (c) line += ',';
      line += number(s.min(b, c));
      line += ',';
      line += number(s.max(b, c));
    }
    out.row(line);
  }
  out.commit();
}

BinnedSignals read_signals(const std::filesystem::path& file) {
  core::CsvReader in(file);
  const std::string& fname = in.name();
  BinnedSignals s;
  bool magic = false;
  // The metadata: the '#' lines before the header.
  for (const core::CsvComment& c : in.comments()) {
    if (c.text.rfind("# vmsim signals 1", 0) == 0) magic = true;
    const auto kv = core::comment_key_value(c.text);
    if (!kv) continue;
    const std::string key(kv->first), value(kv->second);
    auto number_of = [&](const char* what) {
      const auto v = core::parse_number(value);
      if (!v)
        throw core::Error(
            core::located(fname, c.line, std::string("expected a number for ") + what + ", found \"" + value + "\""));
      return *v;
    };
    if (key == "job")
      s.job = value;
    else if (key == "period_s")
      s.period_s = number_of("period_s");
    else if (key == "samples")
      s.samples = static_cast<Eigen::Index>(number_of("samples"));
    else if (key == "bin_samples")
      s.bin_samples = static_cast<Eigen::Index>(number_of("bin_samples"));
    else if (key == "axes") {
      std::stringstream ss(value);
      std::string item;
      while (std::getline(ss, item, ',')) {
        const auto colon = item.find(':');
        if (colon == std::string::npos) throw core::Error(core::located(fname, c.line, "expected axes=NAME:UNIT,..."));
        s.axes.emplace_back(item.substr(0, colon), item.substr(colon + 1));
      }
    } else if (key == "held_axes") {
      std::stringstream ss(value);
      std::string item;
      while (std::getline(ss, item, ','))
        if (!item.empty()) s.held_axes.push_back(item);
    } else if (key.rfind("limit ", 0) == 0) {
      s.limits[key.substr(6)] = number_of(key.c_str());
    }
  }
  if (!magic) {
    const int at = in.has_header() ? in.header_line() : 0;
    throw core::Error(core::located(fname, at, "not a vmsim signals file (no \"# vmsim signals 1\" line)"));
  }
  if (!in.has_header()) throw core::Error(fname + ": no column header");
  const std::vector<std::string>& cells = in.columns();
  if (cells.size() % 2 != 0) throw in.error("expected pairs of NAME.min,NAME.max columns", in.header_line());
  for (std::size_t c = 0; c < cells.size(); c += 2) {
    const std::string& a = cells[c];
    const std::string& b = cells[c + 1];
    if (a.size() < 5 || a.substr(a.size() - 4) != ".min" || b != a.substr(0, a.size() - 4) + ".max")
      throw in.error("expected NAME.min,NAME.max, found \"" + a + "," + b + "\"", in.header_line());
    s.names.push_back(a.substr(0, a.size() - 4));
  }
  if (s.find("t_s") < 0) throw core::Error(fname + ": no t_s column");
  if (!(s.period_s > 0)) throw core::Error(fname + ": period_s must be > 0");
  const std::size_t columns = cells.size();
  std::vector<double> values;
  while (in.next())
    for (std::size_t c = 0; c < columns; ++c) values.push_back(in.number_or_nan(c));
  const auto nb = static_cast<Eigen::Index>(values.size() / std::max<std::size_t>(1, columns));
  const auto nc = static_cast<Eigen::Index>(s.names.size());
  s.min.resize(nb, nc);
  s.max.resize(nb, nc);
  for (Eigen::Index b = 0; b < nb; ++b)
    for (Eigen::Index c = 0; c < nc; ++c) {
      s.min(b, c) = values[static_cast<std::size_t>(b) * columns + static_cast<std::size_t>(2 * c)];
      s.max(b, c) = values[static_cast<std::size_t>(b) * columns + static_cast<std::size_t>(2 * c + 1)];
    }
  return s;
}

}  // namespace vmsim::sim
