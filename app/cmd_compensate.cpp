// vmsim compensate JOB: the predictive-compensation paper's predictive contour-error compensation. The job's setpoints are predicted with its
// axis models (the machine file's cascades, or identified transfer functions: [job] axis_models or --axis-models),
// corrected by the predicted contour error (drives/compensate), and written as setpoints and as a G-code program a
// user can send to the machine. The contour errors before and after are measured with core/contour on the cutting
// moves, for the prediction and, when identified models predicted, also on the machine file's cascades.
#include "sim/axis_models.hpp"
#include "methods/compensated_program.hpp"
#include "app/commands_sysid.hpp"
#include "sim/contour_stats.hpp"
#include "sim/job_program.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "motion/contour.hpp"
#include "core/error.hpp"
#include "core/timing.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "core/units.hpp"
#include "methods/compensate.hpp"
#include "drives/simulate.hpp"
#include "render/chart.hpp"
#include "render/image.hpp"
#include "render/window.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

namespace vmsim::app {

namespace {

using core::Clock;
using core::seconds_since;

struct Figures {
  double max_mm = 0, mean_mm = 0, rms_mm = 0;
  double orientation_max_rad = 0, orientation_mean_rad = 0;  // five-axis: tool axis vs the commanded one at the foot
  bool orientation = false;
  Eigen::Index samples = 0;
  motion::ContourError ce;
  Eigen::VectorXd angle_rad;  // per actual row (five-axis)
};

// Contour error of `actual` against the planned tip path on the cutting (feed) moves (classified by the setpoints and
// program the actual rows come from): max, mean and rms of |CE|; with tool axes, the angle between the actual axis
// and the commanded one interpolated at core/contour's foot point (the orientation part of the five-axis contour
// error).
Figures measure(const Eigen::MatrixXd& command_tip, const Eigen::MatrixXd& actual_tip, const core::Setpoints& sp,
                const core::ToolPath& program, const Eigen::MatrixXd* command_axis = nullptr,
                const Eigen::MatrixXd* actual_axis = nullptr) {
  Figures f;
  f.ce = motion::contour_error(command_tip, actual_tip);
  f.orientation = command_axis && actual_axis;
  if (f.orientation) {
    const Eigen::Index rows = actual_tip.rows(), ns = command_tip.rows();
    Eigen::VectorXd param(rows);
    for (Eigen::Index k = 0; k < rows; ++k) {
      const Eigen::Index i = std::clamp<Eigen::Index>(f.ce.foot_segment[k], 0, std::max<Eigen::Index>(ns - 2, 0));
      const Eigen::Vector3d a = command_tip.row(i).transpose(), b = command_tip.row(std::min(i + 1, ns - 1)).transpose();
      const double l2 = (b - a).squaredNorm();
      const double t = l2 > 0 ? std::clamp((actual_tip.row(k).transpose() - a).dot(b - a) / l2, 0.0, 1.0) : 0.0;
      param[k] = static_cast<double>(i) + t;
    }
    f.angle_rad = methods::axis_angles(methods::axes_at(*command_axis, param), *actual_axis);
  }
  double sum = 0, sum2 = 0, osum = 0;
  for (Eigen::Index k = 0; k < f.ce.signed_mm.size(); ++k) {
    const int mi = sp.move_index[std::min(k, sp.samples() - 1)];
    if (mi < 0 || program.moves[static_cast<std::size_t>(mi)].rapid) continue;
    const double e = std::abs(f.ce.signed_mm[k]);
    f.max_mm = std::max(f.max_mm, e);
    sum += e;
    sum2 += e * e;
    if (f.orientation) {
      f.orientation_max_rad = std::max(f.orientation_max_rad, f.angle_rad[k]);
      osum += f.angle_rad[k];
    }
    ++f.samples;
  }
  if (f.samples > 0) {
    f.mean_mm = sum / static_cast<double>(f.samples);
    f.rms_mm = std::sqrt(sum2 / static_cast<double>(f.samples));
    f.orientation_mean_rad = osum / static_cast<double>(f.samples);
  }
  return f;
}

nlohmann::json figures_json(const Figures& before, const Figures& after) {
  auto pct = [](double b, double a) { return b > 0 ? 100.0 * (a - b) / b : 0.0; };
  nlohmann::json j = {{"before", {{"max_mm", before.max_mm}, {"mean_mm", before.mean_mm}, {"rms_mm", before.rms_mm}}},
                      {"after", {{"max_mm", after.max_mm}, {"mean_mm", after.mean_mm}, {"rms_mm", after.rms_mm}}},
                      {"change_percent", {{"max", pct(before.max_mm, after.max_mm)},
                                          {"mean", pct(before.mean_mm, after.mean_mm)},
                                          {"rms", pct(before.rms_mm, after.rms_mm)}}},
                      {"samples", before.samples}};
  if (before.orientation && after.orientation) {
    const double d = core::units::kRadToDeg;
    j["before"]["orientation_max_deg"] = before.orientation_max_rad * d;
    j["before"]["orientation_mean_deg"] = before.orientation_mean_rad * d;
    j["after"]["orientation_max_deg"] = after.orientation_max_rad * d;
    j["after"]["orientation_mean_deg"] = after.orientation_mean_rad * d;
    j["change_percent"]["orientation_max"] = pct(before.orientation_max_rad, after.orientation_max_rad);
    j["change_percent"]["orientation_mean"] = pct(before.orientation_mean_rad, after.orientation_mean_rad);
  }
  return j;
}

nlohmann::json limits_json(const std::vector<methods::AxisLimitCheck>& checks, const core::Machine& m) {
  nlohmann::json j = nlohmann::json::object();
  for (std::size_t a = 0; a < checks.size(); ++a) {
    const auto& c = checks[a];
    const bool rot = m.axes[a].kind == core::AxisKind::Rotary;
    const double f = rot ? core::units::kRadToDeg : 1.0;
    const std::string u = rot ? "deg" : "mm";
    j[c.axis] = {{"within_limits", c.within()},
                 {"samples_over", c.samples_over},
                 {"first_over_s", c.first_over_s},
                 {"peak_velocity_" + u + "_per_s", c.peak_velocity * f},
                 {"peak_acceleration_" + u + "_per_s2", c.peak_acceleration * f},
                 {"peak_jerk_" + u + "_per_s3", c.peak_jerk * f},
                 {"limit_velocity_" + u + "_per_s", c.limit_velocity * f},
                 {"limit_acceleration_" + u + "_per_s2", c.limit_acceleration * f},
                 {"limit_jerk_" + u + "_per_s3", c.limit_jerk * f}};
  }
  return j;
}

}  // namespace

int run_compensate(const CompensateArgs& args) {
  const auto t_start = Clock::now();
  if (args.buffer_samples < 0 || (args.buffer_samples > 0 && args.buffer_samples % 2 == 0))
    throw core::Error(fmt::format("--buffer {}: expected an odd number of samples (or 0: automatic)", args.buffer_samples));
  if (args.max_iterations < 0 || args.max_iterations > 50)
    throw core::Error(fmt::format("--iterations {}: expected 0 to 50", args.max_iterations));
  const core::Job job = core::load_job(args.job);
  const core::Machine& machine = job.machine;
  const sim::JobAxisModels models = sim::job_axis_models(job, args.axis_models);
  const core::ToolPath program = sim::read_job_program(job);
  const core::ToolPath path = motion::toolpath_in_axis_space(program, machine);
  motion::InterpOptions iopt;
  iopt.period_s = job.interp.period_s;
  iopt.tolerance_mm = job.interp.tolerance_mm;
  const motion::InterpResult ir = motion::interpolate(path, machine, iopt);
  const core::Setpoints& sp = ir.setpoints;
  const double te = sp.period_s;
  const auto kin = motion::make_kinematics(machine);
  Eigen::VectorXd tlo(sp.samples());
  for (Eigen::Index k = 0; k < sp.samples(); ++k) {
    const int mi = sp.move_index[k];
    tlo[k] = mi >= 0 ? program.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
  }
  const double t_prepare = seconds_since(t_start);

  // Predictions: with the job's models, and with the machine file's cascades (the "machine" the program runs on).
  auto predictor = [&](const std::vector<const drives::AxisModel*>* per_axis) {
    return [&sp, &machine, per_axis](const Eigen::MatrixXd& setpoints) {
      core::Setpoints s = sp;
      s.position = setpoints;
      drives::SimulateOptions o;
      o.axis_models = per_axis;
      return drives::simulate_axes(s, machine, o).position;
    };
  };
  methods::CompensationProblem problem;
  problem.setpoints = &sp;
  problem.kinematics = kin.get();
  problem.tool_length_offset_mm = tlo;
  problem.predict = predictor(models.any() ? &models.per_axis : nullptr);
  methods::CompensateOptions copt;
  copt.buffer_samples = args.buffer_samples;
  copt.max_iterations = args.max_iterations;
  copt.limits = &machine;  // the correction is faded where it would break an axis limit the setpoints kept
  copt.orientation = !args.tip_only;
  if (!(args.smoothing_samples >= 0.0 && args.smoothing_samples <= 1000.0))
    throw core::Error(fmt::format("--smoothing {}: expected 0 to 1000 samples", args.smoothing_samples));
  copt.smoothing_samples = args.smoothing_samples;
  auto t0 = Clock::now();
  const methods::CompensationResult res = methods::compensate_contour(problem, copt);
  const double t_comp = seconds_since(t0);

  const Eigen::MatrixXd& cmd_tip = res.command_tip;
  const bool five = res.orientation;
  const Eigen::MatrixXd* cmd_axis = five ? &res.command_axis : nullptr;
  // Tip (and, five-axis, tool axis) figures of predicted axis rows against the plan.
  auto figures = [&](const Eigen::MatrixXd& rows, const core::Setpoints& s, const core::ToolPath& prog) {
    const Eigen::MatrixXd tips = methods::tool_tips(*kin, rows, tlo);
    if (!five) return measure(cmd_tip, tips, s, prog);
    const Eigen::MatrixXd axes = methods::tool_axes(*kin, rows, tlo);
    return measure(cmd_tip, tips, s, prog, cmd_axis, &axes);
  };
  const Figures pred_before = figures(res.predicted_before, sp, program);
  const Figures pred_after = figures(res.predicted_after, sp, program);
  const auto on_machine = predictor(nullptr);
  std::optional<Figures> mach_before, mach_after;
  if (models.any()) {
    mach_before = figures(on_machine(sp.position), sp, program);
    mach_after = figures(on_machine(res.setpoints), sp, program);
  }
  const auto limits_before = methods::check_axis_limits(sp.position, te, machine);
  const auto limits_after = methods::check_axis_limits(res.setpoints, te, machine);
  bool within = true;
  for (const auto& c : limits_after) within = within && c.within();

  // Files.
  t0 = Clock::now();
  const std::filesystem::path dir = args.out_dir.value_or(std::filesystem::current_path());
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());
  const Eigen::Index ns = sp.samples(), na = static_cast<Eigen::Index>(machine.axes.size());
  std::vector<std::string> files;
  {
    std::string s = "t_s";
    for (const auto& ax : machine.axes)
      s += fmt::format(",{0}_{1},{0}_compensated_{1}", ax.name, ax.kind == core::AxisKind::Rotary ? "deg" : "mm");
    s += '\n';
    for (Eigen::Index k = 0; k < ns; ++k) {
      s += fmt::format("{:.6f}", k * te);
      for (Eigen::Index a = 0; a < na; ++a) {
        const double f = machine.axes[static_cast<std::size_t>(a)].kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0;
        s += fmt::format(",{:.9f},{:.9f}", sp.position(k, a) * f, res.setpoints(k, a) * f);
      }
      s += '\n';
    }
    core::write_file_atomic(dir / "compensated_setpoints.csv", s);
    files.push_back("compensated_setpoints.csv");
  }
  // The compensated program: the original's moves and feeds with corrected points (app/compensated_program).
  methods::CompensatedProgramInput pin;
  pin.program = &program;
  pin.axis_path = &path;
  pin.setpoints = &sp;
  pin.compensated = &res.setpoints;
  pin.command_tip = &cmd_tip;
  pin.machine = &machine;
  pin.kinematics = kin.get();
  pin.title = job.name;
  const methods::CompensatedProgram cprog = methods::write_compensated_program(pin);
  const std::string cprog_name = "compensated." + cprog.extension;
  core::write_file_atomic(dir / cprog_name, cprog.text);
  files.push_back(cprog_name);
  std::optional<methods::CompensatedProgram> tcp_prog;
  if (five && cprog.extension == "cl") {
    // The G-code form for a controller with a five-axis transformation, and the original in the same form (zero
    // correction), so the two can be timed alike.
    tcp_prog = methods::write_compensated_tcp_gcode(pin);
    core::write_file_atomic(dir / "compensated_tcp.ngc", tcp_prog->text);
    files.push_back("compensated_tcp.ngc");
    methods::CompensatedProgramInput orig = pin;
    orig.compensated = &sp.position;
    orig.title = job.name + ", original, no correction: the reference for compensated_tcp.ngc";
    core::write_file_atomic(dir / "original_tcp.ngc", methods::write_compensated_tcp_gcode(orig).text);
    files.push_back("original_tcp.ngc");
  }
  if (args.dense_program) {
    // The compensated setpoints themselves as a program: the tool tip (and rotary words) of every setpoint, one block
    // per Te in inverse-time feed (G93: F = 1 / block duration in minutes), for an NC that replays blocks as timed.
    std::string s;
    s += fmt::format("(vmsim compensate: {} - the predictive-compensation paper predictive contour-error compensation, dense form)\n", job.name);
    s += "(one block per interpolation period Te; X Y Z: tool tip in the workpiece frame, as the original program)\n";
    if (five) s += "(five-axis: tool-centre-point form, X Y Z the tip and A B C the rotary axes; vmsim: [job] tcp = true)\n";
    s += "G21 G90 G17\n";
    Eigen::VectorXd q(na);
    std::vector<int> rotary;
    for (Eigen::Index a = 0; a < na; ++a)
      if (machine.axes[static_cast<std::size_t>(a)].kind == core::AxisKind::Rotary) rotary.push_back(static_cast<int>(a));
    auto words = [&](Eigen::Index k) {
      q = res.setpoints.row(k).transpose();
      const motion::ToolPose pose = kin->forward(q, tlo[k]);
      std::string w = fmt::format("X{:.6f} Y{:.6f} Z{:.6f}", pose.tip_mm.x(), pose.tip_mm.y(), pose.tip_mm.z());
      for (int a : rotary)
        if (five || (res.setpoints.col(a).array() != res.setpoints(0, a)).any())
          w += fmt::format(" {}{:.6f}", machine.axes[static_cast<std::size_t>(a)].name, q[a] * core::units::kRadToDeg);
      return w;
    };
    s += "G0 " + words(0) + "\nG93\n";
    const double f = 60.0 / te;
    for (Eigen::Index k = 1; k < ns; ++k) s += fmt::format("G1 {} F{:.1f}\n", words(k), f);
    s += "G94\nM2\n";
    core::write_file_atomic(dir / "compensated_dense.ngc", s);
    files.push_back("compensated_dense.ngc");
  }
  {
    std::string s = five ? "t_s,contour_error_before_mm,contour_error_after_mm,orientation_error_before_deg,"
                           "orientation_error_after_deg\n"
                         : "t_s,contour_error_before_mm,contour_error_after_mm\n";
    const Eigen::Index rows = std::min(pred_before.ce.signed_mm.size(), pred_after.ce.signed_mm.size());
    for (Eigen::Index k = 0; k < rows; ++k) {
      s += fmt::format("{:.6f},{:.9f},{:.9f}", k * te, pred_before.ce.signed_mm[k], pred_after.ce.signed_mm[k]);
      if (five)
        s += fmt::format(",{:.9f},{:.9f}", pred_before.angle_rad[k] * core::units::kRadToDeg,
                         pred_after.angle_rad[k] * core::units::kRadToDeg);
      s += '\n';
    }
    core::write_file_atomic(dir / "contour_errors.csv", s);
    files.push_back("contour_errors.csv");
  }
  const double t_write = seconds_since(t0);

