// vmsim plan-feed JOB: Chen et al.'s contour-error-constrained feed plan (sim/plan_feed.hpp), played by the job's chain
// under the plan's feed ceiling, against the same path without a plan and with a plan that leaves the contour error
// out. Writes the plan for `[job] feed_plan` (feed_plan.csv), the feed profile (CSV), the played motion (CSV),
// report.json and charts (feed; axis velocity and acceleration with their limits; chord and contour error with their
// tolerances).
#include "app/commands.hpp"
#include "app/progress.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/job.hpp"
#include "core/timing.hpp"
#include "methods/feedplan_file.hpp"
#include "render/chart.hpp"
#include "render/window.hpp"
#include "sim/plan_feed.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <optional>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace vmsim::app {

namespace {

namespace fs = std::filesystem;
using core::Clock;
using core::seconds_since;
using Index = Eigen::Index;

std::string csv_number(double v, int digits) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (std::isnan(v)) return "nan";
  return fmt::format("{:.{}f}", v, digits);
}

Eigen::ArrayXd finite_or_nan(const Eigen::ArrayXd& a, double cap) {
  return a.isFinite().select(a.min(cap), std::numeric_limits<double>::quiet_NaN());
}

// The played plan's setpoints: X Y Z positions and their backward differences (at rest before the first sample).
struct PlayedAxes {
  const core::Setpoints& sp;
  double te;
  std::vector<Index> cols;  // machine columns of X Y Z (-1: the machine lacks it)
  PlayedAxes(const core::Setpoints& s, const core::Machine& machine) : sp(s), te(s.period_s) {
    for (int r = 0; r < 3; ++r) cols.push_back(machine.axis_index(r));
  }
  double pos(Index k, int r) const {
    const Index c = cols[static_cast<std::size_t>(r)];
    return c < 0 ? 0.0 : sp.position(std::clamp<Index>(k, 0, sp.samples() - 1), c);
  }
  double fd(Index k, int r, int order) const {
    if (cols[static_cast<std::size_t>(r)] < 0) return 0.0;
    return order == 1 ? (pos(k, r) - pos(k - 1, r)) / te : (pos(k, r) - 2 * pos(k - 1, r) + pos(k - 2, r)) / (te * te);
  }
};

void write_feed_profile(const fs::path& file, const sim::PlanFeedResult& r) {
  const methods::PathSamples& samples = r.samples;
  const methods::FeedPlan& plan = r.verified.plan;
  core::AtomicFile f(file);
  auto& o = f.stream();
  o << "# vmsim plan-feed: Chen et al.'s feed plan per sample (arc length s); feeds in mm/s, bounds: eq. 13 (contour), "
       "15 (chord), 22 (axis velocity), 23 without tangential part (centripetal), 24 (f_star = the smallest with "
       "f_max); feed_without_contour: the same plan without eq. 13; contour_scale: the factor on the tolerance the "
       "verified plan used; simulated errors: the largest contour error of the simulated axes whose foot point lies "
       "at the sample\n";
  o << "s_mm,u,x_mm,y_mm,z_mm,curvature_per_mm,f_star,bound_contour,bound_chord,bound_axis_velocity,bound_centripetal,"
       "omega0_rad_s,feed_without_contour,feed,contour_scale,sim_contour_error_no_plan_um,"
       "sim_contour_error_without_contour_um,sim_contour_error_um\n";
  std::string line;
  for (Index i = 0; i < samples.size(); ++i) {
    line = fmt::format(
        "{:.6f},{},{:.6f},{:.6f},{:.6f},{:.6g},{},{},{},{},{},{},{:.6f},{:.6f},{:.6f},{:.4f},{:.4f},{:.4f}\n",
        samples.s[i], csv_number(samples.u[i], 9), samples.p(i, 0), samples.p(i, 1), samples.p(i, 2),
        samples.kappa_max[i], csv_number(plan.f_star[i], 6), csv_number(plan.bound_contour[i], 6),
        csv_number(plan.bound_chord[i], 6), csv_number(plan.bound_axis_velocity[i], 6),
        csv_number(plan.bound_centripetal[i], 6), csv_number(plan.omega0[i], 6), r.free_plan.feed[i], plan.feed[i],
        r.verified.contour_scale[i], r.no_plan.per_sample[i] * 1e3, r.free_played.per_sample[i] * 1e3,
        r.verified.played.per_sample[i] * 1e3);
    o << line;
  }
  f.commit();
}

