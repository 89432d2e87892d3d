// vmsim compare --measured SCAN --predicted PRED: a measured scan (confocal, STIL-style) held against the surface
// vmsim predicted. The scan is cleaned of spikes, registered to the prediction (robust 6-DoF, optionally on named
// reference faces only), resampled onto the prediction's grid; then the signed deviation (X3P), its statistics, the
// marks in it (depth, width across and length along the path), the areal parameters of both surfaces on their
// common area and their differences, profiles across the marks, report.json and the pictures.
#include "app/cmd_surface.hpp"
#include "app/commands.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/timing.hpp"
#include "core/stl.hpp"
#include "metrology/areal.hpp"
#include "metrology/filter.hpp"
#include "metrology/marks.hpp"
#include "metrology/mesh_distance.hpp"
#include "metrology/register.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"
#include "render/chart.hpp"
#include "render/scene.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace vmsim::app {

namespace {

using core::Clock;
using core::seconds_since;
constexpr double kPi = 3.14159265358979323846;

std::vector<metrology::Region> parse_regions(const std::vector<std::string>& texts) {
  std::vector<metrology::Region> out;
  for (const std::string& t : texts) {
    std::vector<double> v;
    std::stringstream ss(t);
    std::string cell;
    while (std::getline(ss, cell, ',')) v.push_back(parse_length_mm(cell, "--align-region"));
    if (v.size() != 4 || !(v[1] > v[0]) || !(v[3] > v[2]))
      throw core::Error("--align-region: expected XMIN,XMAX,YMIN,YMAX with XMIN < XMAX and YMIN < YMAX (mm), found \"" + t + "\"");
    out.push_back({v[0], v[1], v[2], v[3]});
  }
  return out;
}

nlohmann::json transform_json(const metrology::RigidTransform& T) {
  const Eigen::Vector3d rv = T.rotation_vector();
  // R = Rz Ry Rx: the angles that rebuild it (small for a fixtured part).
  const Eigen::Vector3d e = T.R.eulerAngles(2, 1, 0);
  double rz = e[0], ry = e[1], rx = e[2];
  if (std::abs(ry) > kPi / 2) rz -= std::copysign(kPi, rz), ry = std::copysign(kPi, ry) - ry, rx -= std::copysign(kPi, rx);
  nlohmann::json R = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) R.push_back({T.R(r, 0), T.R(r, 1), T.R(r, 2)});
  return {{"maps", "scan coordinates -> prediction coordinates: p' = R p + t"},
          {"R", R},
          {"t_mm", {T.t.x(), T.t.y(), T.t.z()}},
          {"rotation_vector_rad", {rv.x(), rv.y(), rv.z()}},
          {"angle_rad", rv.norm()},
          {"rx_ry_rz_rad", {rx, ry, rz}},
          {"convention", "R = Rz(rz) Ry(ry) Rx(rx)"}};
}

struct DeviationStats {
  std::size_t points = 0;
  double min = NAN, max = NAN, mean = NAN, rms = NAN, mean_abs = NAN;
};
DeviationStats stats_of(const core::HeightGrid& d) {
  DeviationStats s;
  double sum = 0, s2 = 0, sa = 0, lo = HUGE_VAL, hi = -HUGE_VAL;
  for (Eigen::Index k = 0; k < d.z_mm.size(); ++k) {
    const double v = d.z_mm.data()[k];
    if (!std::isfinite(v)) continue;
    ++s.points, sum += v, s2 += v * v, sa += std::abs(v), lo = std::min(lo, v), hi = std::max(hi, v);
  }
  if (s.points) {
    const double n = static_cast<double>(s.points);
    s.min = lo, s.max = hi, s.mean = sum / n, s.rms = std::sqrt(s2 / n), s.mean_abs = sa / n;
  }
  return s;
}

