// vmsim plan-feed JOB: Chen et al.'s contour-error-constrained feed plan (drives/feedplan), played by the interpolator
// under the plan's feed ceiling and simulated through the servo, against the same path without a plan and with a
// plan that leaves the contour error out. Writes the feed profile (CSV), the played motion (CSV), report.json and
// charts (feed; axis velocity and acceleration with their limits; chord and contour error with their tolerances).
#include "app/commands.hpp"
#include "sim/job_program.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "motion/nurbs.hpp"
#include "core/hash.hpp"
#include "methods/feedplan.hpp"
#include "methods/feedplan_play.hpp"
#include "methods/feedplan_servo.hpp"
#include "render/chart.hpp"
#include "render/window.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

namespace vmsim::app {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using Index = Eigen::Index;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
constexpr double kInf = std::numeric_limits<double>::infinity();

nlohmann::json input(const fs::path& p) {
  std::error_code ec;
  const auto abs = fs::weakly_canonical(p, ec);
  return {{"path", (ec ? p : abs).string()}, {"sha256", core::sha256_file_hex(p)}};
}

std::string csv_number(double v, int digits) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (std::isnan(v)) return "nan";
  return fmt::format("{:.{}f}", v, digits);
}

// The servo of the job's [feedplan]: frequency responses of the moving axes for the contour-error model, and for the
// simulation either transfer functions per machine axis or nothing (the machine's own cascades).
struct Servo {
  std::vector<methods::AxisFrequencyResponse> responses;
  std::vector<methods::TransferFunction> simulate;  // empty: drives::simulate_axes with [axes.drive]
  std::string description;
};

Servo make_servo(const core::FeedPlanSpec& spec, const core::Machine& machine, double te,
                 const Eigen::Vector3d& moving, const std::string& job_file) {
  Servo s;
  static const char* names[] = {"X", "Y", "Z"};
  if (spec.servo == core::FeedPlanSpec::Servo::Machine) {
    s.description = "the machine's cascades ([axes.drive]), linearised (drives/linear_model, sampled-data at Te)";
    for (int r = 0; r < 3; ++r) {
      if (!(moving[r] > 0)) continue;
      const int ai = machine.axis_index(r);
      if (ai < 0 || !machine.axes[static_cast<std::size_t>(ai)].drive)
        throw core::Error(core::located(machine.source_file, 0,
                                        fmt::format("axis {} moves but has no [axes.drive]: [feedplan] servo = "
                                                    "\"machine\" needs its cascade (or give servo = \"pid\")",
                                                    names[r])));
      s.responses.push_back(methods::frequency_response(*machine.axes[static_cast<std::size_t>(ai)].drive, te));
    }
    return s;
  }
  const bool pid = spec.servo == core::FeedPlanSpec::Servo::Pid;
  s.description = pid ? "PID servo of Chen et al. 2016 eq. 2 per [[feedplan.axis]]" : "transfer functions per [[feedplan.axis]]";
  auto tf_of = [&](const core::FeedPlanSpec::Axis& a) {
    if (!pid) return methods::TransferFunction{a.num, a.den};
    methods::PidServoParams p{a.kp, a.ki, a.kd, a.ka, a.kt, a.inertia, a.damping, a.rg};
    return methods::pid_servo_transfer_function(p);
  };
  for (const core::MachineAxis& ax : machine.axes) {
    const core::FeedPlanSpec::Axis* given = nullptr;
    for (const auto& a : spec.axes)
      if (a.name == ax.name) given = &a;
    const bool moves = ax.program_axis < 3 && moving[ax.program_axis] > 0;
    if (!given && moves)
      throw core::Error(core::located(job_file, 0, fmt::format("axis {} moves but [feedplan] has no [[feedplan.axis]] "
                                                               "with name = \"{}\"",
                                                               ax.name, ax.name)));
    try {
      s.simulate.push_back(given ? tf_of(*given) : methods::TransferFunction{{1.0}, {1.0}});  // held axes: ideal
      if (moves) s.responses.push_back(methods::frequency_response(s.simulate.back()));
    } catch (const core::Error& e) {
      throw core::Error(core::located(job_file, 0, fmt::format("[[feedplan.axis]] {}: {}", ax.name, e.what())));
    }
  }
  return s;
}

