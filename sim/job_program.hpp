#pragma once
// A job's program as every command reads it: the reader's options from the job, and the job's start position.
#include "core/job.hpp"
#include "core/toolpath.hpp"

namespace vmsim::sim {

// Tool tip path in the workpiece frame. With [job] start_mm the tool starts there: the reader starts from it (the
// program's first moves keep the axes they do not name), and the first move begins at that point (under the first
// move's tool length offset) instead of the program's own start.
core::ToolPath read_job_program(const core::Job& job);

}  // namespace vmsim::sim
