// vmsim interp JOB: the interpolator alone, so users can look at setpoints before the drives act on them.
#include "app/report.hpp"
#include "app/commands.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <optional>

namespace vmsim::app {

namespace {
void write_setpoints_csv(const std::filesystem::path& file, const core::Setpoints& sp, const core::Machine& machine) {
  core::AtomicFile out(file);
  auto& s = out.stream();
  s << "t_s";
  for (const auto& ax : machine.axes) s << ',' << ax.name << (ax.kind == core::AxisKind::Linear ? "_mm" : "_deg");
  s << ",path_speed_mm_per_s\n";
  std::string line;
  for (Eigen::Index k = 0; k < sp.samples(); ++k) {
    line = fmt::format("{:.6f}", k * sp.period_s);
    for (std::size_t a = 0; a < machine.axes.size(); ++a) {
      double v = sp.position(k, static_cast<Eigen::Index>(a));
      if (machine.axes[a].kind == core::AxisKind::Rotary) v *= 180.0 / 3.14159265358979323846;
      line += fmt::format(",{:.9f}", v);
    }
    line += fmt::format(",{:.6f}\n", sp.path_speed_mm_per_s[k]);
    s << line;
  }
  out.commit();
}
}  // namespace

int run_interp(const InterpArgs& args) {
  const core::Job job = core::load_job(args.job);
  // Locked before the run, written in staging, swapped into place whole (core/output_dir.hpp).
  std::optional<core::OutputDir> out;
  if (!args.summary_only) out.emplace(out_dir_or_default(args.out_dir, job.name, "interp"), "vmsim interp");
  sim::ChainOptions copt;
  copt.feed_scale = args.feed_scale.value_or(1.0);
  copt.ignore_gain_schedule = true;  // the drives do not run here
  const sim::Chain chain(job, copt);
  const core::ToolPath program = sim::read_job_program(job);
  const core::ToolPath path = motion::toolpath_in_axis_space(program, job.machine);
  const motion::InterpResult r = chain.interpolate(program);

  std::printf("job %s: %d moves, %d blends, %d exact stops, %lld setpoints at Te = %g ms\n", job.name.c_str(),
              r.stats.moves, r.stats.blends, r.stats.exact_stops, static_cast<long long>(r.setpoints.samples()),
              r.setpoints.period_s * 1e3);
  std::printf("cycle time: %.3f s\n", r.stats.cycle_time_s);
  // Feed reached on cutting moves (not rapids), against the highest programmed feed.
  double programmed = 0.0, reached = 0.0;
  for (const core::Move& m : path.moves)
    if (!m.rapid && m.feed_mode == core::FeedMode::UnitsPerMinute) programmed = std::max(programmed, m.feed_mm_per_min);
  for (Eigen::Index k = 0; k < r.setpoints.samples(); ++k) {
    const int mi = r.setpoints.move_index[k];
    if (mi < 0) continue;
    const core::Move& m = path.moves[static_cast<std::size_t>(mi)];
    if (!m.rapid && m.feed_mode == core::FeedMode::UnitsPerMinute)
      reached = std::max(reached, r.setpoints.path_speed_mm_per_s[k] * 60.0);
  }
  if (programmed > 0)
    std::printf("feed on cutting moves (G94): programmed up to %.0f mm/min, reached up to %.0f mm/min\n",
                programmed * chain.feed_scale(), reached);
  const core::AxisPeaks peaks = core::finite_difference_peaks(r.setpoints);
  std::printf("axis  peak velocity        peak acceleration      peak jerk              (finite differences; limit)\n");
  for (std::size_t a = 0; a < job.machine.axes.size(); ++a) {
    const core::MachineAxis& ax = job.machine.axes[a];
    const bool lin = ax.kind == core::AxisKind::Linear;
    // Trade units: m/min, m/s^2, m/s^3 for linear axes; deg/s, deg/s^2, deg/s^3 for rotary ones.
    const double fv = lin ? 0.06 : 180.0 / 3.14159265358979323846, fa = lin ? 1e-3 : fv, fj = fa;
    const char* uv = lin ? "m/min" : "deg/s";
    const char* ua = lin ? "m/s2" : "deg/s2";
    const char* uj = lin ? "m/s3" : "deg/s3";
    const auto i = static_cast<Eigen::Index>(a);
    std::printf("%-4s  %7.3f / %-7g %-5s %7.3f / %-7g %-6s %8.3f / %-7g %-6s\n", ax.name.c_str(),
                peaks.velocity[i] * fv, ax.max_velocity * fv, uv, peaks.acceleration[i] * fa, ax.max_acceleration * fa,
                ua, peaks.jerk[i] * fj, ax.max_jerk * fj, uj);
  }
  if (args.summary_only) return 0;
  write_setpoints_csv(out->path() / "setpoints.csv", r.setpoints, job.machine);
  out->commit();
  std::printf("wrote %s\n", (out->target() / "setpoints.csv").string().c_str());
  return 0;
}

}  // namespace vmsim::app
