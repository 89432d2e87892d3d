#pragma once
// The motions `vmsim run --plan` computes -- the run's own and its reference's, as the run computes them (an actual
// motion streamed, sim/motion_stream.hpp), down to the sweeps -- once, for both its models: memory
// (sim/memory_plan.hpp) and time (sim/time_plan.hpp). Nothing is cut.
#include "core/job.hpp"
#include "core/progress.hpp"
#include "removal/swept_tool.hpp"

#include <optional>
#include <vector>

namespace vmsim::sim {

struct PlannedMotion {
  double samples = 0;     // setpoint samples (the programmed path's poses for motion = "program")
  bool turning = false;   // the track's tool axis turns
  bool streamed = false;  // an actual motion, streamed
  std::vector<removal::SweptTool> sweeps;
  double cpu_s = 0;  // the CPU computing it took (the process's, every thread)
};

// The job's motion of `kind` at feed_scale times its feeds (a gain schedule is ignored at other feeds, as for a
// reference). Throws core::Error as a run would.
PlannedMotion plan_motion(const core::Job& job, double feed_scale, core::RemovalSpec::Motion kind,
                          core::Progress& progress);

struct PlannedMotions {
  PlannedMotion own;
  // Reference kinds feed and program: the same job's motion at the reference's feeds or along its programmed path;
  // job: the reference job's own motion; stock, none: nothing.
  std::optional<PlannedMotion> reference;
};

// The run's motions. `own`, when given, is taken as the job's own motion instead of computing it again (a reference
// job's, which the plan of the job that refers to it has computed).
PlannedMotions plan_motions(const core::Job& job, double feed_scale, core::Progress& progress,
                            std::optional<PlannedMotion> own = {});

}  // namespace vmsim::sim