// The played motion of the plan: setpoints, their finite-difference axis velocity and acceleration, chord error,
// and the simulated contour error at the same instant.
void write_motion(const fs::path& file, const sim::PlanFeedResult& r, const PlayedAxes& ax) {
  const methods::PlayedPlan& played = r.verified.played;
  const core::Setpoints& sp = ax.sp;
  core::AtomicFile f(file);
  auto& o = f.stream();
  o << "t_s,s_mm,feed_mm_per_s,ceiling_mm_per_s,x_mm,y_mm,z_mm,vx_mm_per_s,vy_mm_per_s,vz_mm_per_s,ax_mm_per_s2,"
       "ay_mm_per_s2,az_mm_per_s2,chord_error_um,contour_error_um\n";
  for (Index k = 0; k < sp.samples(); ++k)
    o << fmt::format(
        "{:.4f},{:.6f},{:.5f},{:.5f},{:.6f},{:.6f},{:.6f},{:.5f},{:.5f},{:.5f},{:.4f},{:.4f},{:.4f},{:.5f},{:.5f}\n",
        k * ax.te, sp.path_length_mm[k], sp.path_speed_mm_per_s[k], r.ceiling.at(sp.path_length_mm[k]), ax.pos(k, 0),
        ax.pos(k, 1), ax.pos(k, 2), ax.fd(k, 0, 1), ax.fd(k, 1, 1), ax.fd(k, 2, 1), ax.fd(k, 0, 2), ax.fd(k, 1, 2),
        ax.fd(k, 2, 2), played.chord_error_mm[k] * 1e3, played.contour.signed_mm[k] * 1e3);
  f.commit();
}

render::ChartPicture feed_picture(const sim::PlanFeedResult& r) {
  const double fmax = r.max_feed_mm_per_s;
  const methods::FeedPlan& plan = r.verified.plan;
  render::ChartPicture pic;
  pic.caption = {"",
                 "feed along the path: eq. 24's bound f*, the plan without and with the contour-error "
                 "constraint, and the interpolator's feed playing the plan"};
  render::Chart c;
  c.title = "feed";
  c.x_title = "s [mm]";
  c.y_title = "feed [mm/s]";
  const Eigen::ArrayXd& s = r.samples.s;
  c.series.push_back(render::make_series("f* (eq. 24)", s, finite_or_nan(plan.f_star, 2 * fmax), 7, 1.2, true));
  c.series.push_back(render::make_series("plan without contour error", s, r.free_plan.feed, 1));
  c.series.push_back(render::make_series("plan", s, plan.feed, 0, 2.0));
  c.series.push_back(render::make_series("interpolated (plan)", r.played_sample_s,
                                         r.verified.played.interp.setpoints.path_speed_mm_per_s, 2, 1.2));
  c.levels.push_back({fmt::format("f_max {} mm/s", fmax), fmax});
  c.y_range = std::pair<double, double>{0.0, fmax * 1.1};
  pic.charts.push_back(c);
  return pic;
}

render::ChartPicture axes_picture(const sim::PlanFeedResult& r, const PlayedAxes& ax) {
  render::ChartPicture pic;
  pic.caption = {"",
                 "axis velocity and acceleration of the interpolated plan (finite differences of the setpoints), "
                 "with the machine's limits"};
  const Index ns = ax.sp.samples();
  for (int order = 1; order <= 2; ++order) {
    render::Chart c;
    c.title = order == 1 ? "axis velocity" : "axis acceleration";
    c.x_title = "s [mm]";
    c.y_title = order == 1 ? "velocity [mm/s]" : "acceleration [mm/s²]";
    int colour = 0;
    double limit = 0.0;
    for (int a = 0; a < 3; ++a) {
      if (!(r.moving[a] > 0) || ax.cols[static_cast<std::size_t>(a)] < 0) continue;
      Eigen::ArrayXd y(ns);
      for (Index k = 0; k < ns; ++k) y[k] = ax.fd(k, a, order);
      c.series.push_back(render::make_series(std::string(1, "XYZ"[a]), r.played_sample_s, y, colour++));
      limit = std::max(limit, order == 1 ? r.limits.axis_velocity[a] : r.limits.axis_acceleration[a]);
    }
    c.levels.push_back({fmt::format("limit ±{:g} {}", limit, order == 1 ? "mm/s" : "mm/s²"), limit});
    c.levels.push_back({"", -limit});
    pic.charts.push_back(c);
  }
  return pic;
}

