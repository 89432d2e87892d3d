#include "sim/job_program.hpp"

#include "core/error.hpp"
#include "program/program.hpp"

namespace vmsim::sim {

std::optional<JobCurve> read_job_curve(const core::Job& job) {
  if (!job.program_file.empty() || !job.feedplan || !job.feedplan->nurbs) return std::nullopt;
  const core::FeedPlanSpec& spec = *job.feedplan;
  if (!spec.max_feed_mm_per_s)
    throw core::Error(core::located(job.file.string(), 0,
                                    "[feedplan] max_feed_mm_per_s is required with a [feedplan.nurbs] path"));
  JobCurve c;
  c.curve = motion::read_nurbs_csv(spec.nurbs->control_points, spec.nurbs->knots, spec.nurbs->degree);
  motion::NurbsPathOptions no;
  no.feed_mm_per_min = *spec.max_feed_mm_per_s * 60.0;
  c.path = motion::nurbs_to_path(c.curve, no);
  return c;
}

core::ToolPath read_job_program(const core::Job& job) {
  if (auto c = read_job_curve(job)) return std::move(c->path.program);
  program::ProgramOptions popt;
  popt.tool_table = job.tool_table_file;
  popt.no_motion_mcodes = job.no_motion_mcodes;
  if (job.start_mm) popt.start_mm = std::array<double, 3>{job.start_mm->x(), job.start_mm->y(), job.start_mm->z()};
  core::ToolPath tp = program::read_program(job.program_file, popt);
  // [job] tcp: the G-code's X Y Z are the tip in the workpiece frame (CL moves carry their tool axis and ignore it).
  for (core::Move& m : tp.moves) m.tcp = job.tcp;
  if (job.start_mm && !tp.moves.empty()) {
    core::Move& first = tp.moves.front();
    first.start.head<3>() = *job.start_mm;
    // initial_position has no tool length offset applied: the axes sit at the tip plus the first move's offset.
    tp.initial_position = first.start;
    tp.initial_position[core::kZ] += first.tool_length_offset_mm;
  } else if (job.start_mm) {
    tp.initial_position.head<3>() = *job.start_mm;
  }
  return tp;
}

}  // namespace vmsim::sim