  // End to end, as a user would run it: the compensated program read back, re-timed by vmsim's interpolator and run
  // on the machine file's cascades; its contour error against the ORIGINAL plan, its cycle time against the original's.
  t0 = Clock::now();
  core::Job cjob = job;
  cjob.program_file = dir / cprog_name;
  const core::ToolPath cprogram = sim::read_job_program(cjob);
  const motion::InterpResult cir = motion::interpolate(motion::toolpath_in_axis_space(cprogram, machine), machine, iopt);
  Eigen::VectorXd ctlo(cir.setpoints.samples());
  for (Eigen::Index k = 0; k < ctlo.size(); ++k) {
    const int mi = cir.setpoints.move_index[k];
    ctlo[k] = mi >= 0 ? cprogram.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
  }
  const Eigen::MatrixXd cactual = drives::simulate_axes(cir.setpoints, machine).position;
  const Figures prog_machine = [&] {
    const Eigen::MatrixXd tips = methods::tool_tips(*kin, cactual, ctlo);
    if (!five) return measure(cmd_tip, tips, cir.setpoints, cprogram);
    const Eigen::MatrixXd axes = methods::tool_axes(*kin, cactual, ctlo);
    return measure(cmd_tip, tips, cir.setpoints, cprogram, cmd_axis, &axes);
  }();
  const Figures orig_machine = models.any() ? *mach_before : figures(on_machine(sp.position), sp, program);
  const auto limits_program = methods::check_axis_limits(cir.setpoints.position, te, machine);
  bool program_within = true;
  for (const auto& c : limits_program) program_within = program_within && c.within();
  const double cycle_orig = sp.duration_s(), cycle_prog = cir.setpoints.duration_s();
  // The tool-centre-point forms through vmsim's interpreter of such programs ([job] tcp, the tool starting at the
  // program's first pose): original and compensated timed alike.
  std::optional<std::pair<double, double>> tcp_cycles;
  if (tcp_prog) {
    auto cycle_of = [&](const std::filesystem::path& file) {
      core::Job tj = job;
      tj.program_file = file;
      tj.tcp = true;
      Eigen::VectorXd q0(na);
      for (Eigen::Index a = 0; a < na; ++a) q0[a] = path.initial_position[machine.axes[static_cast<std::size_t>(a)].program_axis];
      tj.start_mm = kin->forward(q0, tlo[0]).tip_mm;
      const core::ToolPath tp = sim::read_job_program(tj);
      return motion::interpolate(motion::toolpath_in_axis_space(tp, machine), machine, iopt).setpoints.duration_s();
    };
    tcp_cycles = std::make_pair(cycle_of(dir / "original_tcp.ngc"), cycle_of(dir / "compensated_tcp.ngc"));
  }
  const double t_check = seconds_since(t0);

