#include "sim/compensate.hpp"
#include "sim/drive_checks.hpp"

#include "core/error.hpp"
#include "core/timing.hpp"
#include "core/units.hpp"
#include "motion/kinematics.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <optional>

namespace vmsim::sim {

namespace {

using core::Clock;
using core::seconds_since;
using Eigen::Index;

void check_options(const CompensateJobOptions& o) {
  const methods::CompensateOptions& m = o.method;
  if (m.buffer_samples < 0 || (m.buffer_samples > 0 && m.buffer_samples % 2 == 0))
    throw core::Error(
        fmt::format("--buffer {}: expected an odd number of samples (or 0: automatic)", m.buffer_samples));
  if (m.max_iterations < 0 || m.max_iterations > 50)
    throw core::Error(fmt::format("--iterations {}: expected 0 to 50", m.max_iterations));
  if (!(m.smoothing_samples >= 0.0 && m.smoothing_samples <= 1000.0))
    throw core::Error(fmt::format("--smoothing {}: expected 0 to 1000 samples", m.smoothing_samples));
}

// A program text read as vmsim reads the job's program (its tool table, start, M codes, tcp), through a temporary
// file: the readers take files (G-code subroutines are files beside the program). `name` stands for it in errors.
core::ToolPath read_program_text(core::Job job, const std::string& text, const std::string& extension,
                                 const std::string& name) {
  std::string path = (std::filesystem::temp_directory_path() / ("vmsim-program-XXXXXX." + extension)).string();
  const int fd = mkstemps(path.data(), static_cast<int>(extension.size()) + 1);
  if (fd < 0)
    throw core::Error(
        fmt::format("{}: cannot create a temporary file to read it back: {}", name, std::strerror(errno)));
  struct Remove {
    std::string p;
    ~Remove() { std::remove(p.c_str()); }
  } remove{path};
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n <= 0) {
      ::close(fd);
      throw core::Error(fmt::format("{}: cannot write it to {} to read it back", name, path));
    }
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  job.program_file = path;
  try {
    return read_job_program(job);
  } catch (const core::Error& e) {
    throw core::Error(fmt::format("{} read back: {}", name, e.what()));
  }
}

// Tip (and, five-axis, tool axis) figures of actual axis rows against the plan.
ContourFigures figures_of(const methods::CompensationResult& res, const motion::Kinematics& kin,
                          const Eigen::MatrixXd& rows, const Eigen::VectorXd& tlo, const core::Setpoints& sp,
                          const core::ToolPath& program) {
  const Eigen::MatrixXd tips = methods::tool_tips(kin, rows, tlo);
  if (!res.orientation) return contour_figures(res.command_tip, tips, sp, program);
  const Eigen::MatrixXd axes = methods::tool_axes(kin, rows, tlo);
  return contour_figures(res.command_tip, tips, sp, program, &res.command_axis, &axes);
}

bool within(const std::vector<methods::AxisLimitCheck>& checks) {
  return std::all_of(checks.begin(), checks.end(), [](const auto& c) { return c.within(); });
}

nlohmann::json figures_json(const ContourFigures& before, const ContourFigures& after) {
  auto pct = [](double b, double a) { return b > 0 ? 100.0 * (a - b) / b : 0.0; };
  nlohmann::json j = {{"before", {{"max_mm", before.max_mm}, {"mean_mm", before.mean_mm}, {"rms_mm", before.rms_mm}}},
                      {"after", {{"max_mm", after.max_mm}, {"mean_mm", after.mean_mm}, {"rms_mm", after.rms_mm}}},
                      {"change_percent",
                       {{"max", pct(before.max_mm, after.max_mm)},
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

// The method's description and the iterations.
void method_json(const CompensateJobResult& r, const JobAxisModels& models, nlohmann::json& rep) {
  rep["prediction"] = models.any() ? "identified transfer functions for " +
                                         fmt::format("{}", fmt::join(models.identified_axes, " ")) +
                                         ", the machine file's cascades for the other axes"
                                   : "the machine file's cascades ([axes.drive])";
  rep["method"] = {
      {"foot_points",
       "the predictive-compensation paper section 4: nearest command point in a buffer of m samples, then the adjacent "
       "segment"},
      {"buffer_samples", r.compensation.buffer_samples},
      {"correction",
       "eq. 23: each setpoint moved by the predicted contour error at its place on the path, repeated while the mean "
       "falls"},
      {"smoothing_samples", r.options.smoothing_samples},
      {"limits",
       "the correction is faded out (smoothly, over +-" + std::to_string(r.options.limit_window_samples) +
           " samples and more) where the corrected setpoints would break an axis velocity, acceleration or jerk limit"},
      {"measured_by", "core/contour (exact foot point on the planned path), cutting moves only"}};
  const bool five = r.compensation.orientation;
  if (five)
    rep["method"]["five_axis"] =
        "tool tip and tool axis by the forward transform; the tool axis' error against the commanded axis at the same "
        "foot point corrected with the tip's; the corrected pose back to the joints through the chain's closed-form "
        "inverse (exact for corrections of any size, continuous rotary angles), not its Jacobian";
  nlohmann::json its = nlohmann::json::array();
  for (const auto& it : r.compensation.iterations) {
    nlohmann::json j = {
        {"max_mm", it.max_mm}, {"mean_mm", it.mean_mm}, {"accepted", it.accepted}, {"faded_samples", it.faded_samples}};
    if (five) {
      j["orientation_max_deg"] = it.orientation_max_rad * core::units::kRadToDeg;
      j["orientation_mean_deg"] = it.orientation_mean_rad * core::units::kRadToDeg;
    }
    its.push_back(j);
  }
  rep["iterations"] = its;
}

void results_json(const core::Job& job, CompensateJobResult& r) {
  nlohmann::json& rep = r.report;
  rep["contour_error"]["predicted"] = figures_json(r.predicted_before, r.predicted_after);
  if (r.machine_before) rep["contour_error"]["on_machine_cascades"] = figures_json(*r.machine_before, *r.machine_after);
  rep["contour_error"]["compensated_program_on_machine"] = figures_json(r.original_on_machine, r.program_on_machine);
  const double co = r.cycle_time_original_s, cp = r.cycle_time_program_s;
  const auto& t = r.tcp_cycle_times_s;
  rep["compensated_program"] = {
      {"file", r.program_file},
      {"verdict", r.program_accepted
                      ? (r.fade_rounds > 0 ? "not worse, with the correction faded where it cut worse" : "not worse")
                      : "rejected: cuts worse than the original on the machine model"},
      {"fade_rounds", r.fade_rounds},
      {"faded_setpoints", r.faded_setpoints},
      {"blocks", r.compensated_program.blocks},
      {"original_moves", r.program.moves.size()},
      {"largest_tip_correction_mm", r.compensated_program.largest_tip_correction_mm},
      {"largest_axis_correction_deg", r.compensated_program.largest_axis_correction_rad * core::units::kRadToDeg},
      {"cycle_time_original_s", co},
      {"cycle_time_compensated_program_s", cp},
      {"cycle_time_change_percent", co > 0 ? 100.0 * (cp - co) / co : 0.0},
      {"within_limits", r.program_within_limits},
      {"tcp_form",
       t ? nlohmann::json{{"file", r.program_accepted ? "compensated_tcp.ngc" : "compensated_tcp_rejected.ngc"},
                          {"reference", "original_tcp.ngc"},
                          {"cycle_time_original_s", t->first},
                          {"cycle_time_compensated_s", t->second}}
         : nlohmann::json(nullptr)},
      {"what",
       "the program read back, re-timed by vmsim's interpolator and run on the machine file's cascades; "
       "contour error against the original plan"}};
  rep["limits"] = {{"compensated_within_limits", r.within_limits},
                   {"original", limits_json(r.limits_before, job.machine)},
                   {"compensated", limits_json(r.limits_after, job.machine)}};
  rep["setpoints"] = r.interp.setpoints.samples();
}

// The compensated program in its forms: the original's moves with corrected points, the tool-centre-point G-code
// (five-axis CL programs, with the original in the same form as its reference), the dense form.
// `carried`: the setpoints whose correction the programs carry (the compensated ones, or faded, see compensate_job).
void write_programs(const core::Job& job, const CompensateJobOptions& options, const motion::Kinematics& kin,
                    const core::ToolPath& axis_path, const Eigen::MatrixXd& carried, CompensateJobResult& r) {
  const core::Setpoints& sp = r.interp.setpoints;
  methods::CompensatedProgramInput pin;
  pin.program = &r.program;
  pin.axis_path = &axis_path;
  pin.setpoints = &sp;
  pin.compensated = &carried;
  pin.command_tip = &r.compensation.command_tip;
  pin.machine = &job.machine;
  pin.kinematics = &kin;
  pin.title = job.name;
  r.compensated_program = methods::write_compensated_program(pin);
  if (r.compensation.orientation && r.compensated_program.extension == "cl") {
    r.tcp_program = methods::write_compensated_tcp_gcode(pin);
    methods::CompensatedProgramInput orig = pin;
    orig.compensated = &sp.position;
    orig.title = job.name + ", original, no correction: the reference for compensated_tcp.ngc";
    r.original_tcp_text = methods::write_compensated_tcp_gcode(orig).text;
  }
  if (options.dense_program)
    r.dense_program_text = methods::write_dense_program(r.compensation.setpoints, r.tool_length_offset_mm, job.machine,
                                                        kin, sp.period_s, r.compensation.orientation, job.name);
}

// End to end, as a user would run it: the compensated program read back, re-timed by the chain's interpolator (under
// the original's feed plan, if any) and run on the machine's drives; its contour error against the ORIGINAL plan,
// its cycle time against the original's. `machine`: the chain without identified models.
void check_program(const core::Job& job, const Chain& machine, const motion::Kinematics& kin,
                   const core::ToolPath& axis_path, CompensateJobResult& r) {
  const core::Setpoints& sp = r.interp.setpoints;
  const motion::FeedCeiling ceiling = machine.feed_ceiling(r.program);
  const std::string cname = "compensated." + r.compensated_program.extension;
  const core::ToolPath cprogram =
      read_program_text(job, r.compensated_program.text, r.compensated_program.extension, cname);
  const motion::InterpResult cir = machine.interpolate(cprogram, ceiling);
  const Eigen::MatrixXd cactual = machine.simulate(cir.setpoints).position;
  r.program_on_machine =
      figures_of(r.compensation, kin, cactual, tool_length_offsets(cprogram, cir.setpoints), cir.setpoints, cprogram);
  if (r.original_on_machine.samples == 0)  // the same for every round of compensate_job's fading
    r.original_on_machine = r.machine_before ? *r.machine_before
                                             : figures_of(r.compensation, kin, machine.simulate(sp).position,
                                                          r.tool_length_offset_mm, sp, r.program);
  r.limits_program = methods::check_axis_limits(cir.setpoints.position, sp.period_s, job.machine);
  r.program_within_limits = within(r.limits_program);
  r.cycle_time_original_s = sp.duration_s();
  r.cycle_time_program_s = cir.setpoints.duration_s();
  if (!r.tcp_program) return;
  // The tool-centre-point forms through vmsim's interpreter of such programs ([job] tcp, the tool starting at the
  // program's first pose): original and compensated timed alike.
  core::Job tj = job;
  tj.tcp = true;
  const Index na = static_cast<Index>(job.machine.axes.size());
  Eigen::VectorXd q0(na);
  for (Index a = 0; a < na; ++a)
    q0[a] = axis_path.initial_position[job.machine.axes[static_cast<std::size_t>(a)].program_axis];
  tj.start_mm = kin.forward(q0, r.tool_length_offset_mm[0]).tip_mm;
  auto cycle_of = [&](const std::string& text, const std::string& name) {
    return machine.interpolate(read_program_text(tj, text, "ngc", name), ceiling).setpoints.duration_s();
  };
  r.tcp_cycle_times_s = std::make_pair(cycle_of(*r.original_tcp_text, "original_tcp.ngc"),
                                       cycle_of(r.tcp_program->text, "compensated_tcp.ngc"));
}

// How much worse than the original the program may cut and still count as "not worse": the figures' own resolution
// (report.json's contour errors are exact to far below; a program that carries no correction somewhere re-times
// there to within rounding of the original).
constexpr double kNotWorseMm = 1e-6;
constexpr double kNotWorseRad = 1e-6 * core::units::kDegToRad;
constexpr int kMaxFadeRounds = 8;
constexpr Index kFadeWindowSamples = 25;  // first round's half-width; doubled every round

bool not_worse(const ContourFigures& original, const ContourFigures& program) {
  bool ok = program.max_mm <= original.max_mm + kNotWorseMm && program.mean_mm <= original.mean_mm + kNotWorseMm;
  if (original.orientation && program.orientation)
    ok = ok && program.orientation_max_rad <= original.orientation_max_rad + kNotWorseRad &&
         program.orientation_mean_rad <= original.orientation_mean_rad + kNotWorseRad;
  return ok;
}

// The original setpoints (the plan's foot segments) where the program's run exceeds the original's largest error, tip
// or tool axis, on the rows counted.
std::vector<Index> places_over(const ContourFigures& original, const ContourFigures& program, Index ns) {
  std::vector<Index> out;
  for (Index k = 0; k < program.ce.signed_mm.size(); ++k) {
    if (!program.counted[static_cast<std::size_t>(k)]) continue;
    const bool tip = std::abs(program.ce.signed_mm[k]) > original.max_mm + kNotWorseMm;
    const bool axis = original.orientation && program.orientation &&
                      program.angle_rad[k] > original.orientation_max_rad + kNotWorseRad;
    if (tip || axis) out.push_back(std::clamp<Index>(program.ce.foot_segment[k], 0, ns - 1));
  }
  return out;
}

// The compensated program, written, read back and run on the machine model (check_program). Where it cuts worse than
// the original (not_worse), the correction it carries is faded out around the places where its error exceeds the
// original's largest (zero over +-w setpoints, back to full over w more; w doubled each round), up to kMaxFadeRounds:
// a program that carries no correction there is the original there. What still cuts worse is rejected: the program
// with the whole correction (and its figures) is written as compensated_rejected.<extension>, not as the program to
// send (report.json and a warning say why).
void write_and_check_program(const core::Job& job, const CompensateJobOptions& options, const Chain& machine,
                             const motion::Kinematics& kin, const core::ToolPath& axis_path, CompensateJobResult& r) {
  const core::Setpoints& sp = r.interp.setpoints;
  const Index ns = sp.samples();
  const Eigen::MatrixXd delta = r.compensation.setpoints - sp.position;
  Eigen::VectorXd weight = Eigen::VectorXd::Ones(ns);
  Eigen::MatrixXd carried = r.compensation.setpoints;
  std::optional<CompensateJobResult> whole;  // round 0: the program with the whole correction
  for (int round = 0;; ++round) {
    write_programs(job, options, kin, axis_path, carried, r);
    check_program(job, machine, kin, axis_path, r);
    r.fade_rounds = round;
    r.program_accepted = not_worse(r.original_on_machine, r.program_on_machine);
    if (r.program_accepted) break;
    if (round == 0) whole = r;
    if (round == kMaxFadeRounds) {
      // Rejected: the program with the whole correction is the one to look at (fading gave up some of its gain
      // without making it not worse); its figures with it.
      const int rounds = r.fade_rounds;
      r = std::move(*whole);
      r.fade_rounds = rounds;
      weight.setOnes();
      break;
    }
    const std::vector<Index> over = places_over(r.original_on_machine, r.program_on_machine, ns);
    if (over.empty()) {  // worse on the mean only: a local fade does not answer that
      if (round > 0) {
        const int rounds = r.fade_rounds;
        r = std::move(*whole);
        r.fade_rounds = rounds;
        weight.setOnes();
      }
      break;
    }
    const Index w = kFadeWindowSamples << round;
    for (const Index at : over)
      for (Index i = std::max<Index>(0, at - 2 * w); i <= std::min(ns - 1, at + 2 * w); ++i)
        weight[i] = std::min(weight[i], std::clamp(static_cast<double>(std::abs(i - at) - w) / w, 0.0, 1.0));
    carried = sp.position + weight.asDiagonal() * delta;
  }
  r.faded_setpoints = r.program_accepted ? (weight.array() < 1.0).count() : 0;
  const std::string ext = r.compensated_program.extension;
  r.program_file = r.program_accepted ? "compensated." + ext : "compensated_rejected." + ext;
}

}  // namespace

ContourFigures contour_figures(const Eigen::MatrixXd& command_tip, const Eigen::MatrixXd& actual_tip,
                               const core::Setpoints& sp, const core::ToolPath& program,
                               const Eigen::MatrixXd* command_axis, const Eigen::MatrixXd* actual_axis) {
  ContourFigures f;
  f.ce = motion::contour_error(command_tip, actual_tip);
  f.orientation = command_axis && actual_axis;
  if (f.orientation) {
    const Index rows = actual_tip.rows(), ns = command_tip.rows();
    Eigen::VectorXd param(rows);
    for (Index k = 0; k < rows; ++k) {
      const Index i = std::clamp<Index>(f.ce.foot_segment[k], 0, std::max<Index>(ns - 2, 0));
      const Eigen::Vector3d a = command_tip.row(i).transpose(),
                            b = command_tip.row(std::min(i + 1, ns - 1)).transpose();
      const double l2 = (b - a).squaredNorm();
      const double t = l2 > 0 ? std::clamp((actual_tip.row(k).transpose() - a).dot(b - a) / l2, 0.0, 1.0) : 0.0;
      param[k] = static_cast<double>(i) + t;
    }
    f.angle_rad = methods::axis_angles(methods::axes_at(*command_axis, param), *actual_axis);
  }
  double sum = 0, sum2 = 0, osum = 0;
  f.counted.assign(static_cast<std::size_t>(f.ce.signed_mm.size()), 0);
  for (Index k = 0; k < f.ce.signed_mm.size(); ++k) {
    const int mi = sp.move_index[std::min(k, sp.samples() - 1)];
    if (mi < 0 || program.moves[static_cast<std::size_t>(mi)].rapid) continue;
    f.counted[static_cast<std::size_t>(k)] = 1;
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

CompensateJobResult compensate_job(const core::Job& job, const CompensateJobOptions& options,
                                   core::Progress& progress) {
  const auto t_start = Clock::now();
  check_options(options);
  // The job's chain, with its identified models (or the option's), and the same chain on the machine file's drives.
  // A departure: both run the drives' own gains. A gain schedule belongs to the original setpoints, which the
  // compensation moves by microns (methods/oga_schedule checks them within 1e-6 mm); report.json says so.
  ChainOptions copt;
  copt.ignore_gain_schedule = true;
  copt.axis_models_file = options.axis_models_file;
  const Chain chain(job, copt);
  core::Job machine_job = job;
  machine_job.axis_models_file.reset();
  ChainOptions mopt;
  mopt.ignore_gain_schedule = true;
  const Chain machine(machine_job, mopt);
  if (chain.curve())
    throw core::Error(core::located(job.file.string(), 0,
                                    "the job's path is a [feedplan.nurbs] curve: vmsim "
                                    "compensate corrects a program ([job] program)"));
  CompensateJobResult r;
  r.identified = chain.axis_models().any();
  progress.stage(job.name + ": interpolation");
  r.program = read_job_program(job);
  const core::ToolPath axis_path = motion::toolpath_in_axis_space(r.program, job.machine);
  r.interp = chain.interpolate(r.program);
  const core::Setpoints& sp = r.interp.setpoints;
  const auto kin = motion::make_kinematics(job.machine);
  r.tool_length_offset_mm = tool_length_offsets(r.program, sp);
  progress.done();
  r.timings["prepare"] = seconds_since(t_start);
  // The drives the predictions run, checked before they run (an unstable loop is refused).
  const DriveChecks drive_checks = check_drives_before(job.machine, sp, chain.cascade_axes());

  // Predictions: with the job's models, and with the machine file's cascades (the "machine" the program runs on).
  auto predictor = [&sp](const Chain& c) {
    return [&sp, &c](const Eigen::MatrixXd& setpoints) {
      core::Setpoints s = sp;
      s.position = setpoints;
      return c.simulate(s).position;
    };
  };
  methods::CompensationProblem problem;
  problem.setpoints = &sp;
  problem.kinematics = kin.get();
  problem.tool_length_offset_mm = r.tool_length_offset_mm;
  problem.predict = predictor(chain);
  r.options = options.method;
  r.options.limits = &job.machine;
  progress.stage(job.name + ": compensation");
  auto t0 = Clock::now();
  r.compensation = methods::compensate_contour(problem, r.options);
  r.timings["compensate"] = seconds_since(t0);
  r.options.limits = nullptr;  // refers to the caller's job
  progress.done();

  const Eigen::VectorXd& tlo = r.tool_length_offset_mm;
  r.predicted_before = figures_of(r.compensation, *kin, r.compensation.predicted_before, tlo, sp, r.program);
  r.predicted_after = figures_of(r.compensation, *kin, r.compensation.predicted_after, tlo, sp, r.program);
  if (r.identified) {
    const auto on_machine = predictor(machine);
    r.machine_before = figures_of(r.compensation, *kin, on_machine(sp.position), tlo, sp, r.program);
    r.machine_after = figures_of(r.compensation, *kin, on_machine(r.compensation.setpoints), tlo, sp, r.program);
  }
  r.limits_before = methods::check_axis_limits(sp.position, sp.period_s, job.machine);
  r.limits_after = methods::check_axis_limits(r.compensation.setpoints, sp.period_s, job.machine);
  r.within_limits = within(r.limits_after);

  progress.stage(job.name + ": the compensated program, read back and re-timed");
  t0 = Clock::now();
  write_and_check_program(job, options, machine, *kin, axis_path, r);
  r.timings["program_check"] = seconds_since(t0);
  progress.done();
  method_json(r, chain.axis_models(), r.report);
  results_json(job, r);
  r.report["drive_checks"] = drive_checks.axes;
  core::Warnings warnings = drive_checks.warnings;
  if (!r.program_accepted)
    warnings.push_back(
        {"compensated_program_worse", r.program_file,
         fmt::format(
             "the compensated program cuts worse than the original on the machine model (max {:.4f} -> {:.4f} "
             "um, mean {:.4f} -> {:.4f} um; {} rounds of fading its correction where it cut worse did not bring it "
             "within the original's figures): written, with the whole correction, as {}, "
             "not as the program to send; send the compensated setpoints (compensated_setpoints.csv) or the dense "
             "form (--dense-program) instead",
             r.original_on_machine.max_mm * 1e3, r.program_on_machine.max_mm * 1e3, r.original_on_machine.mean_mm * 1e3,
             r.program_on_machine.mean_mm * 1e3, r.fade_rounds, r.program_file)});
  add_verdict(r.report, warnings);
  if (job.gain_schedule_file)
    r.report["gain_schedule"] = "not applied: the prediction runs the drives' own gains (" +
                                job.gain_schedule_file->string() + " belongs to the uncompensated setpoints)";
  return r;
}

}  // namespace vmsim::sim