// What the pictures need; the surface and the deviation share one grid.
struct ComparePictures {
  const core::HeightGrid* surface = nullptr;
  const core::HeightGrid* deviation = nullptr;
  const core::HeightGrid* measured = nullptr;   // on the same grid (grid mode), for the profiles
  std::vector<metrology::Mark> marks;
  double path_direction_rad = 0;
  std::string what;                             // "measured - predicted, vertical" / "... along the normal"
  std::string measured_name, predicted_name;
};

// The pictures of a comparison through render/ (headless VTK): images/deviation_map.png (top view of the
// deviation, diverging colours in um) and images/profile_mark_<k>.png (measured and predicted heights and their
// deviation across the path through each of the three deepest marks). Returns the files written, or the reason
// none could be (no EGL context on this machine, say): pictures never fail a comparison.
nlohmann::json write_compare_pictures(const std::filesystem::path& dir, const ComparePictures& in) {
  nlohmann::json out = {{"files", nlohmann::json::array()}};
  try {
    std::filesystem::create_directories(dir / "images");
    render::Window window;
    render::PartPicture pic;
    pic.view.direction = render::ViewDirection::Top;
    render::DeviationColours dc;
    dc.lit = false;
    dc.isolines = 0;  // a measured deviation carries noise: iso-lines would only draw its speckle
    dc.reference = "the prediction (" + in.predicted_name + ")";
    pic.deviation = dc;
    pic.caption = {"Deviation of the measured scan from the prediction",
                   in.measured_name + " vs " + in.predicted_name + ": " + in.what};
    const render::PartImage map = render::render_part(window, *in.surface, in.deviation, pic);
    render::write_png(dir / "images" / "deviation_map.png", map.image);
    out["files"].push_back("images/deviation_map.png");
    out["deviation_map_limit_um"] = map.limit_mm * 1e3;
    const double across = in.path_direction_rad + kPi / 2;
    for (std::size_t k = 0; k < in.marks.size() && k < 3; ++k) {
      const metrology::Mark& m = in.marks[k];
      const double half = std::max({3 * m.width_mm, 30 * in.deviation->dx_mm, 0.2});
      const double step = std::min(in.deviation->dx_mm, in.deviation->dy_mm) / 2;
      const auto pd = metrology::profile(*in.deviation, m.x_mm, m.y_mm, across, half, step);
      render::ChartPicture cp;
      cp.caption = {fmt::format("Mark {}: {} {:.2f} um deep at x {:.3f} y {:.3f} mm", k + 1, m.overcut ? "overcut" : "undercut",
                                m.depth_mm * 1e3, m.x_mm, m.y_mm),
                    fmt::format("profile across the path ({:.1f} deg from +x)", across * 180 / kPi)};
      render::Chart heights;
      heights.title = "heights";
      heights.x_title = "across the path [mm]";
      heights.y_title = "z - z_pred(centre) [um]";
      if (in.measured) {
        const auto pm = metrology::profile(*in.measured, m.x_mm, m.y_mm, across, half, step);
        const auto pp = metrology::profile(*in.surface, m.x_mm, m.y_mm, across, half, step);
        const double z0 = pp.z_mm[pp.z_mm.size() / 2];
        heights.series.push_back({"predicted", pp.s_mm, (pp.z_mm - z0) * 1e3, render::series_colour(0)});
        heights.series.push_back({"measured", pm.s_mm, (pm.z_mm - z0) * 1e3, render::series_colour(1)});
        cp.charts.push_back(heights);
      }
      render::Chart dev;
      dev.title = "deviation";
      dev.x_title = "across the path [mm]";
      dev.y_title = "deviation [um]";
      dev.series.push_back({"measured - predicted", pd.s_mm, pd.z_mm * 1e3, render::series_colour(2)});
      dev.levels.push_back({"0", 0.0, {0.4, 0.4, 0.4}, true});
      cp.charts.push_back(dev);
      const render::ChartImage ci = render::render_charts(window, cp);
      const std::string name = fmt::format("images/profile_mark_{}.png", k + 1);
      render::write_png(dir / name, ci.image);
      out["files"].push_back(name);
    }
  } catch (const core::Error& e) {
    out["error"] = e.what();
    std::fprintf(stderr, "vmsim compare: no pictures: %s\n", e.what());
  }
  return out;
}

}  // namespace

