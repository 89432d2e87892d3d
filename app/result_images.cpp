// The pictures of a result: the part (whole, and the deepest mark seen along the path), its deviation maps, and the
// charts of its drive signals. One headless window draws them all (its context and shaders are made once).
#include "app/result_images.hpp"
#include "core/units.hpp"

#include "app/report.hpp"

#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/x3p.hpp"
#include "render/chart.hpp"
#include "render/colormap.hpp"
#include "render/window.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <tuple>
#include <limits>

namespace vmsim::app {

namespace {

namespace fs = std::filesystem;
using core::units::kNaN;

// The largest of 1, 2, 5 x 10^k that is <= x.
double nice_floor(double x) {
  if (!(x > 0)) return 1;
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * p <= x * (1 + 1e-12)) return m * p;
  return p;
}

// Figures for captions: 4 significant digits, whole numbers up to 10^7 written out (10000, not 1e+04).
std::string num(double v) {
  if (std::abs(v) >= 1 && std::abs(v) < 1e7 && std::abs(v - std::round(v)) < 1e-9 * std::abs(v))
    return fmt::format("{:.0f}", v);
  return fmt::format("{:.4g}", v);
}
// Lengths in mm: at most 3 decimals (um), no exponent, no trailing zeros.
std::string mm(double v) {
  std::string t = fmt::format("{:.3f}", std::abs(v) < 5e-4 ? 0.0 : v);
  while (t.back() == '0') t.pop_back();
  if (t.back() == '.') t.pop_back();
  return t;
}

// ---- series from binned signals ----------------------------------------------------------------------------------

// Each bin's minimum and maximum, in that order, at the bin's mid x: a line through them draws the signal's envelope,
// which at chart resolution is the full-rate curve with every peak. One point per bin when bins hold one sample.
render::Series envelope(const sim::BinnedSignals& s, const std::string& xname, const std::string& yname, double yscale,
                        const std::string& label, int colour, double width = 1.6) {
  const int xi = s.find(xname), yi = s.find(yname);
  render::Series out;
  out.name = label;
  out.colour = render::series_colour(colour);
  out.width = width;
  if (xi < 0 || yi < 0) return out;
  const Eigen::Index nb = s.bins();
  const bool single = s.bin_samples == 1;
  out.x.resize(single ? nb : 2 * nb);
  out.y.resize(out.x.size());
  for (Eigen::Index b = 0; b < nb; ++b) {
    const double x = (s.min(b, xi) + s.max(b, xi)) / 2;
    if (single) {
      out.x[b] = x, out.y[b] = s.min(b, yi) * yscale;
    } else {
      out.x[2 * b] = out.x[2 * b + 1] = x;
      out.y[2 * b] = s.min(b, yi) * yscale;
      out.y[2 * b + 1] = s.max(b, yi) * yscale;
    }
  }
  return out;
}

bool has_data(const render::Series& s) { return (s.x.isFinite() && s.y.isFinite()).any(); }

double max_abs(const sim::BinnedSignals& s, const std::string& name) {
  const int i = s.find(name);
  if (i < 0) return kNaN;
  double m = 0;
  for (Eigen::Index b = 0; b < s.bins(); ++b)
    for (double v : {s.min(b, i), s.max(b, i)})
      if (std::isfinite(v)) m = std::max(m, std::abs(v));
  return m;
}

double range_of(const sim::BinnedSignals& s, const std::string& name) {
  const int i = s.find(name);
  if (i < 0) return 0;
  const Eigen::ArrayXd lo = s.min.col(i), hi = s.max.col(i);
  const double a = lo.isFinite().select(lo, std::numeric_limits<double>::max()).minCoeff();
  const double b = hi.isFinite().select(hi, -std::numeric_limits<double>::max()).maxCoeff();
  return b > a ? b - a : 0;
}

void add_limits(render::Chart& c, double limit, const std::string& unit) {
  c.levels.push_back({fmt::format("limit ±{} {}", num(limit), unit), limit});
  c.levels.push_back({"", -limit});
}

// ---- the pictures ----------------------------------------------------------------------------------------------

struct Writer {
  render::Window window;
  fs::path dir;
  std::vector<std::string> written;

