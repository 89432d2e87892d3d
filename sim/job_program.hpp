#pragma once
// A job's program as every command reads it: the reader's options from the job, and the job's start position; or,
// for a job whose path is a [feedplan.nurbs] curve, the curve and the chain of quintic pieces the interpolator follows.
#include "core/job.hpp"
#include "core/toolpath.hpp"
#include "motion/nurbs.hpp"

#include <optional>
#include <string>

namespace vmsim::sim {

// A job's path given as a NURBS curve ([feedplan.nurbs], no [job] program; Chen et al. 2016's case): the curve, and
// its G2 chain of quintic pieces (motion::nurbs_to_path) whose bookkeeping moves run at [feedplan] max_feed_mm_per_s.
struct JobCurve {
  motion::NurbsCurve curve;
  motion::NurbsPath path;
};
// nullopt for a job with a [job] program. Throws core::Error naming the job file when the curve has no
// max_feed_mm_per_s, or naming the curve's files when they cannot be read.
std::optional<JobCurve> read_job_curve(const core::Job& job);

// Tool tip path in the workpiece frame. With [job] start_mm the tool starts there: the reader starts from it (the
// program's first moves keep the axes they do not name), and the first move begins at that point (under the first
// move's tool length offset) instead of the program's own start. A curve job's path: its chain's bookkeeping moves
// (read_job_curve; the interpolator follows the chain itself through sim::Chain).
core::ToolPath read_job_program(const core::Job& job);

// A job without [tool] or [[tools]] whose program names its tool (APT CUTTER/ or TLDATA/MILL): that tool becomes the
// job's (ball when r = d/2, flat when r = 0, else bull-nose; flute length the program's tool length, else 2 d). A
// program that changes tools (core::ToolPath::program_tools, more than one) gives one job.tools entry per tool,
// numbered as its moves' tool numbers (job.tool_from_program then says so; report.json "tools" source "program ...").
// Returns what was chosen and from where, for the user; with a [tool] that differs from the program's first, a note
// saying so (the job's cuts); nullopt when the program names no tool or names the job's.
std::optional<std::string> use_program_tool(core::Job& job);

}  // namespace vmsim::sim