int run_compare(const CompareArgs& a) {
  const auto t_start = Clock::now();
  nlohmann::json timings;
  const int level = parse_level(a.options.level);
  const auto filters = parse_filters(a.options.filters);
  const double threshold = parse_length_mm(a.mark_threshold, "--mark-threshold");
  const auto regions = parse_regions(a.align_regions);
  if (a.align != "auto" && a.align != "none") throw core::Error("--align: expected auto or none, found \"" + a.align + "\"");
  if (!a.align_init.empty() && a.align_init.size() != 6) throw core::Error("--align-init: expected X,Y,Z,RX,RY,RZ (mm, deg)");
  if (a.loss != "tukey" && a.loss != "huber") throw core::Error("--loss: expected tukey or huber, found \"" + a.loss + "\"");
  const std::filesystem::path dir = a.out_dir.value_or(std::filesystem::current_path());
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());

  // ---- inputs ----
  auto t0 = Clock::now();
  const metrology::SurfaceFile ms = metrology::read_surface_file(a.measured);
  if (!ms.note.empty()) std::fprintf(stderr, "vmsim compare: warning: %s: %s\n", a.measured.string().c_str(), ms.note.c_str());
  if (ms.profile) return run_compare_profile(a, ms);
  if (!a.profile_line.empty()) throw core::Error("--profile-line: applies to a measured profile; " + a.measured.string() + " holds a surface");
  core::HeightGrid scan = ms.grid;
  std::string ext = a.predicted.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool mesh_mode = ext == ".stl";
  core::TriangleMesh mesh;
  core::HeightGrid pred;
  std::string pred_format;
  if (mesh_mode) {
    mesh = core::read_stl(a.predicted);
    // A grid of the mesh's top at the scan's step, for registration; the deviation is taken to the mesh itself.
    pred = metrology::rasterize_top(mesh, std::min(scan.dx_mm, scan.dy_mm));
    pred_format = "stl";
  } else {
    const metrology::SurfaceFile ps = metrology::read_surface_file(a.predicted);
    pred = ps.grid;
    pred_format = ps.format;
  }
  timings["read"] = seconds_since(t0);
  nlohmann::json report = {{"vmsim", VMSIM_VERSION}, {"command", "compare"}};
  report["inputs"] = {{"measured", input_json(a.measured, ms.format)}, {"predicted", input_json(a.predicted, pred_format)}};
  report["measured"] = {{"grid", grid_json(scan)}};
  if (!ms.note.empty()) report["measured"]["note"] = ms.note;
  report["predicted"] = {{"grid", grid_json(pred)}};
  if (mesh_mode) report["predicted"]["mesh_triangles"] = mesh.triangles.rows();

  // ---- spikes: masked, counted, never zeroed ----
  t0 = Clock::now();
  if (a.options.outlier_sigma > 0) {
    metrology::OutlierOptions oo;
    oo.k_sigma = a.options.outlier_sigma;
    const auto r = metrology::mask_outliers(scan, oo);
    report["measured"]["outliers"] = {{"masked", r.masked}, {"k_sigma", oo.k_sigma}, {"sigma_mm", r.sigma_mm},
                                      {"threshold_mm", r.threshold_mm}, {"method", "median of plane-exact neighbour predictions"}};
  }
  timings["outliers"] = seconds_since(t0);

  // ---- registration ----
  t0 = Clock::now();
  metrology::RigidTransform T;
  if (!a.align_init.empty()) {
    const double d = kPi / 180;
    T = metrology::RigidTransform::from_xyz_rxyz(a.align_init[0], a.align_init[1], a.align_init[2], a.align_init[3] * d,
                                                 a.align_init[4] * d, a.align_init[5] * d);
  }
  nlohmann::json reg;
  if (a.align == "none") {
    reg = {{"method", a.align_init.empty() ? "none: the scan as it lies" : "none: the transform given by --align-init"}};
  } else {
    metrology::RegistrationOptions ro;
    ro.loss = a.loss == "huber" ? metrology::RobustLoss::Huber : metrology::RobustLoss::Tukey;
    ro.tuning = a.loss == "huber" ? 1.345 : 4.685;
    ro.regions = regions;
    if (!a.align_init.empty()) ro.initial = T;
    const metrology::RegistrationResult r = metrology::register_scan(scan, pred, ro);
    T = r.transform;
    nlohmann::json reg_regions = nlohmann::json::array();
    for (const auto& R : regions) reg_regions.push_back({R.x_min, R.x_max, R.y_min, R.y_max});
    reg = {{"method", "robust Gauss-Newton, point to surface (normal distance), 6 DoF, coarse to fine"},
           {"loss", a.loss == "huber" ? "Huber k = 1.345 sigma" : "Tukey c = 4.685 sigma (after Huber)"},
           {"regions_mm", reg_regions},
           {"initial_guess", r.initial_guess},
           {"points", r.points},
           {"inliers", r.inliers},
           {"iterations", r.iterations},
           {"converged", r.converged},
           {"residual_rms_mm", r.rms_mm},
           {"residual_mean_mm", r.mean_mm},
           {"residual_robust_sigma_mm", r.robust_sigma_mm},
           {"weakly_constrained", r.weak_directions}};
    if (!r.weak_directions.empty())
      std::fprintf(stderr, "vmsim compare: the surfaces do not constrain %zu direction(s) of the alignment; held at the "
                           "initial guess (see report.json registration.weakly_constrained)\n",
                   r.weak_directions.size());
  }
  reg["transform"] = transform_json(T);
  report["registration"] = reg;
  timings["registration"] = seconds_since(t0);

  // ---- deviation ----
  t0 = Clock::now();
  const core::HeightGrid measured_on = metrology::resample_scan(scan, T, pred);  // the scan on the prediction's grid
  core::HeightGrid dev;
  std::string what;
  if (mesh_mode) {
    dev = metrology::mesh_deviation(scan, T, mesh);
    what = "signed distance along the mesh normal (positive outside the part), on the scan's grid, scan frame";
  } else {
    dev = metrology::deviation(measured_on, pred);
    what = "measured - predicted, vertical, on the prediction's grid (negative: overcut)";
  }
  const DeviationStats ds = stats_of(dev);
  if (ds.points == 0) throw core::Error("compare: the aligned scan and the prediction do not overlap anywhere");
  report["deviation"] = {{"definition", what}, {"points", ds.points}, {"min_mm", ds.min}, {"max_mm", ds.max},
                         {"mean_mm", ds.mean}, {"rms_mm", ds.rms}, {"mean_abs_mm", ds.mean_abs}};
  timings["deviation"] = seconds_since(t0);

  // ---- marks ----
  t0 = Clock::now();
  double path_dir = 0;
  std::string path_from;
  if (a.path_direction_deg) {
    path_dir = *a.path_direction_deg * kPi / 180;
    path_from = "given (--path-direction-deg)";
  } else {
    const metrology::Lay lay = metrology::lay_of(pred);
    path_dir = lay.direction_rad;
    path_from = fmt::format("the lay of the prediction (anisotropy {:.2f})", lay.anisotropy);
    if (lay.anisotropy < 0.2) path_dir = 0, path_from = "+x (the prediction has no clear lay; give --path-direction-deg)";
  }
  // Regions of fewer than 9 nodes (3 x 3) are the scan's noise crossing the threshold, not marks.
  std::vector<metrology::Mark> marks = metrology::find_marks(dev, threshold, 10, path_dir, 9);
  nlohmann::json mj = nlohmann::json::array();
  for (const metrology::Mark& m : marks) {
    nlohmann::json j = {{"depth_mm", m.depth_mm},      {"kind", m.overcut ? "overcut" : "undercut"},
                        {"x_mm", m.x_mm},              {"y_mm", m.y_mm},
                        {"width_mm", m.width_mm},      {"along_path_mm", m.along_mm},
                        {"x_extent_mm", m.x_extent_mm}, {"y_extent_mm", m.y_extent_mm},
                        {"area_mm2", m.area_mm2}};
    if (mesh_mode) {  // scan-frame position carried into the part frame
      double z = 0;
      metrology::sample_bilinear(scan, m.x_mm, m.y_mm, z);
      const Eigen::Vector3d p = T.apply({m.x_mm, m.y_mm, z});
      j["part_x_mm"] = p.x(), j["part_y_mm"] = p.y();
    }
    mj.push_back(j);
  }
  report["marks"] = {{"threshold_mm", threshold}, {"path_direction_deg", path_dir * 180 / kPi}, {"path_direction_from", path_from},
                     {"min_nodes", 9}, {"width", "full width of the part deeper than half the depth, across the path"},
                     {"list", mj}};
  // Profiles across the marks (CSV: mark, s, measured, predicted, deviation), in the deviation's frame.
  {
    std::string csv = "mark,s_mm,measured_mm,predicted_mm,deviation_mm\n";
    for (std::size_t k = 0; k < marks.size() && k < 3; ++k) {
      const metrology::Mark& m = marks[k];
      const double half = std::max({3 * m.width_mm, 30 * dev.dx_mm, 0.2}), step = std::min(dev.dx_mm, dev.dy_mm) / 2;
      const auto pd = metrology::profile(dev, m.x_mm, m.y_mm, path_dir + kPi / 2, half, step);
      const auto pm = metrology::profile(mesh_mode ? scan : measured_on, m.x_mm, m.y_mm, path_dir + kPi / 2, half, step);
      const auto pp = mesh_mode ? pd : metrology::profile(pred, m.x_mm, m.y_mm, path_dir + kPi / 2, half, step);
      for (Eigen::Index i = 0; i < pd.s_mm.size(); ++i)
        csv += fmt::format("{},{},{},{},{}\n", k + 1, pd.s_mm[i], pm.z_mm[i], mesh_mode ? NAN : pp.z_mm[i], pd.z_mm[i]);
    }
    core::write_file_atomic(dir / "profiles.csv", csv);
  }
  timings["marks"] = seconds_since(t0);

  // ---- areal parameters of both surfaces on their common area ----
  t0 = Clock::now();
  core::HeightGrid mc = measured_on, pc = pred;
  for (Eigen::Index k = 0; k < mc.z_mm.size(); ++k)
    if (!std::isfinite(mc.z_mm.data()[k]) || !std::isfinite(pc.z_mm.data()[k]))
      mc.z_mm.data()[k] = pc.z_mm.data()[k] = NAN;
  nlohmann::json proc_m, proc_p;
  const auto am = metrology::areal_parameters(level_and_filter(mc, level, filters, proc_m));
  const auto ap = metrology::areal_parameters(level_and_filter(pc, level, filters, proc_p));
  nlohmann::json diff;
  const nlohmann::json jm = areal_json(am), jp = areal_json(ap);
  for (const auto& [k, v] : jm.items())
    if (k != "points" && v.is_number() && jp[k].is_number()) diff[k] = v.get<double>() - jp[k].get<double>();
  report["areal"] = {{"area", "nodes where both the aligned scan and the prediction are valid"},
                     {"processing", proc_m},
                     {"measured", jm},
                     {"predicted", jp},
                     {"measured_minus_predicted", diff}};
  timings["areal"] = seconds_since(t0);

  // ---- files ----
  t0 = Clock::now();
  std::vector<std::string> files = {"profiles.csv"};
  metrology::X3pWriteOptions xo;
  xo.version = std::string("vmsim ") + VMSIM_VERSION;
  xo.comment = "deviation: " + what + "; measured " + a.measured.filename().string() + ", predicted " + a.predicted.filename().string();
  metrology::write_x3p(dir / "deviation.x3p", dev, xo);
  files.push_back("deviation.x3p");
  xo.comment = "the measured scan " + a.measured.filename().string() + " aligned and resampled onto the prediction's grid";
  xo.probing_type = "NonContacting";
  metrology::write_x3p(dir / "measured_aligned.x3p", measured_on, xo);
  files.push_back("measured_aligned.x3p");
  timings["write"] = seconds_since(t0);

  if (!a.no_render) {
    t0 = Clock::now();
    ComparePictures cp;
    cp.surface = mesh_mode ? &scan : &pred;
    cp.deviation = &dev;
    cp.measured = mesh_mode ? nullptr : &measured_on;
    cp.marks = marks;
    cp.path_direction_rad = path_dir;
    cp.what = mesh_mode ? "distance along the mesh normal" : "vertical, measured - predicted";
    cp.measured_name = a.measured.filename().string();
    cp.predicted_name = a.predicted.filename().string();
    const nlohmann::json pics = write_compare_pictures(dir, cp);
    report["pictures"] = pics;
    for (const auto& f : pics["files"]) files.push_back(f.get<std::string>());
    timings["pictures"] = seconds_since(t0);
  }
  timings["total"] = seconds_since(t_start);
  report["timings_s"] = timings;
  files.push_back("report.json");
  report["files"] = files;
  write_report(dir / "report.json", report);

  // ---- summary ----
  const Eigen::Vector3d rv = T.rotation_vector();
  std::printf("measured %s (%s, %ld x %ld), predicted %s (%s)\n", a.measured.filename().string().c_str(), ms.format.c_str(),
              static_cast<long>(ms.grid.nx()), static_cast<long>(ms.grid.ny()), a.predicted.filename().string().c_str(), pred_format.c_str());
  if (report["measured"].contains("outliers"))
    std::printf("spikes masked: %zu\n", report["measured"]["outliers"]["masked"].get<std::size_t>());
  if (a.align == "auto")
    std::printf("registration: t = (%.4f, %.4f, %.4f) mm, rotation %.3g rad; residual rms %.3f um on %zu points%s\n", T.t.x(),
                T.t.y(), T.t.z(), rv.norm(), reg["residual_rms_mm"].get<double>() * 1e3, reg["inliers"].get<std::size_t>(),
                reg["converged"].get<bool>() ? "" : " (not converged)");
  std::printf("deviation: mean %.2f um, rms %.2f um, min %.2f um, max %.2f um over %zu points\n", ds.mean * 1e3, ds.rms * 1e3,
              ds.min * 1e3, ds.max * 1e3, ds.points);
  for (std::size_t k = 0; k < marks.size() && k < 5; ++k)
    std::printf("mark %zu: %s %.2f um at x %.3f y %.3f, %.3f mm wide, %.3f mm along the path\n", k + 1,
                marks[k].overcut ? "overcut " : "undercut", marks[k].depth_mm * 1e3, marks[k].x_mm, marks[k].y_mm,
                marks[k].width_mm, marks[k].along_mm);
  std::printf("Sa measured %.3f um, predicted %.3f um; Sq %.3f / %.3f um\n", am.Sa_mm * 1e3, ap.Sa_mm * 1e3, am.Sq_mm * 1e3,
              ap.Sq_mm * 1e3);
  std::printf("wrote %s (%zu files) in %.1f s\n", dir.string().c_str(), files.size(), seconds_since(t_start));
  return 0;
}

}  // namespace vmsim::app