  void save(const std::string& name, const render::Image& img) {
    render::write_png(dir / name, img);
    written.push_back(name);
  }
};

void part_pictures(Writer& w, const ResultData& d, const ImageOptions& o, double path_deg) {
  const core::HeightGrid& s = *d.surface;
  const render::Region bounds{s.x0_mm, s.x(s.nx() - 1), s.y0_mm, s.y(s.ny() - 1)};
  const double zmin = s.z_mm.isFinite().select(s.z_mm, std::numeric_limits<double>::max()).minCoeff();
  const double zmax = s.z_mm.isFinite().select(s.z_mm, -std::numeric_limits<double>::max()).maxCoeff();
  const std::string exag =
      o.vertical_exaggeration != 1.0 ? fmt::format("; z exaggerated x{}", num(o.vertical_exaggeration)) : "";
  const core::HeightGrid* dev = d.deviation ? &*d.deviation : nullptr;

  // Zoom: the asked region, or around the deepest mark.
  std::optional<render::Region> zoom = o.region;
  const metrology::Mark* mark = d.marks.empty() ? nullptr : &d.marks.front();
  if (!zoom && mark) {
    const double half = std::max(mark->x_extent_mm, mark->y_extent_mm) / 2 + 2.0;
    zoom = render::region_around(mark->x_mm, mark->y_mm, half, bounds, o.width, o.height);
  }
  std::string zoom_text;
  if (zoom)
    zoom_text = fmt::format("x {}..{} mm, y {}..{} mm", mm(zoom->x_min_mm), mm(zoom->x_max_mm), mm(zoom->y_min_mm),
                            mm(zoom->y_max_mm));

  render::PartPicture pic;
  pic.width = o.width, pic.height = o.height;
  pic.view.vertical_exaggeration = o.vertical_exaggeration;
  pic.view.path_direction_deg = path_deg;

  // 1. The whole part.
  pic.caption = {d.job + ": the predicted part",
                 fmt::format("x {}..{} mm, y {}..{} mm, z {}..{} mm; raking light from the left, {}° above the "
                             "part{}",
                             mm(bounds.x_min_mm), mm(bounds.x_max_mm), mm(bounds.y_min_mm), mm(bounds.y_max_mm),
                             mm(zmin), mm(zmax), num(pic.light.elevation_deg), exag)};
  w.save("part.png", render::render_part(w.window, s, dev, pic).image);

  // 1b. Which tool last cut where (several tools): the same view, each node its tool's colour.
  if (d.tool_index) {
    render::PartPicture t = pic;
    t.caption = {d.job + ": which tool cut where",
                 "each point coloured by the last tool that cut it; grey: uncut stock"};
    t.categories = render::CategoryColours{*d.tool_index, d.tool_names, "uncut stock", "last cut by"};
    w.save("tools.png", render::render_part(w.window, s, nullptr, t).image);
  }

  // 2. The deepest mark (or the asked region), seen along the path, its relief magnified.
  if (zoom) {
    render::PartPicture z = pic;
    z.view.direction = render::ViewDirection::AlongPath;
    z.view.region = zoom;
    double m = 1;
    if (dev && mark)
      m = o.mark_magnification > 0 ? o.mark_magnification : std::clamp(nice_floor(0.2 / mark->depth_mm), 1.0, 500.0);
    z.view.mark_magnification = dev ? m : 1.0;
    const bool at_mark = mark && !o.region;
    const std::string what = at_mark ? fmt::format("the deepest mark, {} {} µm", mark->overcut ? "overcut" : "undercut",
                                                   num(mark->depth_mm * 1e3))
                                     : "the region " + zoom_text;
    z.caption = {
        d.job + ": " + what,
        m != 1 ? fmt::format("seen along the path under a raking light; its departure from the reference "
                             "magnified x{} (the form true to scale){}",
                             num(m), exag)
               : "seen along the path under a raking light" + exag,
        at_mark ? fmt::format("deepest at x {} y {} mm, {} x {} mm deeper than half its depth; shown: {}",
                              mm(mark->x_mm), mm(mark->y_mm), mm(mark->x_extent_mm), mm(mark->y_extent_mm), zoom_text)
                : zoom_text};
    w.save("part_mark.png", render::render_part(w.window, s, dev, z).image);
  }

  if (!dev) return;
  // 3-5. Deviation: the whole map, the zoomed map, the zoomed part coloured under the light; one colour scale.
  const Eigen::ArrayXd vals = Eigen::Map<const Eigen::ArrayXd>(dev->z_mm.data(), dev->z_mm.size()) * 1e3;
  const double maxdev = vals.isFinite().select(vals.abs(), 0.0).maxCoeff();
  const double limit_um = o.limit_mm > 0
                              ? o.limit_mm * 1e3
                              : render::symmetric_limit(std::span<const double>(vals.data(), vals.size()), 1.0);
  render::DeviationColours colours;
  colours.limit_mm = limit_um / 1e3;
  colours.isolines = o.isolines;
  colours.lit = false;
  const std::string limit_text =
      o.limit_mm > 0
          ? fmt::format("colour limits ±{} µm (given); max |deviation| {} µm", num(limit_um), num(maxdev))
          : fmt::format("colour limits ±{} µm: max |deviation| {} µm rounded up", num(limit_um), num(maxdev));
  const std::string iso_text =
      o.isolines > 0 ? fmt::format("; iso-lines every {} µm", num(limit_um / (o.isolines + 1))) : "";
  render::PartPicture map = pic;
  map.view.direction = render::ViewDirection::Top;
  map.deviation = colours;
  const std::string what = d.deviation_along == "normal" ? "deviation from the reference along its normal"
                                                         : "vertical deviation from the reference";
  map.caption = {d.job + ": " + what + " (map, true scale)",
                 "reference: " + (d.reference.empty() ? std::string("see report.json") : d.reference),
                 limit_text + iso_text};
  w.save("deviation.png", render::render_part(w.window, s, dev, map).image);
  if (zoom) {
    map.view.region = zoom;
    map.caption[0] = d.job + ": " + what + " (map, true scale), zoom";
    map.caption[1] = zoom_text + "; reference: " + (d.reference.empty() ? std::string("see report.json") : d.reference);
    w.save("deviation_mark.png", render::render_part(w.window, s, dev, map).image);
  }
  render::PartPicture lit = pic;
  lit.view.direction = zoom ? render::ViewDirection::AlongPath : render::ViewDirection::Isometric;
  lit.view.region = zoom;
  lit.deviation = colours;
  lit.deviation->lit = true;
  lit.deviation->isolines = 0;
  lit.caption = {d.job + ": the part coloured by its " + what,
                 (zoom ? zoom_text + "; " : std::string()) + "under a raking light, true to scale" + exag, limit_text};
  w.save("deviation_3d.png", render::render_part(w.window, s, dev, lit).image);
}

// Contour error along the path; feed, programmed against reached.
void path_charts(Writer& w, const sim::BinnedSignals& s, const render::ChartPicture& base,
                 const std::string& decimation) {
  // Contour error along the path.
  {
    render::Chart c;
    c.title = "contour error on cutting moves";
    c.x_title = "distance along the cutting path [mm]";
    c.y_title = "contour error [µm]";
    c.series.push_back(envelope(s, "cutting_path_mm", "contour_error_mm", 1e3, "contour error", 0));
    c.legend = false;
    if (has_data(c.series[0])) {
      render::ChartPicture p = base;
      p.caption = {s.job + ": contour error along the path",
                   fmt::format("signed distance from the actual tool tip to the commanded path; max |e| {} µm{}",
                               num(max_abs(s, "contour_error_mm") * 1e3), decimation)};
      p.charts.push_back(c);
      w.save("contour_error.png", render::render_charts(w.window, p).image);
    }
  }
  // Feed: programmed against reached.
  {
    render::Chart c;
    c.title = "feed";
    c.x_title = "t [s]";
    c.y_title = "feed [mm/min]";
    c.series.push_back(envelope(s, "t_s", "feed_programmed_mm_per_min", 1, "programmed", 3, 2.4));
    c.series.push_back(envelope(s, "t_s", "path_speed_setpoint_mm_per_min", 1, "setpoints", 0));
    c.series.push_back(envelope(s, "t_s", "path_speed_actual_mm_per_min", 1, "actual", 1, 1.2));
    std::erase_if(c.series, [](const render::Series& x) { return !has_data(x); });
    if (!c.series.empty()) {
      render::ChartPicture p = base;
      p.caption = {s.job + ": programmed and actual feed",
                   "programmed: F x the feed scale, on cutting moves (gaps: rapids); setpoints: the interpolator's "
                   "path speed; actual: the speed of the drives' tool tip" +
                       decimation};
      p.charts.push_back(c);
      w.save("feed.png", render::render_charts(w.window, p).image);
    }
  }
}

// One axis: setpoint against actual position; velocity, acceleration, jerk against their limits.
void axis_charts(Writer& w, const sim::BinnedSignals& s, const render::ChartPicture& base,
                 const std::string& decimation, const std::string& A, const std::string& u) {
  const bool mm = u == "mm";
  const double es = 1e3;
  const std::string eu = mm ? "µm" : "mdeg";
  {
    render::ChartPicture p = base;
    p.caption = {s.job + ": axis " + A + ", setpoint and actual position",
                 "setpoint: the interpolator's command; actual: the drive model's position; tracking error = "
                 "setpoint - actual" +
                     decimation};
    render::Chart pos;
    pos.title = "position";
    pos.x_title = "t [s]";
    pos.y_title = A + " [" + u + "]";
    pos.series.push_back(envelope(s, "t_s", A + "_setpoint_" + u, 1, "setpoint", 0, 2.4));
    pos.series.push_back(envelope(s, "t_s", A + "_actual_" + u, 1, "actual", 1, 1.4));
    render::Chart err;
    err.title = "tracking error";
    err.x_title = "t [s]";
    err.y_title = "setpoint - actual [" + eu + "]";
    err.series.push_back(envelope(s, "t_s", A + "_tracking_error_" + u, es, "tracking error", 2));
    err.legend = false;
    p.charts = {pos, err};
    w.save("position_" + A + ".png", render::render_charts(w.window, p).image);
  }
  {
    render::ChartPicture p = base;
    std::vector<std::string> notes;
    const std::pair<const char*, const char*> q[3] = {{"velocity", "/s"}, {"acceleration", "/s²"}, {"jerk", "/s³"}};
    const char* suffix[3] = {"_per_s", "_per_s2", "_per_s3"};
    for (int k = 0; k < 3; ++k) {
      render::Chart c;
      c.title = q[k].first;
      c.x_title = "t [s]";
      c.y_title = std::string(q[k].first) + " [" + u + q[k].second + "]";
      const std::string sp = A + "_" + q[k].first + "_setpoint_" + u + suffix[k];
      const std::string ac = A + "_" + q[k].first + "_actual_" + u + suffix[k];
      c.series.push_back(envelope(s, "t_s", sp, 1, "setpoint", 0, 2.2));
      const auto lim = s.limit(A + "_" + q[k].first + "_" + u + suffix[k]);
      // The drives' jerk carries the current loop's ripple, orders of magnitude above the setpoints' limit: drawn
      // at that scale it would flatten the setpoint curve the limit applies to. Its peak is given instead.
      const double peak = max_abs(s, ac);
      if (lim && k == 2 && peak > 5 * *lim)
        notes.push_back(fmt::format("actual jerk not drawn (peak {} {}/s³, the current loop's ripple)", num(peak), u));
      else
        c.series.push_back(envelope(s, "t_s", ac, 1, "actual", 1, 1.2));
      if (lim) add_limits(c, *lim, u + q[k].second);
      p.charts.push_back(c);
    }
    std::string second =
        "setpoints: the interpolator's output by backward differences (the limits apply to them); "
        "actual: the drive model";
    p.caption = {s.job + ": axis " + A + ", velocity, acceleration and jerk against the machine's limits",
                 second + decimation};
    for (const auto& n : notes) p.caption.push_back(n);
    w.save("axis_" + A + ".png", render::render_charts(w.window, p).image);
  }
}

// Currents with their limits.
void current_charts(Writer& w, const sim::BinnedSignals& s, const render::ChartPicture& base,
                    const std::string& decimation) {
  render::ChartPicture p = base;
  p.caption = {s.job + ": motor currents",
               "mean over each position-loop period (signed) and the largest |current| within it; dashed: the drive's "
               "current limit" +
                   decimation};
  for (const auto& [A, u] : s.axes) {
    render::Chart c;
    c.title = "axis " + A;
    c.x_title = "t [s]";
    c.y_title = "current [A]";
    c.series.push_back(envelope(s, "t_s", A + "_current_A", 1, "mean per Te", 0, 1.8));
    c.series.push_back(envelope(s, "t_s", A + "_current_peak_A", 1, "peak |i| per Te", 1, 1.0));
    if (const auto lim = s.limit(A + "_current_A")) add_limits(c, *lim, "A");
    p.charts.push_back(c);
  }
  w.save("currents.png", render::render_charts(w.window, p).image);
}

void chart_pictures(Writer& w, const ResultData& d, const ImageOptions& o) {
  const sim::BinnedSignals& s = *d.signals;
  render::ChartPicture base;
  base.width = o.width, base.height = o.height;
  const std::string decimation =
      s.bin_samples > 1 ? fmt::format("; {} samples, drawn as min/max over bins of {}", s.samples, s.bin_samples)
                        : fmt::format("; {} samples", s.samples);

  path_charts(w, s, base, decimation);
  for (const auto& [A, u] : s.axes) axis_charts(w, s, base, decimation, A, u);
  if (!s.axes.empty()) current_charts(w, s, base, decimation);
}

}  // namespace

