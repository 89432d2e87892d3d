#include "sim/job_program.hpp"

#include "core/error.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"
#include "program/sinumerik.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>

namespace vmsim::sim {

namespace {

// The machine's kinematics as the Sinumerik reader needs them at TRAORI/TRAFOOF switches and CYCLE800 swivels
// (program/sinumerik.hpp). Joint coordinates are the axes themselves: the reader's tool length offset is zero.
class ChainTransform final : public program::MachineTransform {
 public:
  explicit ChainTransform(const core::Machine& machine) : machine_(machine), kin_(motion::make_kinematics(machine)) {}

  Eigen::Vector3d tip_of_joint(const core::Vec6& joint) const override {
    return kin_->forward(to_axes(joint), 0.0).tip_mm;
  }
  core::Vec6 joint_of_tip(const core::Vec6& tcp) const override {
    return to_vec6(kin_->place_tip(tcp.head<3>(), 0.0, to_axes(tcp)), tcp);
  }
  Eigen::Vector3d rotary_for_tool_axis(const Eigen::Vector3d& tool_axis, const core::Vec6& near) const override {
    const Eigen::VectorXd q = to_axes(near);
    const motion::ToolPose here = kin_->forward(q, 0.0);
    return to_vec6(kin_->inverse(motion::ToolPose{here.tip_mm, tool_axis.normalized()}, 0.0, q), near).tail<3>();
  }