render::ChartPicture errors_picture(const sim::PlanFeedResult& r, const core::FeedPlanSpec& spec) {
  const methods::PlayedPlan& played = r.verified.played;
  render::ChartPicture pic;
  pic.caption = {"",
                 "chord error of the interpolated plan, and the simulated contour error: no plan (the programmed "
                 "feed), the plan without and with the contour-error constraint"};
  render::Chart ch;
  ch.title = "chord error";
  ch.x_title = "s [mm]";
  ch.y_title = "chord error [µm]";
  ch.series.push_back(render::make_series("plan", r.played_sample_s, played.chord_error_mm * 1e3, 0));
  ch.levels.push_back({fmt::format("limit {:g} µm", spec.chord_error_mm * 1e3), spec.chord_error_mm * 1e3});
  pic.charts.push_back(ch);
  render::Chart ce;
  ce.title = "contour error (simulated)";
  ce.x_title = "s [mm]";
  ce.y_title = "contour error [µm]";
  ce.series.push_back(render::make_series("no plan", r.no_plan.sample_s, r.no_plan.contour.signed_mm * 1e3, 7, 1.0));
  ce.series.push_back(render::make_series("plan without contour error", r.free_played.sample_s,
                                          r.free_played.contour.signed_mm * 1e3, 1, 1.2));
  ce.series.push_back(render::make_series("plan", played.sample_s, played.contour.signed_mm * 1e3, 0, 1.6));
  ce.levels.push_back({fmt::format("tolerance ±{:g} µm", spec.contour_error_mm * 1e3), spec.contour_error_mm * 1e3});
  ce.levels.push_back({"", -spec.contour_error_mm * 1e3});
  pic.charts.push_back(ce);
  return pic;
}

// Chen et al. 2016 Fig. 3 b-f, against the arc length.
std::vector<std::string> draw_charts(const fs::path& dir, const core::Job& job, const sim::PlanFeedResult& r,
                                     const PlayedAxes& ax) {
  const core::FeedPlanSpec& spec = *job.feedplan;
  render::Window window;
  const fs::path idir = dir / "images";
  core::create_result_subdir(idir);
  const std::string title =
      job.name + fmt::format(": T {} ms, chord {} µm, contour {} µm, f_max {} mm/s", ax.te * 1e3,
                             spec.chord_error_mm * 1e3, spec.contour_error_mm * 1e3, r.max_feed_mm_per_s);
  std::vector<std::string> images;
  auto save = [&](const std::string& name, render::ChartPicture pic) {
    pic.caption[0] = title;
    pic.width = 1600, pic.height = 900;
    render::write_png(idir / name, render::render_charts(window, pic).image);
    images.push_back("images/" + name);
  };
  save("feed.png", feed_picture(r));
  save("axes.png", axes_picture(r, ax));
  save("errors.png", errors_picture(r, spec));
  return images;
}