std::pair<int, int> parse_image_size(const std::string& text) {
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') || w < 16 || h < 16 ||
      w > 16384 || h > 16384)
    throw core::Error("image size \"" + text + "\": expected WIDTHxHEIGHT in pixels, each 16..16384 (e.g. 1600x1200)");
  return {w, h};
}

ImageOptions image_options(const ImageArgs& a) {
  ImageOptions o;
  std::tie(o.width, o.height) = parse_image_size(a.size);
  o.vertical_exaggeration = a.exaggeration;
  if (!a.region.empty()) {
    if (a.region.size() != 4 || !(a.region[1] > a.region[0]) || !(a.region[3] > a.region[2]))
      throw core::Error("--region: expected X_MIN,X_MAX,Y_MIN,Y_MAX in mm with X_MIN < X_MAX and Y_MIN < Y_MAX");
    o.region = render::Region{a.region[0], a.region[1], a.region[2], a.region[3]};
  }
  if (a.limit_um) o.limit_mm = *a.limit_um / 1e3;
  o.isolines = a.isolines;
  if (a.magnification) o.mark_magnification = *a.magnification;
  o.path_direction_deg = a.path_direction_deg;
  return o;
}

std::string tool_legend(const nlohmann::json& t) {
  return fmt::format("{} {} D{:g}", t.value("tool", std::string("?")), t.value("type", std::string("?")),
                     t.value("diameter_mm", 0.0));
}