 private:
  Eigen::VectorXd to_axes(const core::Vec6& v) const {
    Eigen::VectorXd q(static_cast<Eigen::Index>(machine_.axes.size()));
    for (std::size_t i = 0; i < machine_.axes.size(); ++i)
      q[static_cast<Eigen::Index>(i)] = v[machine_.axes[i].program_axis];
    return q;
  }
  core::Vec6 to_vec6(const Eigen::VectorXd& q, core::Vec6 base) const {
    for (std::size_t i = 0; i < machine_.axes.size(); ++i)
      base[machine_.axes[i].program_axis] = q[static_cast<Eigen::Index>(i)];
    return base;
  }
  const core::Machine& machine_;
  std::unique_ptr<motion::Kinematics> kin_;
};

// A CL tool's geometry as a job tool: ball when r = d/2, flat when r = 0, else bull-nose; flute length the program's
// tool length, else 2 d.
core::ToolSpec program_tool_spec(double d, double r, double length_mm) {
  core::ToolSpec t;
  t.diameter_mm = d;
  if (std::abs(r - d / 2) <= 1e-9 * d) {
    t.shape = core::ToolShape::Ball;
    t.corner_radius_mm = d / 2;
  } else if (r <= 1e-9 * d) {
    t.shape = core::ToolShape::Flat;
    t.corner_radius_mm = 0;
  } else {
    t.shape = core::ToolShape::BullNose;
    t.corner_radius_mm = r;
  }
  t.flute_length_mm = length_mm > 0 ? length_mm : 2 * d;
  t.length_mm = std::max(50.0, t.flute_length_mm);
  return t;
}

const char* shape_word(core::ToolShape s) {
  return s == core::ToolShape::Ball ? "ball" : s == core::ToolShape::Flat ? "flat" : "bull-nose";
}

}  // namespace

std::optional<JobCurve> read_job_curve(const core::Job& job) {
  if (!job.program_file.empty() || !job.feedplan || !job.feedplan->nurbs) return std::nullopt;
  const core::FeedPlanSpec& spec = *job.feedplan;
  if (!spec.max_feed_mm_per_s)
    throw core::Error(
        core::located(job.file.string(), 0, "[feedplan] max_feed_mm_per_s is required with a [feedplan.nurbs] path"));
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
  popt.dialect = program::parse_dialect(job.program_dialect);
  popt.lenient = job.program_lenient;
  if (!job.program_units.empty())
    popt.program_units = job.program_units == "inch" ? program::LengthUnit::Inch : program::LengthUnit::Mm;
  if (job.start_mm) popt.start_mm = std::array<double, 3>{job.start_mm->x(), job.start_mm->y(), job.start_mm->z()};
  std::unique_ptr<ChainTransform> transform;
  if (job.machine.kinematics == "chain" &&
      program::program_dialect(job.program_file, popt.dialect) == program::Dialect::Sinumerik) {
    transform = std::make_unique<ChainTransform>(job.machine);
    popt.machine = transform.get();
  }
  core::ToolPath tp = program::read_program(job.program_file, popt);
  // [job] tcp: the G-code's X Y Z are the tip in the workpiece frame (CL moves carry their tool axis and ignore it;
  // Sinumerik programs say it themselves with TRAORI, so it only adds).
  if (job.tcp)
    for (core::Move& m : tp.moves) m.tcp = true;
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

std::optional<std::string> use_program_tool(core::Job& job) {
  // Only CL programs carry their tool; others are not read twice.
  if (job.program_file.empty() ||
      program::program_dialect(job.program_file, program::parse_dialect(job.program_dialect)) != program::Dialect::Apt)
    return std::nullopt;
  const core::ToolPath tp = read_job_program(job);
  const double d = tp.tool_diameter_mm, r = tp.tool_corner_radius_mm;
  if (tp.tool_line == 0 || !(d > 0)) return std::nullopt;
  if (!job.tools.empty()) return std::nullopt;  // [[tools]]: the job describes every tool itself
  if (job.tool_given) {
    // The job's tool cuts; say so when the program names another (a stand-in, or a tool change the job ignores).
    if (std::abs(job.tool.diameter_mm - d) <= 1e-6 && std::abs(job.tool.corner_radius_mm - r) <= 1e-6)
      return std::nullopt;
    return fmt::format("{}:{}: the program's tool is D{:.4g} R{:.4g} mm; the job's [tool] D{:.4g} R{:.4g} mm cuts",
                       job.program_file.string(), tp.tool_line, d, r, job.tool.diameter_mm, job.tool.corner_radius_mm);
  }
  if (tp.program_tools.size() > 1) {
    // Tool changes (TLDATA/, CUTTER/, LOAD/TOOL): one [[tools]] per program tool, by the moves' tool numbers.
    std::string list;
    for (const core::ProgramTool& pt : tp.program_tools) {
      core::ToolSpec t = program_tool_spec(pt.diameter_mm, pt.corner_radius_mm, pt.length_mm);
      t.number = pt.number;
      job.tools.push_back(t);
      std::string lines;
      for (int l : pt.stretch_lines) lines += fmt::format("{}{}", lines.empty() ? "" : ", ", l);
      list += fmt::format("\n  T{}: {} D{:.4g} R{:.4g} mm, flute length {:.4g} mm (line{} {})", pt.number,
                          shape_word(t.shape), t.diameter_mm, t.corner_radius_mm, t.flute_length_mm,
                          pt.stretch_lines.size() > 1 ? "s" : "", lines);
    }
    job.tool = job.tools.front();
    const bool numbered = tp.program_tools.front().numbered_by_program;
    job.tool_from_program =
        fmt::format("{}: {} tools{}", job.program_file.string(), tp.program_tools.size(),
                    numbered ? " numbered by LOAD/TOOL" : " numbered in order of first appearance (no LOAD/TOOL)");
    return fmt::format(
        "{}: the job has no [tool]: the program changes tools; each move is cut by the tool in effect "
        "at it ({}):{}",
        job.program_file.string(), numbered ? "numbered by its LOAD/TOOL" : "numbered in order of first appearance",
        list);
  }
  const core::ToolSpec t = program_tool_spec(d, r, tp.tool_length_mm);
  job.tool = t;
  job.tool_from_program = fmt::format("{}:{}", job.program_file.string(), tp.tool_line);
  return fmt::format("{}:{}: the job has no [tool]: the program's {} D{:.4g} R{:.4g} mm, flute length {:.4g} mm",
                     job.program_file.string(), tp.tool_line, shape_word(t.shape), d, t.corner_radius_mm,
                     t.flute_length_mm);
}

}  // namespace vmsim::sim