  // The chart of the contour error before and after (images/contour_error.png), after every result file: a failure
  // to draw loses no result.
  std::optional<std::string> render_error;
  double t_render = 0;
  if (!args.no_render) {
    t0 = Clock::now();
    try {
      render::Window window;
      std::filesystem::create_directories(dir / "images");
      auto um = [](const Eigen::VectorXd& mm) { return Eigen::ArrayXd(mm.array() * 1e3); };
      auto deg = [](const Eigen::VectorXd& rad) { return Eigen::ArrayXd(rad.array() * core::units::kRadToDeg); };
      auto time = [te](Eigen::Index n) {
        return Eigen::ArrayXd(Eigen::ArrayXd::LinSpaced(n, 0.0, te * static_cast<double>(n - 1)));
      };
      auto chart = [&](const std::string& title, const std::string& y, const std::string& a, const Eigen::ArrayXd& ya,
                       const std::string& b, const Eigen::ArrayXd& yb) {
        render::Chart c;
        c.title = title;
        c.x_title = "t [s]";
        c.y_title = y;
        c.series.push_back(render::make_series(a, time(ya.size()), ya, 1, 1.4));
        c.series.push_back(render::make_series(b, time(yb.size()), yb, 0, 1.6));
        return c;
      };
      render::ChartPicture pic;
      pic.caption = {fmt::format("{}: predictive contour-error compensation, contour error on the machine max {:.2f} "
                                 "→ {:.2f} µm", job.name, orig_machine.max_mm * 1e3, prog_machine.max_mm * 1e3),
                     "signed contour error against the planned path, every sample (rapid moves too)"};
      pic.charts.push_back(chart("predicted: the setpoints before and after the correction", "contour error [µm]",
                                 "before", um(pred_before.ce.signed_mm), "after", um(pred_after.ce.signed_mm)));
      pic.charts.push_back(chart("the original and the compensated program, re-timed and run on the machine file's "
                                 "cascades", "contour error [µm]", "original program", um(orig_machine.ce.signed_mm),
                                 "compensated program", um(prog_machine.ce.signed_mm)));
      // The orientation error where the tool axis has one (a five-axis chain whose program turns the tool).
      const bool turns = five && pred_before.angle_rad.size() > 0 && pred_after.angle_rad.size() > 0 &&
                         std::max(pred_before.angle_rad.maxCoeff(), pred_after.angle_rad.maxCoeff()) > 0;
      if (turns)
        pic.charts.push_back(chart("predicted orientation error (tool axis)", "angle [deg]", "before",
                                   deg(pred_before.angle_rad), "after", deg(pred_after.angle_rad)));
      pic.height = turns ? 1200 : 900;
      render::write_png(dir / "images" / "contour_error.png", render::render_charts(window, pic).image);
      files.push_back("images/contour_error.png");
    } catch (const core::Error& e) {
      render_error = e.what();
      std::fprintf(stderr, "vmsim compensate: no chart: %s\n", e.what());
    }
    t_render = seconds_since(t0);
  }