ResultData load_results(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw core::Error(dir.string() + ": not a directory");
  ResultData d;
  d.job = fs::absolute(dir).lexically_normal().filename().string();
  // Only what the directory's report.json lists is this run's: a file an earlier run left there is not read, and a
  // listed file that is missing makes the directory incomplete.
  const nlohmann::json r = read_report(dir);
  if (r.contains("job") && r["job"].is_string()) d.job = r["job"].get<std::string>();
  if (r.contains("reference") && r["reference"].is_string()) d.reference = r["reference"].get<std::string>();
  const std::vector<std::string> listed = listed_files(r);
  auto take = [&](const std::string& name) {
    if (std::find(listed.begin(), listed.end(), name) == listed.end()) return false;
    if (!fs::is_regular_file(dir / name, ec))
      throw core::Error(fmt::format(
          "{}: report.json lists {}, which is missing: the result is incomplete (run it again)", dir.string(), name));
    return true;
  };
  // A large grid's run writes no CSV by default ([outputs] csv): its X3P files hold the same heights.
  if (take("surface.csv"))
    d.surface = metrology::read_height_csv(dir / "surface.csv");
  else if (take("surface.x3p"))
    d.surface = metrology::read_x3p(dir / "surface.x3p").grid;
  std::optional<core::HeightGrid> deviation;
  if (take("deviation.csv"))
    deviation = metrology::read_height_csv(dir / "deviation.csv");
  else if (take("deviation.x3p"))
    deviation = metrology::read_x3p(dir / "deviation.x3p").grid;
  if (deviation) {
    d.deviation = std::move(deviation);
    const nlohmann::json along = r.value("surface", nlohmann::json::object()).value("deviation_along", "vertical");
    d.deviation_along = along.is_string() ? along.get<std::string>() : "vertical";
    d.marks = metrology::find_marks(*d.deviation, 1e-3);  // as vmsim run: marks deeper than 1 um
  }
  // A run with several tools: which tool last cut each node (tools.png), the legend from report.json's tools.
  if (d.surface && take("tool_map.npy")) {
    const metrology::IndexGrid index = metrology::read_index_npy(dir / "tool_map.npy");
    if (index.rows() != d.surface->ny() || index.cols() != d.surface->nx())
      throw core::Error(fmt::format("{}: tool_map.npy is {} x {} nodes, the surface {} x {}", dir.string(),
                                    index.cols(), index.rows(), d.surface->nx(), d.surface->ny()));
    d.tool_index = index.cast<int>();
    for (const nlohmann::json& t : r.value("tools", nlohmann::json::object()).value("list", nlohmann::json::array()))
      d.tool_names.push_back(tool_legend(t));
    if (static_cast<int>(d.tool_names.size()) <= d.tool_index->maxCoeff())
      throw core::Error(dir.string() + ": tool_map.npy names a tool that report.json's tools.list does not have");
  }
  if (take("signals.csv")) d.signals = sim::read_signals(dir / "signals.csv");
  if (!d.surface && !d.deviation && !d.signals)
    throw core::Error(dir.string() +
                      ": nothing to render: its report.json lists no surface.csv, deviation.csv or "
                      "signals.csv (written by vmsim run and vmsim motion)");
  if (d.deviation && !d.surface)
    throw core::Error(dir.string() + ": deviation.csv without surface.csv: the maps are drawn on the surface");
  return d;
}