nlohmann::json check_json(const methods::FeedPlanCheck& c) {
  return {{"feed", c.feed},
          {"chord_error", c.chord},
          {"contour_error_model", c.contour},
          {"axis_velocity", c.axis_velocity},
          {"axis_acceleration", c.axis_acceleration},
          {"axis_jerk", c.axis_jerk},
          {"worst", c.worst()}};
}

// Largest eq. 7 estimate rho |1 - |G(j f/rho)|| over the samples.
double model_contour_peak(const methods::PathSamples& ps, const Eigen::ArrayXd& feed,
                          const methods::ContourErrorModel& model) {
  double m = 0.0;
  for (Index i = 0; i < ps.size(); ++i) {
    const double k = ps.kappa_max[i];
    if (k > 1e-12) m = std::max(m, model.error_ratio(feed[i] * k) / k);
  }
  return m;
}

nlohmann::json run_json(const methods::PlayedPlan& p) {
  return {{"cycle_time_s", p.interp.stats.cycle_time_s},
          {"setpoints", p.interp.setpoints.samples()},
          {"interpolator_repair_passes", p.interp.stats.repair_passes},
          {"simulated_contour_error_max_um", p.max_abs_mm * 1e3},
          {"simulated_contour_error_rms_um", p.contour.rms_mm * 1e3},
          {"chord_error_max_um", p.chord_error_mm.maxCoeff() * 1e3}};
}

// ---- charts ------------------------------------------------------------------------------------------------------

Eigen::ArrayXd finite_or_nan(const Eigen::ArrayXd& a, double cap) {
  return a.isFinite().select(a.min(cap), std::numeric_limits<double>::quiet_NaN());
}

}  // namespace