  nlohmann::json report = report_header("compensate", job);
  if (models.file)
    report["inputs"]["axis_models"] = {{"path", models.file->string()}};
  report["prediction"] = models.any() ? "identified transfer functions for " + fmt::format("{}", fmt::join(models.identified_axes, " ")) +
                                            ", the machine file's cascades for the other axes"
                                      : "the machine file's cascades ([axes.drive])";
  report["method"] = {{"foot_points", "the predictive-compensation paper section 4: nearest command point in a buffer of m samples, then the adjacent segment"},
                      {"buffer_samples", res.buffer_samples},
                      {"correction", "eq. 23: each setpoint moved by the predicted contour error at its place on the path, repeated while the mean falls"},
                      {"smoothing_samples", copt.smoothing_samples},
                      {"limits", "the correction is faded out (smoothly, over +-" + std::to_string(copt.limit_window_samples) +
                                     " samples and more) where the corrected setpoints would break an axis velocity, acceleration or jerk limit"},
                      {"measured_by", "core/contour (exact foot point on the planned path), cutting moves only"}};
  if (five)
    report["method"]["five_axis"] =
        "tool tip and tool axis by the forward transform; the tool axis' error against the commanded axis at the same "
        "foot point corrected with the tip's; the corrected pose back to the joints through the chain's closed-form "
        "inverse (exact for corrections of any size, continuous rotary angles), not its Jacobian";
  nlohmann::json its = nlohmann::json::array();
  for (const auto& it : res.iterations) {
    nlohmann::json j = {{"max_mm", it.max_mm}, {"mean_mm", it.mean_mm}, {"accepted", it.accepted},
                        {"faded_samples", it.faded_samples}};
    if (five) {
      j["orientation_max_deg"] = it.orientation_max_rad * core::units::kRadToDeg;
      j["orientation_mean_deg"] = it.orientation_mean_rad * core::units::kRadToDeg;
    }
    its.push_back(j);
  }
  report["iterations"] = its;
  report["contour_error"]["predicted"] = figures_json(pred_before, pred_after);
  if (mach_before) report["contour_error"]["on_machine_cascades"] = figures_json(*mach_before, *mach_after);
  report["contour_error"]["compensated_program_on_machine"] = figures_json(orig_machine, prog_machine);
  report["compensated_program"] = {
      {"file", cprog_name},
      {"blocks", cprog.blocks},
      {"original_moves", program.moves.size()},
      {"largest_tip_correction_mm", cprog.largest_tip_correction_mm},
      {"largest_axis_correction_deg", cprog.largest_axis_correction_rad * core::units::kRadToDeg},
      {"cycle_time_original_s", cycle_orig},
      {"cycle_time_compensated_program_s", cycle_prog},
      {"cycle_time_change_percent", cycle_orig > 0 ? 100.0 * (cycle_prog - cycle_orig) / cycle_orig : 0.0},
      {"within_limits", program_within},
      {"tcp_form", tcp_cycles ? nlohmann::json{{"file", "compensated_tcp.ngc"},
                                               {"reference", "original_tcp.ngc"},
                                               {"cycle_time_original_s", tcp_cycles->first},
                                               {"cycle_time_compensated_s", tcp_cycles->second}}
                              : nlohmann::json(nullptr)},
      {"what", "the program read back, re-timed by vmsim's interpolator and run on the machine file's cascades; "
               "contour error against the original plan"}};
  report["limits"] = {{"compensated_within_limits", within},
                      {"original", limits_json(limits_before, machine)},
                      {"compensated", limits_json(limits_after, machine)}};
  report["setpoints"] = ns;
  files.push_back("report.json");
  report["files"] = files;
  if (render_error) report["render_error"] = *render_error;
  report["timings_s"] = {{"prepare", t_prepare}, {"compensate", t_comp}, {"write", t_write}, {"render", t_render},
                         {"program_check", t_check}, {"total", seconds_since(t_start)}};
  write_report(dir / "report.json", report);

