#include "sim/signals.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "motion/kinematics.hpp"
#include "core/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

namespace vmsim::sim {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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
      if (std::isnan(lo[b])) lo[b] = hi[b] = v;
      else lo[b] = std::min(lo[b], v), hi[b] = std::max(hi[b], v);
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
    bin.add(A + "_acceleration_actual_" + u + "_per_s2", [&, f, ai](Eigen::Index k) { return resp.acceleration(k, ai) * f; });
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
  core::AtomicFile out(file);
  auto& o = out.stream();
  o << "# vmsim signals 1: per-bin minimum and maximum of each signal (columns NAME.min, NAME.max) over bins of "
       "bin_samples consecutive samples, so that peaks survive the decimation; nan: undefined over the whole bin\n";
  o << "# job=" << s.job << '\n';
  o << fmt::format("# period_s={:.9g}\n# samples={}\n# bin_samples={}\n", s.period_s, s.samples, s.bin_samples);
  std::string axes, held;
  for (const auto& [name, unit] : s.axes) axes += (axes.empty() ? "" : ",") + name + ":" + unit;
  for (const auto& name : s.held_axes) held += (held.empty() ? "" : ",") + name;
  o << "# axes=" << axes << "\n# held_axes=" << held << '\n';
  for (const auto& [name, v] : s.limits) o << "# limit " << name << '=' << fmt::format("{:.9g}", v) << '\n';
  std::string line;
  for (std::size_t c = 0; c < s.names.size(); ++c) line += (c ? "," : "") + s.names[c] + ".min," + s.names[c] + ".max";
  o << line << '\n';
  for (Eigen::Index b = 0; b < s.bins(); ++b) {
    line.clear();
    for (Eigen::Index c = 0; c < static_cast<Eigen::Index>(s.names.size()); ++c) {
      if (c) line += ',';
      line += number(s.min(b, c));
      line += ',';
      line += number(s.max(b, c));
    }
    line += '\n';
    o << line;
  }
  out.commit();
}

BinnedSignals read_signals(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  const std::string fname = file.string();
  BinnedSignals s;
  std::string line;
  int lineno = 0;
  bool magic = false;
  std::vector<std::vector<double>> rows;
  std::size_t columns = 0;
  auto number_of = [&](const std::string& text, const char* key) {
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (end == text.c_str() || *end != '\0')
      throw core::Error(core::located(fname, lineno, std::string("expected a number for ") + key + ", found \"" + text + "\""));
    return v;
  };
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    if (line[0] == '#') {
      if (line.rfind("# vmsim signals 1", 0) == 0) magic = true;
      const std::string body = line.substr(std::min<std::size_t>(2, line.size()));
      const auto eq = body.find('=');
      if (eq == std::string::npos) continue;
      const std::string key = body.substr(0, eq), value = body.substr(eq + 1);
      if (key == "job") s.job = value;
      else if (key == "period_s") s.period_s = number_of(value, "period_s");
      else if (key == "samples") s.samples = static_cast<Eigen::Index>(number_of(value, "samples"));
      else if (key == "bin_samples") s.bin_samples = static_cast<Eigen::Index>(number_of(value, "bin_samples"));
      else if (key == "axes") {
        std::stringstream ss(value);
        std::string item;
        while (std::getline(ss, item, ',')) {
          const auto colon = item.find(':');
          if (colon == std::string::npos) throw core::Error(core::located(fname, lineno, "expected axes=NAME:UNIT,..."));
          s.axes.emplace_back(item.substr(0, colon), item.substr(colon + 1));
        }
      } else if (key == "held_axes") {
        std::stringstream ss(value);
        std::string item;
        while (std::getline(ss, item, ','))
          if (!item.empty()) s.held_axes.push_back(item);
      } else if (key.rfind("limit ", 0) == 0) {
        s.limits[key.substr(6)] = number_of(value, key.c_str());
      }
      continue;
    }
    if (!magic) throw core::Error(core::located(fname, lineno, "not a vmsim signals file (no \"# vmsim signals 1\" line)"));
    std::vector<std::string> cells;
    {
      std::stringstream ss(line);
      std::string cell;
      while (std::getline(ss, cell, ',')) cells.push_back(cell);
    }
    if (s.names.empty()) {
      if (cells.size() % 2 != 0) throw core::Error(core::located(fname, lineno, "expected pairs of NAME.min,NAME.max columns"));
      for (std::size_t c = 0; c < cells.size(); c += 2) {
        const std::string& a = cells[c];
        const std::string& b = cells[c + 1];
        if (a.size() < 5 || a.substr(a.size() - 4) != ".min" || b != a.substr(0, a.size() - 4) + ".max")
          throw core::Error(core::located(fname, lineno, "expected NAME.min,NAME.max, found \"" + a + "," + b + "\""));
        s.names.push_back(a.substr(0, a.size() - 4));
      }
      columns = cells.size();
      continue;
    }
    if (cells.size() != columns)
      throw core::Error(core::located(fname, lineno, fmt::format("expected {} values, found {}", columns, cells.size())));
    std::vector<double> row(columns);
    for (std::size_t c = 0; c < columns; ++c) {
      if (cells[c] == "nan") {
        row[c] = kNaN;
        continue;
      }
      char* end = nullptr;
      row[c] = std::strtod(cells[c].c_str(), &end);
      if (end == cells[c].c_str() || *end != '\0')
        throw core::Error(core::located(fname, lineno, "not a number: \"" + cells[c] + "\""));
    }
    rows.push_back(std::move(row));
  }
  if (!magic) throw core::Error(fname + ": not a vmsim signals file (no \"# vmsim signals 1\" line)");
  if (s.names.empty()) throw core::Error(fname + ": no column header");
  if (s.find("t_s") < 0) throw core::Error(fname + ": no t_s column");
  if (!(s.period_s > 0)) throw core::Error(fname + ": period_s must be > 0");
  const auto nb = static_cast<Eigen::Index>(rows.size()), nc = static_cast<Eigen::Index>(s.names.size());
  s.min.resize(nb, nc);
  s.max.resize(nb, nc);
  for (Eigen::Index b = 0; b < nb; ++b)
    for (Eigen::Index c = 0; c < nc; ++c) {
      s.min(b, c) = rows[static_cast<std::size_t>(b)][static_cast<std::size_t>(2 * c)];
      s.max(b, c) = rows[static_cast<std::size_t>(b)][static_cast<std::size_t>(2 * c + 1)];
    }
  return s;
}

}  // namespace vmsim::sim