int run_plan_feed(const PlanFeedArgs& args) {
  const auto t_start = Clock::now();
  const core::Job job = core::load_job(args.job);
  if (!job.feedplan)
    throw core::Error(core::located(job.file.string(), 0, "the job has no [feedplan] table (see parts/README.md)"));
  const core::FeedPlanSpec& spec = *job.feedplan;
  const core::Machine& machine = job.machine;
  const double te = job.interp.period_s;

  // The path: a NURBS (the quintic chain the interpolator follows, the curve sampled by parameter with arc-length
  // correction), or the job's program (its smoothed path, sampled).
  core::ToolPath program;
  std::optional<motion::NurbsPath> nurbs_path;
  std::optional<motion::NurbsCurve> curve;
  methods::PlanPlayer player;
  player.machine = &machine;
  player.interp.period_s = te;
  player.interp.tolerance_mm = job.interp.tolerance_mm;
  methods::PathSamples samples;
  double fmax = spec.max_feed_mm_per_s.value_or(0.0);
  nlohmann::json path_json;
  if (spec.nurbs) {
    if (!spec.max_feed_mm_per_s)
      throw core::Error(core::located(job.file.string(), 0,
                                      "[feedplan] max_feed_mm_per_s is required with a [feedplan.nurbs] path"));
    curve = motion::read_nurbs_csv(spec.nurbs->control_points, spec.nurbs->knots, spec.nurbs->degree);
    motion::NurbsPathOptions no;
    no.feed_mm_per_min = fmax * 60.0;
    nurbs_path = motion::nurbs_to_path(*curve, no);
    program = nurbs_path->program;
    player.interp.geometry = std::make_shared<const motion::SmoothPath>(nurbs_path->path);
    player.to_path_s = [np = &*nurbs_path](double s) { return np->path_s(s); };
    player.to_sample_s = [np = &*nurbs_path](double s) { return np->curve_s(s); };
    samples = methods::sample_nurbs(*curve, spec.sample_spacing_mm);
    path_json = {{"kind", "nurbs"},
                 {"degree", curve->degree},
                 {"control_points", curve->points.size()},
                 {"quintic_pieces", nurbs_path->path.pieces.size()},
                 {"quintic_chain_max_deviation_um", nurbs_path->max_deviation_mm * 1e3}};
  } else {
    program = motion::toolpath_in_axis_space(sim::read_job_program(job), machine);
    double programmed = 0.0;
    for (const core::Move& m : program.moves)
      if (!m.rapid && m.feed_mode == core::FeedMode::UnitsPerMinute) programmed = std::max(programmed, m.feed_mm_per_min / 60.0);
    if (!spec.max_feed_mm_per_s) fmax = programmed;
    if (!(fmax > 0))
      throw core::Error(core::located(job.file.string(), 0, "[feedplan] max_feed_mm_per_s: the program has no feed "
                                                             "move to take it from; give it"));
    samples = methods::sample_path(motion::smooth_path_for(program, machine, player.interp), spec.sample_spacing_mm);
    path_json = {{"kind", "program"}, {"moves", program.moves.size()}};
  }
  player.program = &program;
  const double length = samples.s[samples.size() - 1];
  path_json["length_mm"] = length;
  path_json["samples"] = samples.size();
  path_json["sample_spacing_mm"] = samples.ds;
  path_json["smallest_radius_mm"] = 1.0 / samples.kappa_max.maxCoeff();
  const double t_path = seconds_since(t_start);

  // Servo and limits.
  Eigen::Vector3d moving;
  for (int r = 0; r < 3; ++r) moving[r] = samples.t_abs_max.col(r).maxCoeff() > 1e-9 ? 1.0 : 0.0;
  const Servo servo = make_servo(spec, machine, te, moving, job.file.string());
  player.servo = servo.simulate;
  const methods::ContourErrorModel model(servo.responses);
  methods::FeedPlanLimits lim;
  lim.period_s = te;
  lim.chord_error_mm = spec.chord_error_mm;
  lim.contour_error_mm = spec.contour_error_mm;
  lim.max_feed_mm_per_s = fmax;
  for (int r = 0; r < 3; ++r) {
    const int ai = machine.axis_index(r);
    if (ai < 0) {
      if (moving[r] > 0) throw core::Error(fmt::format("the path moves axis {}, which the machine lacks", "XYZ"[r]));
      lim.axis_velocity[r] = lim.axis_acceleration[r] = lim.axis_jerk[r] = kInf;
      continue;
    }
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(ai)];
    lim.axis_velocity[r] = ax.max_velocity;
    lim.axis_acceleration[r] = ax.max_acceleration;
    lim.axis_jerk[r] = spec.jerk ? ax.max_jerk : kInf;
  }
  methods::FeedPlanOptions opt;
  opt.limits = lim;
  opt.contour_model = &model;
  opt.window_samples = spec.window_samples;
  methods::FeedPlanOptions opt_free = opt;  // the same plan without the contour-error constraint
  opt_free.limits.contour_error_mm = 0.0;

  // Plans and their play (a line per stage on stderr: DESIGN.md, long runs show progress).
  auto progress = [&](const char* what) {
    std::fprintf(stderr, "plan-feed: %s (%.1f s)\n", what, seconds_since(t_start));
    std::fflush(stderr);
  };
  progress("path sampled; simulating the programmed feed");
  auto t0 = Clock::now();
  const methods::PlayedPlan no_plan = methods::play_plan(player, samples, nullptr);
  progress("planning and simulating without the contour-error constraint");
  const methods::FeedPlan free_plan = methods::plan_feed(samples, opt_free);
  const methods::PlayedPlan free_played = methods::play_plan(player, samples, &free_plan);
  progress("planning with the contour-error constraint, simulating, verifying");
  methods::VerifyOptions vo;
  if (!spec.verify) vo.max_rounds = 1;
  const methods::VerifiedPlan ver = methods::plan_feed_verified(samples, opt, player, vo);
  progress("writing");
  const double t_plans = seconds_since(t0);
  const methods::FeedPlan& plan = ver.plan;
  const methods::PlayedPlan& played = ver.played;
  const methods::FeedPlanCheck check = methods::check_feed_plan(samples, plan.feed, lim, &model);
  const methods::FeedPlanCheck check_free = methods::check_feed_plan(samples, free_plan.feed, opt_free.limits, &model);
  const double model_peak_free = model_contour_peak(samples, free_plan.feed, model);
  const double model_peak = model_contour_peak(samples, plan.feed, model);

  // Files.
  t0 = Clock::now();
  const fs::path dir = args.out_dir.value_or(fs::current_path());
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());
  std::vector<std::string> files;
  {
    core::AtomicFile f(dir / "feed_profile.csv");
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
      line = fmt::format("{:.6f},{},{:.6f},{:.6f},{:.6f},{:.6g},{},{},{},{},{},{},{:.6f},{:.6f},{:.6f},{:.4f},{:.4f},{:.4f}\n",
                         samples.s[i], csv_number(samples.u[i], 9), samples.p(i, 0), samples.p(i, 1), samples.p(i, 2),
                         samples.kappa_max[i], csv_number(plan.f_star[i], 6), csv_number(plan.bound_contour[i], 6),
                         csv_number(plan.bound_chord[i], 6), csv_number(plan.bound_axis_velocity[i], 6),
                         csv_number(plan.bound_centripetal[i], 6), csv_number(plan.omega0[i], 6), free_plan.feed[i],
                         plan.feed[i], ver.contour_scale[i], no_plan.per_sample[i] * 1e3,
                         free_played.per_sample[i] * 1e3, played.per_sample[i] * 1e3);
      o << line;
    }
    f.commit();
    files.push_back("feed_profile.csv");
  }
  // The played motion of the plan: setpoints, their finite-difference axis velocity and acceleration, chord error,
  // and the simulated contour error at the same instant.
  const core::Setpoints& sp = played.interp.setpoints;
  const Index ns = sp.samples();
  std::vector<Index> cols;  // machine columns of X Y Z
  for (int r = 0; r < 3; ++r) cols.push_back(machine.axis_index(r));
  auto fd = [&](Index k, int r, int order) {  // backward differences, at rest before the first sample
    const Index c = cols[static_cast<std::size_t>(r)];
    if (c < 0) return 0.0;
    auto x = [&](Index j) { return sp.position(std::clamp<Index>(j, 0, ns - 1), c); };
    return order == 1 ? (x(k) - x(k - 1)) / te : (x(k) - 2 * x(k - 1) + x(k - 2)) / (te * te);
  };
  {
    core::AtomicFile f(dir / "motion.csv");
    auto& o = f.stream();
    o << "t_s,s_mm,feed_mm_per_s,ceiling_mm_per_s,x_mm,y_mm,z_mm,vx_mm_per_s,vy_mm_per_s,vz_mm_per_s,ax_mm_per_s2,"
         "ay_mm_per_s2,az_mm_per_s2,chord_error_um,contour_error_um\n";
    const motion::FeedCeiling ceil = methods::feed_ceiling(plan, player.to_path_s);
    for (Index k = 0; k < ns; ++k) {
      auto pos = [&](int r) { return cols[static_cast<std::size_t>(r)] < 0 ? 0.0 : sp.position(k, cols[static_cast<std::size_t>(r)]); };
      o << fmt::format("{:.4f},{:.6f},{:.5f},{:.5f},{:.6f},{:.6f},{:.6f},{:.5f},{:.5f},{:.5f},{:.4f},{:.4f},{:.4f},{:.5f},{:.5f}\n",
                       k * te, sp.path_length_mm[k], sp.path_speed_mm_per_s[k], ceil.at(sp.path_length_mm[k]), pos(0),
                       pos(1), pos(2), fd(k, 0, 1), fd(k, 1, 1), fd(k, 2, 1), fd(k, 0, 2), fd(k, 1, 2), fd(k, 2, 2),
                       played.chord_error_mm[k] * 1e3, played.contour.signed_mm[k] * 1e3);
    }
    f.commit();
    files.push_back("motion.csv");
  }

  // Charts (Chen et al. 2016 Fig. 3 b-f), against the arc length.
  std::vector<std::string> images;
  if (!args.no_render) {
    render::Window window;
    const fs::path idir = dir / "images";
    fs::create_directories(idir, ec);
    if (ec) throw core::Error(idir.string() + ": cannot create the directory: " + ec.message());
    auto [w, h] = std::pair<int, int>{1600, 900};
    const std::string title = job.name + fmt::format(": T {} ms, chord {} µm, contour {} µm, f_max {} mm/s",
                                                     te * 1e3, spec.chord_error_mm * 1e3, spec.contour_error_mm * 1e3, fmax);
    auto save = [&](const std::string& name, render::ChartPicture pic) {
      pic.width = w, pic.height = h;
      render::write_png(idir / name, render::render_charts(window, pic).image);
      images.push_back("images/" + name);
    };
    Eigen::ArrayXd sset(ns), speed = sp.path_speed_mm_per_s;
    for (Index k = 0; k < ns; ++k) sset[k] = player.to_sample_s ? player.to_sample_s(sp.path_length_mm[k]) : sp.path_length_mm[k];
    {
      render::ChartPicture pic;
      pic.caption = {title, "feed along the path: eq. 24's bound f*, the plan without and with the contour-error "
                            "constraint, and the interpolator's feed playing the plan"};
      render::Chart c;
      c.title = "feed";
      c.x_title = "s [mm]";
      c.y_title = "feed [mm/s]";
      c.series.push_back(render::make_series("f* (eq. 24)", samples.s, finite_or_nan(plan.f_star, 2 * fmax), 7, 1.2, true));
      c.series.push_back(render::make_series("plan without contour error", samples.s, free_plan.feed, 1));
      c.series.push_back(render::make_series("plan", samples.s, plan.feed, 0, 2.0));
      c.series.push_back(render::make_series("interpolated (plan)", sset, speed, 2, 1.2));
      c.levels.push_back({fmt::format("f_max {} mm/s", fmax), fmax});
      c.y_range = std::pair<double, double>{0.0, fmax * 1.1};
      pic.charts.push_back(c);
      save("feed.png", pic);
    }
    {
      render::ChartPicture pic;
      pic.caption = {title, "axis velocity and acceleration of the interpolated plan (finite differences of the "
                            "setpoints), with the machine's limits"};
      for (int order = 1; order <= 2; ++order) {
        render::Chart c;
        c.title = order == 1 ? "axis velocity" : "axis acceleration";
        c.x_title = "s [mm]";
        c.y_title = order == 1 ? "velocity [mm/s]" : "acceleration [mm/s²]";
        int colour = 0;
        double limit = 0.0;
        for (int r = 0; r < 3; ++r) {
          if (!(moving[r] > 0) || cols[static_cast<std::size_t>(r)] < 0) continue;
          Eigen::ArrayXd y(ns);
          for (Index k = 0; k < ns; ++k) y[k] = fd(k, r, order);
          c.series.push_back(render::make_series(std::string(1, "XYZ"[r]), sset, y, colour++));
          limit = std::max(limit, order == 1 ? lim.axis_velocity[r] : lim.axis_acceleration[r]);
        }
        c.levels.push_back({fmt::format("limit ±{:g} {}", limit, order == 1 ? "mm/s" : "mm/s²"), limit});
        c.levels.push_back({"", -limit});
        pic.charts.push_back(c);
      }
      save("axes.png", pic);
    }
    {
      render::ChartPicture pic;
      pic.caption = {title, "chord error of the interpolated plan, and the simulated contour error: no plan (the "
                            "programmed feed), the plan without and with the contour-error constraint"};
      render::Chart ch;
      ch.title = "chord error";
      ch.x_title = "s [mm]";
      ch.y_title = "chord error [µm]";
      ch.series.push_back(render::make_series("plan", sset, played.chord_error_mm * 1e3, 0));
      ch.levels.push_back({fmt::format("limit {:g} µm", spec.chord_error_mm * 1e3), spec.chord_error_mm * 1e3});
      pic.charts.push_back(ch);
      render::Chart ce;
      ce.title = "contour error (simulated)";
      ce.x_title = "s [mm]";
      ce.y_title = "contour error [µm]";
      ce.series.push_back(render::make_series("no plan", no_plan.sample_s, no_plan.contour.signed_mm * 1e3, 7, 1.0));
      ce.series.push_back(render::make_series("plan without contour error", free_played.sample_s, free_played.contour.signed_mm * 1e3, 1, 1.2));
      ce.series.push_back(render::make_series("plan", played.sample_s, played.contour.signed_mm * 1e3, 0, 1.6));
      ce.levels.push_back({fmt::format("tolerance ±{:g} µm", spec.contour_error_mm * 1e3), spec.contour_error_mm * 1e3});
      ce.levels.push_back({"", -spec.contour_error_mm * 1e3});
      pic.charts.push_back(ce);
      save("errors.png", pic);
    }
  }
  const double t_write = seconds_since(t0);

  // report.json
  nlohmann::json inputs = {{"job", input(job.file)}, {"machine", input(job.machine_file)}};
  if (spec.nurbs) {
    inputs["nurbs_control_points"] = input(spec.nurbs->control_points);
    inputs["nurbs_knots"] = input(spec.nurbs->knots);
  } else {
    inputs["program"] = input(job.program_file);
  }
  nlohmann::json report = {{"vmsim", VMSIM_VERSION}, {"command", "plan-feed"}, {"job", job.name}, {"inputs", inputs}};
  report["path"] = path_json;
  report["servo"] = {{"model", servo.description},
                     {"natural_frequency_rad_s", model.natural_frequency()},
                     {"simulated_by", servo.simulate.empty() ? "drives::simulate_axes (the machine's cascades)"
                                                             : "methods::TransferFunctionAxis per axis"}};
  report["limits"] = {{"period_s", te},
                      {"chord_error_um", spec.chord_error_mm * 1e3},
                      {"contour_error_um", spec.contour_error_mm * 1e3},
                      {"max_feed_mm_per_s", fmax},
                      {"axis_velocity_mm_per_s", {lim.axis_velocity[0], lim.axis_velocity[1], lim.axis_velocity[2]}},
                      {"axis_acceleration_mm_per_s2", {lim.axis_acceleration[0], lim.axis_acceleration[1], lim.axis_acceleration[2]}},
                      {"axis_jerk_mm_per_s3", spec.jerk ? nlohmann::json({lim.axis_jerk[0], lim.axis_jerk[1], lim.axis_jerk[2]})
                                                        : nlohmann::json(nullptr)}};
  const auto& st = plan.stats;
  report["lp"] = {{"solver", "COIN-OR Clp, dual simplex"},
                  {"variables_per_window_max", st.lp_columns_max},
                  {"rows_per_window_max", st.lp_rows_max},
                  {"nonzeros_per_window_max", st.lp_nonzeros_max},
                  {"windows", st.windows},
                  {"window_samples", st.window_samples},
                  {"overlap_samples", st.overlap_samples},
                  {"solves", st.lp_solves},
                  {"jerk_linearisations_max", st.jerk_iterations_max},
                  {"lp_seconds", st.lp_seconds},
                  {"plan_seconds", st.total_seconds}};
  nlohmann::json runs;
  runs["no_plan"] = run_json(no_plan);
  runs["plan_without_contour_error"] = run_json(free_played);
  runs["plan_without_contour_error"]["plan_time_s"] = free_plan.time_s;
  runs["plan_without_contour_error"]["model_contour_error_max_um"] = model_peak_free * 1e3;
  runs["plan_without_contour_error"]["check"] = check_json(check_free);
  runs["plan"] = run_json(played);
  runs["plan"]["plan_time_s"] = plan.time_s;
  runs["plan"]["model_contour_error_max_um"] = model_peak * 1e3;
  runs["plan"]["check"] = check_json(check);
  runs["plan"]["verification_rounds"] = ver.rounds;
  runs["plan"]["simulated_peak_per_round_um"] = ver.simulated_peak_mm;
  for (auto& v : runs["plan"]["simulated_peak_per_round_um"]) v = v.get<double>() * 1e3;
  runs["plan"]["plan_time_per_round_s"] = ver.model_time_s;
  runs["plan"]["contour_scale_min"] = ver.contour_scale.minCoeff();
  runs["plan"]["within_tolerance"] = played.max_abs_mm <= spec.contour_error_mm;
  report["runs"] = runs;
  const double cost = played.interp.stats.cycle_time_s / free_played.interp.stats.cycle_time_s - 1.0;
  report["cycle_time_cost_of_contour_constraint"] = cost;
  report["files"] = files;
  report["images"] = images;
  report["timings_s"] = {{"path", t_path}, {"plans_and_simulations", t_plans}, {"write", t_write},
                         {"total", seconds_since(t_start)}};
  write_report(dir / "report.json", report);

  std::printf("job %s: %s path, %.3f mm, %lld samples of %.4f mm; servo w_n %.2f rad/s\n", job.name.c_str(),
              spec.nurbs ? "NURBS" : "program", length, static_cast<long long>(samples.size()), samples.ds,
              model.natural_frequency());
  std::printf("LP: %lld variables, %lld rows per window (max), %d windows, %d Clp solves (%d jerk linearisations max), "
              "%.3f s in Clp, plan %.3f s\n",
              static_cast<long long>(st.lp_columns_max), static_cast<long long>(st.lp_rows_max), st.windows,
              st.lp_solves, st.jerk_iterations_max, st.lp_seconds, st.total_seconds);
  std::printf("                              cycle time   plan time   contour error max (simulated / model)\n");
  std::printf("no plan (programmed feed)      %8.3f s                %7.2f um\n", no_plan.interp.stats.cycle_time_s,
              no_plan.max_abs_mm * 1e3);
  std::printf("plan without contour error     %8.3f s  %8.3f s    %7.2f / %.2f um\n",
              free_played.interp.stats.cycle_time_s, free_plan.time_s, free_played.max_abs_mm * 1e3, model_peak_free * 1e3);
  std::printf("plan (contour error <= %g um)  %8.3f s  %8.3f s    %7.2f / %.2f um  (%d round%s)\n",
              spec.contour_error_mm * 1e3, played.interp.stats.cycle_time_s, plan.time_s, played.max_abs_mm * 1e3,
              model_peak * 1e3, ver.rounds, ver.rounds == 1 ? "" : "s");
  std::printf("cycle-time cost of the contour constraint: %+.1f %%; every constraint at every sample: worst %.6f of its "
              "limit\n",
              cost * 100, check.worst());
  std::printf("wrote %s (report.json, feed_profile.csv, motion.csv%s)\n", dir.string().c_str(),
              images.empty() ? "" : ", images/");
  if (played.max_abs_mm > spec.contour_error_mm)
    std::printf("NOTE: the simulated contour error of the plan exceeds the tolerance (%s)\n",
                spec.verify ? "the verification rounds did not bring it within: see report.json"
                            : "[feedplan] verify = false: Chen et al.'s model alone");
  return 0;
}

}  // namespace vmsim::app