  auto line = [five](const char* what, const Figures& b, const Figures& a) {
    std::printf("%-34s max %8.3f -> %8.3f um (%+.1f %%)   mean %8.3f -> %8.3f um (%+.1f %%)\n", what, b.max_mm * 1e3,
                a.max_mm * 1e3, b.max_mm > 0 ? 100 * (a.max_mm - b.max_mm) / b.max_mm : 0.0, b.mean_mm * 1e3,
                a.mean_mm * 1e3, b.mean_mm > 0 ? 100 * (a.mean_mm - b.mean_mm) / b.mean_mm : 0.0);
    if (five)
      std::printf("%-34s max %8.4f -> %8.4f deg          mean %8.4f -> %8.4f deg\n", "  tool axis orientation error",
                  b.orientation_max_rad * core::units::kRadToDeg, a.orientation_max_rad * core::units::kRadToDeg,
                  b.orientation_mean_rad * core::units::kRadToDeg, a.orientation_mean_rad * core::units::kRadToDeg);
  };
  std::printf("job %s: %lld setpoints, %zu iterations (buffer m = %d), compensated in %.2f s\n", job.name.c_str(),
              static_cast<long long>(ns), res.iterations.size() - 1, res.buffer_samples, t_comp);
  line(models.any() ? "contour error, identified model" : "contour error, predicted", pred_before, pred_after);
  if (mach_before) line("contour error, machine cascades", *mach_before, *mach_after);
  line("compensated program on the machine", orig_machine, prog_machine);
  // The program form moves only the programmed points (arcs keep their shape between corrected ends), so it can cut
  // worse than the original where the correction varies along a move: say so rather than let it go to a machine.
  // Worse: a larger mean, or a largest error grown by more than 5 % (the max sits at friction glitches that move by
  // a fraction of a per cent from run to run of a correction).
  if (prog_machine.max_mm > 1.05 * orig_machine.max_mm || prog_machine.mean_mm > orig_machine.mean_mm)
    std::fprintf(stderr,
                 "vmsim: warning: the compensated program cuts worse than the original on the machine model (max "
                 "%.3f -> %.3f um, mean %.3f -> %.3f um); send the dense form (--dense-program) or the compensated "
                 "setpoints instead\n",
                 orig_machine.max_mm * 1e3, prog_machine.max_mm * 1e3, orig_machine.mean_mm * 1e3,
                 prog_machine.mean_mm * 1e3);
  std::printf("compensated program: %d blocks for %zu moves, cycle time %.3f s (original %.3f s, %+.2f %%)\n",
              cprog.blocks, program.moves.size(), cycle_prog, cycle_orig,
              cycle_orig > 0 ? 100.0 * (cycle_prog - cycle_orig) / cycle_orig : 0.0);
  if (tcp_cycles)
    std::printf("tool-centre-point G-code: compensated_tcp.ngc %.3f s, original_tcp.ngc %.3f s ([job] tcp = true)\n",
                tcp_cycles->second, tcp_cycles->first);
  for (const auto& c : limits_after)
    if (!c.within())
      std::printf("axis %s: compensated setpoints exceed a limit at %d samples, first at t = %.3f s\n", c.axis.c_str(),
                  c.samples_over, c.first_over_s);
  std::printf("compensated setpoints within every axis limit: %s\nwrote %s (%s)\n", within ? "yes" : "NO",
              dir.string().c_str(), fmt::format("{}", fmt::join(files, ", ")).c_str());
  return 0;
}

}  // namespace vmsim::app