void print_summary(const core::Job& job, const sim::PlanFeedResult& r, const fs::path& dir, bool images) {
  const core::FeedPlanSpec& spec = *job.feedplan;
  const methods::FeedPlan& plan = r.verified.plan;
  const methods::PlayedPlan& played = r.verified.played;
  const auto& st = plan.stats;
  const double length = r.samples.s[r.samples.size() - 1];
  std::printf("job %s: %s path, %.3f mm, %lld samples of %.4f mm; servo w_n %.2f rad/s\n", job.name.c_str(),
              spec.nurbs ? "NURBS" : "program", length, static_cast<long long>(r.samples.size()), r.samples.ds,
              r.natural_frequency_rad_s);
  std::printf(
      "LP: %lld variables, %lld rows per window (max), %d windows, %d Clp solves (%d jerk linearisations max), "
      "%.3f s in Clp, plan %.3f s\n",
      static_cast<long long>(st.lp_columns_max), static_cast<long long>(st.lp_rows_max), st.windows, st.lp_solves,
      st.jerk_iterations_max, st.lp_seconds, st.total_seconds);
  std::printf("                              cycle time   plan time   contour error max (simulated / model)\n");
  std::printf("no plan (programmed feed)      %8.3f s                %7.2f um\n", r.no_plan.interp.stats.cycle_time_s,
              r.no_plan.max_abs_mm * 1e3);
  std::printf("plan without contour error     %8.3f s  %8.3f s    %7.2f / %.2f um\n",
              r.free_played.interp.stats.cycle_time_s, r.free_plan.time_s, r.free_played.max_abs_mm * 1e3,
              r.model_peak_free_mm * 1e3);
  std::printf("plan (contour error <= %g um)  %8.3f s  %8.3f s    %7.2f / %.2f um  (%d round%s)\n",
              spec.contour_error_mm * 1e3, played.interp.stats.cycle_time_s, plan.time_s, played.max_abs_mm * 1e3,
              r.model_peak_mm * 1e3, r.verified.rounds, r.verified.rounds == 1 ? "" : "s");
  std::printf(
      "cycle-time cost of the contour constraint: %+.1f %%; every constraint at every sample: worst %.6f of its "
      "limit\n",
      r.report["cycle_time_cost_of_contour_constraint"].get<double>() * 100, r.check.worst());
  std::printf("wrote %s (report.json, feed_plan.csv, feed_profile.csv, motion.csv%s)\n", dir.string().c_str(),
              images ? ", images/" : "");
  if (played.max_abs_mm > spec.contour_error_mm)
    std::printf("NOTE: the simulated contour error of the plan exceeds the tolerance (%s)\n",
                spec.verify ? "the verification rounds did not bring it within: see report.json"
                            : "[feedplan] verify = false: Chen et al.'s model alone");
}

}  // namespace

int run_plan_feed(const PlanFeedArgs& args) {
  const auto t_start = Clock::now();
  const core::Job job = core::load_job(args.job);
  // Locked before the run, written in staging, swapped into place whole (core/output_dir.hpp).
  core::OutputDir out(out_dir_or_default(args.out_dir, job.name, "plan_feed"), "vmsim plan-feed");
  TerminalProgress progress;
  const sim::PlanFeedResult r = sim::plan_feed(job, progress);

  const auto t0 = Clock::now();
  const fs::path dir = out.path();
  std::vector<std::string> files = {"feed_plan.csv", "feed_profile.csv", "motion.csv"};
  // The plan as `[job] feed_plan` takes it: as the interpolator played it (a profile to follow, or a ceiling).
  methods::write_feed_plan(dir / "feed_plan.csv", r.ceiling, r.path, job.interp.period_s, job.name,
                           {fmt::format("contour error {:g} um, chord error {:g} um, f_max {:g} mm/s; {} round(s)",
                                        job.feedplan->contour_error_mm * 1e3, job.feedplan->chord_error_mm * 1e3,
                                        r.max_feed_mm_per_s, r.verified.rounds)});
  write_feed_profile(dir / "feed_profile.csv", r);
  const PlayedAxes axes(r.verified.played.interp.setpoints, job.machine);
  write_motion(dir / "motion.csv", r, axes);
  std::vector<std::string> images;
  std::optional<std::string> render_error;
  if (!args.no_render) {
    try {
      images = draw_charts(dir, job, r, axes);
    } catch (const std::exception& e) {  // any failure (bad_alloc too): the results and the report are written
      render_error = e.what();
    }
  }
  const double t_write = seconds_since(t0);

  nlohmann::json report = report_header("plan-feed", job);
  report.update(r.report);
  report["files"] = files;
  report["images"] = images;
  if (render_error) report["render_error"] = *render_error;
  report["timings_s"] = r.timings;
  report["timings_s"]["write"] = t_write;
  report["timings_s"]["total"] = seconds_since(t_start);
  write_report(dir / "report.json", report);
  out.commit();
  print_summary(job, r, out.target(), !images.empty());
  const int verdict_code = print_verdict(report);
  if (render_error)
    throw core::Error("the results are written to " + out.target().string() +
                      ", but the charts could not be drawn (--no-render skips them): " + *render_error);
  return verdict_code;
}

}  // namespace vmsim::app