std::vector<std::string> write_result_images(const ResultData& d, const fs::path& image_dir, const ImageOptions& o) {
  if (o.isolines < 0 || o.isolines > 20) throw core::Error("--isolines must be in 0..20");
  core::create_result_subdir(image_dir);
  std::error_code ec;
  Writer w{render::Window(), image_dir, {}};
  double path_deg = 0;
  if (o.path_direction_deg) {
    path_deg = *o.path_direction_deg;
  } else if (d.signals) {
    // The passes run along the linear axis that travels furthest.
    path_deg = range_of(*d.signals, "Y_setpoint_mm") > range_of(*d.signals, "X_setpoint_mm") ? 90 : 0;
  }
  if (d.surface) part_pictures(w, d, o, path_deg);
  if (d.signals) chart_pictures(w, d, o);
  // Pictures of an earlier run into the same directory that this one did not draw (a mark that is gone, an axis
  // that no longer moves) would contradict its report: they go. Only names this function writes are touched.
  const auto ours = [](const std::string& n) {
    for (const char* p : {"part.png", "part_mark.png", "tools.png", "deviation.png", "deviation_mark.png",
                          "deviation_3d.png", "contour_error.png", "feed.png", "currents.png"})
      if (n == p) return true;
    // Per-axis charts: axis_<name>.png, position_<name>.png (axis names are one letter: X Y Z A B C).
    return n.size() <= 16 && n.ends_with(".png") && (n.starts_with("axis_") || n.starts_with("position_"));
  };
  for (const auto& e : fs::directory_iterator(image_dir, ec)) {
    const std::string n = e.path().filename().string();
    if (e.is_regular_file(ec) && ours(n) && std::find(w.written.begin(), w.written.end(), n) == w.written.end())
      fs::remove(e.path(), ec);
  }
  return w.written;
}

}  // namespace vmsim::app
