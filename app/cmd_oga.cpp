// vmsim oga JOB: offline gain adjustment (Duong et al.) on a job's biaxial profile (sim/oga.hpp). This file parses the
// options, runs the library call (its best-pair search spread over the ranks under mpirun), writes the tables and
// the gain schedules ([job] gain_schedule for vmsim run and vmsim motion), draws the charts, writes report.json and
// prints the summary.
#include "app/commands_oga.hpp"
#include "core/units.hpp"
#include "app/mpi_session.hpp"
#include "app/progress.hpp"
#include "app/report.hpp"
#include "app/result_images.hpp"
#include "app/tiled_run.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/job.hpp"
#include "core/timing.hpp"
#include "methods/oga.hpp"
#include "methods/oga_schedule.hpp"
#include "render/chart.hpp"
#include "render/window.hpp"
#include "sim/oga.hpp"

#include <fmt/format.h>
#include <mpi.h>
#include <nlohmann/json.hpp>
#include <omp.h>

#include <optional>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

namespace vmsim::app {

namespace {

namespace fs = std::filesystem;
using core::Clock;
using core::seconds_since;
using Eigen::Index;
using core::units::kNaN;

// "MIN:STEP:MAX" -> the grid MIN, MIN + STEP, ... <= MAX (as Duong et al. writes [1 : 0.5 : 9]); a single number is a
// grid of one value.
std::vector<double> parse_grid(const std::string& text, const std::string& option) {
  std::vector<double> parts;
  std::stringstream ss(text);
  std::string cell;
  while (std::getline(ss, cell, ':')) {
    try {
      std::size_t used = 0;
      parts.push_back(std::stod(cell, &used));
      if (used != cell.size()) throw std::invalid_argument(cell);
    } catch (const std::exception&) {
      throw core::Error(
          fmt::format("{} \"{}\": \"{}\" is not a number (expected MIN:STEP:MAX, e.g. 1:0.5:9)", option, text, cell));
    }
  }
  if (parts.size() == 1 && std::isfinite(parts[0])) return parts;
  if (parts.size() != 3 || !std::isfinite(parts[0]) || !std::isfinite(parts[2]) || !(parts[1] > 0) ||
      !(parts[2] >= parts[0]))
    throw core::Error(
        fmt::format("{} \"{}\": expected MIN:STEP:MAX with STEP > 0 and MAX >= MIN (e.g. 1:0.5:9)", option, text));
  const double n = std::floor((parts[2] - parts[0]) / parts[1] + 1e-9);
  if (n > 10000) throw core::Error(fmt::format("{} \"{}\": more than 10000 values", option, text));
  std::vector<double> g;
  for (int i = 0; i <= static_cast<int>(n); ++i) g.push_back(parts[0] + i * parts[1]);
  return g;
}

// --range "MIN:MAX" (every adjusted axis) or "AXIS=MIN:MAX".
void parse_range(const std::string& text, std::map<std::string, std::pair<double, double>>& named,
                 std::optional<std::pair<double, double>>& all) {
  std::string axis, span = text;
  if (const auto eq = text.find('='); eq != std::string::npos) axis = text.substr(0, eq), span = text.substr(eq + 1);
  const auto colon = span.find(':');
  double lo = kNaN, hi = kNaN;
  try {
    if (colon == std::string::npos) throw std::invalid_argument(span);
    std::size_t u1 = 0, u2 = 0;
    lo = std::stod(span.substr(0, colon), &u1);
    hi = std::stod(span.substr(colon + 1), &u2);
    if (u1 != colon || u2 != span.size() - colon - 1) throw std::invalid_argument(span);
  } catch (const std::exception&) {
    throw core::Error("--range \"" + text + "\": expected MIN:MAX or AXIS=MIN:MAX in (m/min)/mm (e.g. Z=5:6.5)");
  }
  if (!(lo > 0 && hi >= lo && std::isfinite(hi)))
    throw core::Error("--range \"" + text + "\": expected 0 < MIN <= MAX");
  if (axis.empty()) {
    all = std::pair{lo, hi};
  } else {
    if (axis != "X" && axis != "Y" && axis != "Z")
      throw core::Error("--range \"" + text + "\": the axis must be X, Y or Z");
    if (named.count(axis)) throw core::Error("--range: axis " + axis + " is given twice");
    named[axis] = {lo, hi};
  }
}

// The command line's options, checked before any simulation (a typo costs none).
sim::OgaJobOptions oga_options(const OgaArgs& args) {
  sim::OgaJobOptions opt;
  methods::OgaOptions& o = opt.search;
  o.kp_grid = parse_grid(args.kp_grid, "--kp-grid");
  o.kf_grid = parse_grid(args.kf_grid, "--kf-grid");
  for (const std::string& r : args.ranges) parse_range(r, o.range, opt.range_all);
  if (!(args.gain_step > 0 && std::isfinite(args.gain_step)))
    throw core::Error(fmt::format("--dk {}: expected a gain step > 0 in (m/min)/mm", args.gain_step));
  o.gain_step = args.gain_step;
  if (!(args.frequency_hz > 0 && std::isfinite(args.frequency_hz)))
    throw core::Error(fmt::format("--frequency-hz {}: expected a frequency > 0", args.frequency_hz));
  o.frequency_hz = args.frequency_hz;
  if (args.reference == "best") {
    o.reference = methods::OgaOptions::Reference::Best;
  } else if (args.reference == "machine") {
    o.reference = methods::OgaOptions::Reference::Machine;
  } else {
    throw core::Error("--reference \"" + args.reference + "\": expected best or machine");
  }
  if (!(args.straight_curvature_per_mm >= 0 && std::isfinite(args.straight_curvature_per_mm)))
    throw core::Error("--straight-curvature: expected a curvature >= 0 in 1/mm");
  if (!(args.transition_rate_per_mm2 > 0 && std::isfinite(args.transition_rate_per_mm2)))
    throw core::Error("--transition-rate: expected a rate > 0 in 1/mm^2");
  if (args.min_window_rows < 1) throw core::Error("--min-window-rows: expected >= 1");
  if (args.lead_in_rows < 0) throw core::Error("--lead-in-rows: expected >= 0");
  if (!(args.settle_s >= 0 && args.settle_s <= 60)) throw core::Error("--settle-s: expected 0 .. 60 s");
  o.windows.straight_curvature_per_mm = args.straight_curvature_per_mm;
  o.windows.transition_rate_per_mm2 = args.transition_rate_per_mm2;
  o.windows.min_rows = args.min_window_rows;
  o.lead_in_rows = args.lead_in_rows;
  o.settle_s = args.settle_s;
  o.from_start = args.from_start;
  try {
    o.limits = methods::parse_limit_set(args.limits);
  } catch (const core::Error& e) {
    throw core::Error(std::string("--limits: ") + e.what());
  }
  if (args.threads && (*args.threads < 1 || *args.threads > 1024)) throw core::Error("--threads: expected 1 .. 1024");
  // Under mpirun: the best-fixed-pair search (most of a whole run's CPU, bench/README.md) is spread over the ranks;
  // every rank then holds the same values and reaches the same result, which rank 0 alone verifies and writes.
  if (mpi_active()) {
    o.share.index = mpi_rank();
    o.share.count = mpi_size();
    o.share.combine = [](std::vector<double>& v) {
      // Every rank meets first under the watchdog (a stopped rank is named), so the reduction itself cannot hang.
      quiet_barrier("oga: the exchange of the fixed-pair search's results");
      MPI_Allreduce(MPI_IN_PLACE, v.data(), static_cast<int>(v.size()), MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
    };
  }
  opt.verify = mpi_rank() == 0;
  return opt;
}

std::string csv_text(const std::string& s) {
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

// Per response row (setpoints, then the settling rows): time, path length, the contour error of C1 and C2 (um) and
// whether the row counts in MSE(CE).
struct Rows {
  Eigen::ArrayXd t, s, ce1, ce2, weight;
  Rows(const sim::OgaJobResult& o) {
    const methods::OgaVerification& v = *o.verification;
    const core::Setpoints& sp = o.interp.setpoints;
    const Index nr = v.c1.samples(), ns = sp.samples();
    t.resize(nr), s.resize(nr), ce1.resize(nr), ce2.resize(nr), weight.resize(nr);
    for (Index k = 0; k < nr; ++k) {
      t[k] = k * sp.period_s;
      s[k] = sp.path_length_mm[std::min(k, ns - 1)];
      ce1[k] = v.ce_c1.signed_mm[k] * 1e3;
      ce2[k] = v.ce_c2.signed_mm[k] * 1e3;
      weight[k] = k < o.options.row_weight.size() ? o.options.row_weight[k] : 0.0;
    }
  }
};

// The admissible sets (Duong et al. Fig. 7) and the windows of the schedule.
void write_search_tables(const fs::path& dir, const methods::OgaResult& r, double te) {
  core::AtomicFile a(dir / "admissible.csv");
  a.stream() << "axis,kp_1000_per_min,kf,admissible,velocity_m_per_min,acceleration_m_per_s2,jerk_m_per_s3,"
                "current_peak_A,violation\n";
  for (std::size_t q = 0; q < r.axes.size(); ++q)
    for (const methods::ConfigCheck& c : r.sweep[q])
      a.stream() << fmt::format("{},{:g},{:g},{},{:.6g},{:.6g},{:.6g},{:.6g},{}\n", r.axis_names[q], c.gains.kp,
                                c.gains.kf, c.admissible ? 1 : 0, c.twin.velocity.value * 60e-3,
                                c.twin.acceleration.value * 1e-3, c.twin.jerk.value * 1e-3, c.twin.current.value,
                                csv_text(c.violation));
  a.commit();
  core::AtomicFile f(dir / "windows.csv");
  std::string h = "window,first_row,end_row,t_start_s,kind";
  for (const auto& n : r.axis_names) h += fmt::format(",{0}_final_kv_1000_per_min,{0}_candidates,{0}_within_limits", n);
  f.stream() << h << ",mse_um2,hold_mse_um2,note\n";
  for (std::size_t w = 0; w < r.windows.size(); ++w) {
    const methods::OgaWindowResult& x = r.windows[w];
    std::string l = fmt::format("{},{},{},{:.6f},{}", w, x.window.begin, x.window.end, x.window.begin * te,
                                methods::window_kind_name(x.window.kind));
    for (std::size_t q = 0; q < r.axes.size(); ++q)
      l += fmt::format(",{:.17g},{},{}", x.final_kp[q], x.candidates[q], x.within_limits[q]);
    f.stream() << l << fmt::format(",{:.6g},{:.6g},{}\n", x.mse_um2, x.hold_mse_um2, csv_text(x.note));
  }
  f.commit();
}

void write_schedules(const fs::path& dir, const core::Job& job, const sim::OgaJobResult& o,
                     const std::string& reference) {
  const methods::OgaResult& r = o.result;
  const core::Setpoints& sp = o.interp.setpoints;
  std::vector<std::string> comments = {
      fmt::format("C2 of vmsim oga: receding windows, dK {:g}, f {:g} Hz (p = {}), C1 = {}", o.options.gain_step,
                  o.options.frequency_hz, r.sinusoid_samples, reference)};
  for (std::size_t q = 0; q < r.axes.size(); ++q)
    comments.push_back(fmt::format("{}: range [{:g}, {:g}] (m/min)/mm, KF {:g} (C1's)", r.axis_names[q],
                                   r.range[q].first, r.range[q].second, r.c1[q].kf));
  methods::write_gain_schedule(dir / "gain_schedule.csv", r.table, sp, job.machine, job.name, comments);
  methods::write_gain_schedule(dir / "gain_schedule_c1.csv", r.c1_table, sp, job.machine, job.name,
                               {"C1 of vmsim oga: the fixed gains, as a schedule"});
}

// C1 against C2 row by row, and Duong et al. Table II.
void write_comparison(const fs::path& dir, const sim::OgaJobResult& o, const Rows& rows) {
  const methods::OgaResult& r = o.result;
  const methods::OgaVerification& v = *o.verification;
  const std::size_t nq = r.axes.size();
  const Index ns = o.interp.setpoints.samples();
  core::AtomicFile f(dir / "comparison.csv");
  std::string h = "t_s,path_mm";
  for (const auto& n : r.axis_names) h += fmt::format(",{}_kv_c2_1000_per_min", n);
  h += ",contour_error_c1_um,contour_error_c2_um,counted";
  for (const auto& n : r.axis_names) h += fmt::format(",{0}_current_setpoint_c1_A,{0}_current_setpoint_c2_A", n);
  f.stream() << h << '\n';
  for (Index k = 0; k < rows.t.size(); ++k) {
    std::string l = fmt::format("{:.6f},{:.6f}", rows.t[k], rows.s[k]);
    for (std::size_t q = 0; q < nq; ++q)
      l += fmt::format(",{:.6f}", r.table.kv_1000_per_min(std::min(k, ns - 1), static_cast<Index>(q)));
    l += fmt::format(",{:.6f},{:.6f},{}", rows.ce1[k], rows.ce2[k], rows.weight[k] > 0 ? 1 : 0);
    for (std::size_t q = 0; q < nq; ++q)
      l += fmt::format(",{:.5f},{:.5f}", v.c1.current_setpoint_A(k, r.axes[q]), v.c2.current_setpoint_A(k, r.axes[q]));
    f.stream() << l << '\n';
  }
  f.commit();
  core::AtomicFile m(dir / "mse_table.csv");
  h = "case";
  for (const auto& n : r.axis_names) h += fmt::format(",{0}_kv_min_1000_per_min,{0}_kv_max_1000_per_min,{0}_kf", n);
  m.stream() << h << ",mse_um2,max_contour_error_um,change_percent\n";
  for (int c = 0; c < 2; ++c) {
    const methods::GainTable& g = c == 0 ? r.c1_table : r.table;
    std::string l = c == 0 ? "C1" : "C2";
    for (std::size_t q = 0; q < nq; ++q)
      l += fmt::format(",{:.6g},{:.6g},{:g}", g.kv_1000_per_min.col(static_cast<Index>(q)).minCoeff(),
                       g.kv_1000_per_min.col(static_cast<Index>(q)).maxCoeff(), r.c1[q].kf);
    l += c == 0 ? fmt::format(",{:.6g},{:.6g},0\n", v.mse_c1_um2, v.max_c1_mm * 1e3)
                : fmt::format(",{:.6g},{:.6g},{:.3f}\n", v.mse_c2_um2, v.max_c2_mm * 1e3, o.change_percent);
    m.stream() << l;
  }
  m.commit();
}

// A histogram as a step line: counts per bin of width `bin` over [lo, hi].
render::Series histogram(const std::string& name, const Eigen::ArrayXd& v, const Eigen::ArrayXd& weight, double lo,
                         double hi, int bins, int colour) {
  Eigen::ArrayXd count = Eigen::ArrayXd::Zero(bins);
  for (Index k = 0; k < v.size(); ++k) {
    if (!(weight[k] > 0) || !std::isfinite(v[k])) continue;
    const int b = std::clamp(static_cast<int>(std::floor((v[k] - lo) / (hi - lo) * bins)), 0, bins - 1);
    count[b] += 1;
  }
  Eigen::ArrayXd x(2 * bins + 2), y(2 * bins + 2);
  const double w = (hi - lo) / bins;
  x[0] = lo, y[0] = 0;
  for (int b = 0; b < bins; ++b) {
    x[2 * b + 1] = lo + b * w, y[2 * b + 1] = count[b];
    x[2 * b + 2] = lo + (b + 1) * w, y[2 * b + 2] = count[b];
  }
  x[2 * bins + 1] = hi, y[2 * bins + 1] = 0;
  return render::make_series(name, x, y, colour, 1.6);
}

// The gains along the path (C2 and C1) over the curvature the windows are cut on (Duong et al. Fig. 8-9).
render::ChartPicture gains_picture(const core::Machine& machine, const sim::OgaJobResult& o, const Rows& rows) {
  const methods::OgaResult& r = o.result;
  const core::Setpoints& sp = o.interp.setpoints;
  const Index nr = rows.t.size(), ns = sp.samples();
  render::ChartPicture pic;
  pic.caption = {"", fmt::format("position-loop gain along the path: C2 (receding windows, {} windows, eq. 3-4) and C1 "
                                 "(fixed); the curvature the windows are cut on",
                                 r.windows.size())};
  render::Chart c;
  c.title = "Kv";
  c.x_title = "s [mm]";
  c.y_title = "Kv [(m/min)/mm]";
  double lo = INFINITY, hi = -INFINITY;
  for (std::size_t q = 0; q < r.axes.size(); ++q) {
    Eigen::ArrayXd k(nr);
    for (Index i = 0; i < nr; ++i) k[i] = r.table.kv_1000_per_min(std::min(i, ns - 1), static_cast<Index>(q));
    c.series.push_back(render::make_series(r.axis_names[q] + " C2", rows.s, k, static_cast<int>(q), 2.0));
    c.series.push_back(render::make_series(r.axis_names[q] + " C1", rows.s, Eigen::ArrayXd::Constant(nr, r.c1[q].kp),
                                           static_cast<int>(q), 1.0, true));
    lo = std::min(lo, r.range[q].first), hi = std::max(hi, r.range[q].second);
  }
  c.levels.push_back({fmt::format("range [{:g}, {:g}]", lo, hi), hi, {0.5, 0.5, 0.5}});
  c.levels.push_back({"", lo, {0.5, 0.5, 0.5}});
  const double pad = 0.1 * (hi - lo) + 0.05;
  c.y_range = std::pair{lo - pad, hi + pad};
  pic.charts.push_back(c);
  render::Chart k;
  k.title = "curvature";
  k.x_title = "s [mm]";
  k.y_title = "curvature [1/mm]";
  Eigen::MatrixXd xyz(ns, 3);
  for (int cc = 0; cc < 3; ++cc) xyz.col(cc) = sp.position.col(machine.axis_index(cc));
  const Eigen::ArrayXd kappa = methods::setpoint_curvature(xyz, r.plane_normal, o.options.windows.min_chord_mm);
  k.series.push_back(render::make_series("curvature (+: convex)", rows.s.head(ns), kappa, 3));
  Eigen::ArrayXd wx(3 * r.windows.size()), wy(3 * r.windows.size());
  const double kmax = std::max(1e-3, kappa.abs().maxCoeff());
  for (std::size_t w = 0; w < r.windows.size(); ++w) {  // window starts as vertical ticks
    const double x = sp.path_length_mm[r.windows[w].window.begin];
    wx[3 * w] = wx[3 * w + 1] = x, wx[3 * w + 2] = kNaN;
    wy[3 * w] = -kmax, wy[3 * w + 1] = kmax, wy[3 * w + 2] = kNaN;
  }
  k.series.push_back(render::make_series("window starts", wx, wy, 7, 0.8, true));
  pic.charts.push_back(k);
  return pic;
}

render::ChartPicture contour_picture(const methods::OgaVerification& v, const Rows& rows) {
  render::ChartPicture pic;
  pic.caption = {"",
                 "contour error along the path, C1 (fixed gains) and C2 (the schedule), simulated with the "
                 "nonlinear model"};
  render::Chart c;
  c.title = "contour error";
  c.x_title = "s [mm]";
  c.y_title = "contour error [µm]";
  c.series.push_back(render::make_series(fmt::format("C1 (MSE {:.3g} µm²)", v.mse_c1_um2), rows.s, rows.ce1, 1, 1.4));
  c.series.push_back(render::make_series(fmt::format("C2 (MSE {:.3g} µm²)", v.mse_c2_um2), rows.s, rows.ce2, 0, 1.6));
  pic.charts.push_back(c);
  return pic;
}

render::ChartPicture histogram_picture(const Rows& rows) {
  render::ChartPicture pic;
  pic.caption = {"", "histogram of the contour error on the feed moves, C1 and C2"};
  double m = 0;
  for (Index k = 0; k < rows.t.size(); ++k)
    if (rows.weight[k] > 0) m = std::max({m, std::abs(rows.ce1[k]), std::abs(rows.ce2[k])});
  m = m > 0 ? m * 1.02 : 1.0;
  render::Chart c;
  c.title = "contour error histogram";
  c.x_title = "contour error [µm]";
  c.y_title = "samples";
  c.series.push_back(histogram("C1", rows.ce1, rows.weight, -m, m, 60, 1));
  c.series.push_back(histogram("C2", rows.ce2, rows.weight, -m, m, 60, 0));
  pic.charts.push_back(c);
  return pic;
}

render::ChartPicture currents_picture(const sim::OgaJobResult& o, const Rows& rows) {
  const methods::OgaResult& r = o.result;
  const methods::OgaVerification& v = *o.verification;
  render::ChartPicture pic;
  pic.caption = {"",
                 "current reference (velocity-loop output) of each adjusted axis, C1 and C2 (Duong et al. Fig. 12)"};
  for (std::size_t q = 0; q < r.axes.size(); ++q) {
    render::Chart c;
    const methods::AxisVerification& av = v.axes[q];
    c.title = fmt::format("{} current, max |C2 − C1| {:.3g} A ({:.1f} % of C1's peak)", r.axis_names[q],
                          av.current_setpoint_max_diff_A, av.current_setpoint_max_rel_diff * 100);
    c.x_title = "t [s]";
    c.y_title = "current [A]";
    c.series.push_back(render::make_series("C1", rows.t, v.c1.current_setpoint_A.col(r.axes[q]).array(), 1, 1.4));
    c.series.push_back(render::make_series("C2", rows.t, v.c2.current_setpoint_A.col(r.axes[q]).array(), 0, 1.2));
    pic.charts.push_back(c);
  }
  return pic;
}

// Adds the pictures drawn to `images` (those drawn before a failure stay listed).
void draw_charts(const fs::path& dir, const core::Job& job, const sim::OgaJobResult& o, const Rows& rows,
                 std::pair<int, int> size, std::vector<std::string>& images) {
  const methods::OgaVerification& v = *o.verification;
  render::Window window;
  const fs::path idir = dir / "images";
  core::create_result_subdir(idir);
  const std::string title = fmt::format("{}: OGA (Duong et al.), MSE(CE) {:.3g} → {:.3g} µm² ({:+.1f} %)", job.name,
                                        v.mse_c1_um2, v.mse_c2_um2, o.change_percent);
  auto save = [&](const std::string& name, render::ChartPicture pic) {
    pic.caption[0] = title;
    pic.width = size.first, pic.height = size.second;
    render::write_png(idir / name, render::render_charts(window, pic).image);
    images.push_back("images/" + name);
  };
  save("gains.png", gains_picture(job.machine, o, rows));
  save("contour_error.png", contour_picture(v, rows));
  save("contour_error_histogram.png", histogram_picture(rows));
  save("currents.png", currents_picture(o, rows));
}

void print_summary(const core::Job& job, const sim::OgaJobResult& o, const fs::path& dir, bool images, double total_s) {
  const methods::OgaResult& r = o.result;
  const methods::OgaVerification& v = *o.verification;
  const std::size_t nq = r.axes.size();
  std::printf("job %s: %lld setpoints (%.3f s), axes %s and %s\n", job.name.c_str(),
              static_cast<long long>(o.interp.setpoints.samples()), o.interp.stats.cycle_time_s,
              r.axis_names[0].c_str(), r.axis_names[1].c_str());
  for (std::size_t q = 0; q < nq; ++q) {
    std::printf("admissible %s: %d of %zu configurations (limits: %s)\n", r.axis_names[q].c_str(),
                o.report["admissible"][r.axis_names[q]]["admissible"].get<int>(), r.sweep[q].size(),
                methods::limit_set_name(o.options.limits).c_str());
    if (o.report.contains("admissible_by_limit")) {
      const auto& b = o.report["admissible_by_limit"][r.axis_names[q]];
      const auto& d = b["drive_without_friction"];
      const auto& f = b["drive_with_friction"];
      std::printf(
          "  each limit alone: velocity %d, acceleration %d, jerk %d, current %d (drive without friction); "
          "with friction: velocity %d, acceleration %d, jerk %d; jerk of the setpoints %d\n",
          d["velocity"].get<int>(), d["acceleration"].get<int>(), d["jerk"].get<int>(), d["current"].get<int>(),
          f["velocity"].get<int>(), f["acceleration"].get<int>(), f["jerk"].get<int>(),
          b["setpoints"]["jerk"].get<int>());
    }
  }
  if (!r.best.empty())
    std::printf("best fixed pair: %s Kv %g KF %g, %s Kv %g KF %g (MSE(CE) %.4g um^2, %lld pairs)\n",
                r.axis_names[0].c_str(), r.best[0].kp, r.best[0].kf, r.axis_names[1].c_str(), r.best[1].kp,
                r.best[1].kf, r.best_mse_um2, static_cast<long long>(r.pairs_evaluated));
  std::printf("%zu windows, p = %d; ranges", r.windows.size(), r.sinusoid_samples);
  for (std::size_t q = 0; q < nq; ++q)
    std::printf(" %s [%g, %g]", r.axis_names[q].c_str(), r.range[q].first, r.range[q].second);
  std::printf("\n");
  std::printf("case  MSE(CE) um^2  max |CE| um\n");
  std::printf("C1    %10.4f  %10.3f\n", v.mse_c1_um2, v.max_c1_mm * 1e3);
  std::printf("C2    %10.4f  %10.3f   (%+.1f %%)\n", v.mse_c2_um2, v.max_c2_mm * 1e3, o.change_percent);
  for (std::size_t q = 0; q < nq; ++q)
    std::printf("%s current reference: max |C2 - C1| %.3g A = %.1f %% of C1's peak %.3g A\n", r.axis_names[q].c_str(),
                v.axes[q].current_setpoint_max_diff_A, v.axes[q].current_setpoint_max_rel_diff * 100,
                v.axes[q].current_setpoint_peak_c1_A);
  std::printf("limits held (velocity, acceleration, jerk, current): %s\n", v.limits_held ? "yes" : "NO");
  for (const std::string& a : v.advice) std::printf("  %s\n", a.c_str());
  if (o.windows_with_note > 0)
    std::printf("%d window(s) with every candidate of an axis breaking a limit: see windows.csv\n",
                o.windows_with_note);
  std::printf("wrote %s (gain_schedule.csv: [job] gain_schedule for vmsim run / motion)%s in %.1f s\n",
              dir.string().c_str(), images ? ", images/" : "", total_s);
}

}  // namespace

int run_oga(const OgaArgs& args) {
  const auto t_start = Clock::now();
  const sim::OgaJobOptions options = oga_options(args);
  if (args.threads) omp_set_num_threads(*args.threads);
  const std::pair<int, int> image_size = parse_image_size(args.image_size);
  const core::Job job = core::load_job(args.job);
  // Rank 0 writes: it locks the output directory now (core/output_dir.hpp), writes in staging, swaps at the end.
  std::optional<core::OutputDir> out;
  if (mpi_rank() == 0) out.emplace(out_dir_or_default(args.out_dir, job.name, "oga"), "vmsim oga");
  TerminalProgress progress(mpi_rank() == 0);
  const sim::OgaJobResult o = sim::oga_job(job, options, progress);
  if (!o.verification) return 0;  // another rank than 0 under mpirun: rank 0 writes

  const auto t_write0 = Clock::now();
  const fs::path dir = out->path();
  write_search_tables(dir, o.result, o.interp.setpoints.period_s);
  write_schedules(dir, job, o, args.reference);
  const Rows rows(o);
  write_comparison(dir, o, rows);
  const std::vector<std::string> files = {"admissible.csv", "gain_schedule.csv", "gain_schedule_c1.csv",
                                          "windows.csv",    "comparison.csv",    "mse_table.csv"};
  const double t_write = seconds_since(t_write0);

  // Charts after every result file: a failure to draw loses no result.
  std::vector<std::string> images;
  std::optional<std::string> render_error;
  double t_render = 0;
  if (!args.no_render) {
    const auto t0 = Clock::now();
    progress.stage(job.name + ": charts");
    try {
      draw_charts(dir, job, o, rows, image_size, images);
    } catch (const std::exception& e) {  // any failure (bad_alloc too): the report is written all the same
      render_error = e.what();
    }
    progress.done();
    t_render = seconds_since(t0);
  }

  nlohmann::json report = report_header("oga", job);
  report.update(o.report);
  report["files"] = files;
  report["images"] = images;
  if (render_error) report["render_error"] = *render_error;
  report["timings_s"] = o.timings;
  report["timings_s"]["write"] = t_write;
  if (!args.no_render) report["timings_s"]["render"] = t_render;
  report["timings_s"]["total"] = seconds_since(t_start);
  report["mpi_ranks"] =
      mpi_active() ? mpi_size() : 1;  // the pair search's processes (the result does not depend on it)
  write_report(dir / "report.json", report);
  out->commit();
  print_summary(job, o, out->target(), !images.empty(), seconds_since(t_start));
  const int verdict_code = print_verdict(report);
  if (render_error)
    throw core::Error("the results are written to " + out->target().string() +
                      ", but the charts could not be drawn (--no-render skips them): " + *render_error);
  return verdict_code;
}

}  // namespace vmsim::app
