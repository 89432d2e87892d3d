#pragma once
// Time and memory of the running process, as reports state them: wall time of a stage, CPU time of every thread
// (the kernels run on all cores, so wall time stretches when the machine is shared), peak resident memory.
#include <chrono>

namespace vmsim::core {

using Clock = std::chrono::steady_clock;

// Wall time since t0 (s).
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// CPU time of every thread of this process so far (s).
double process_cpu_s();

// This process's peak resident memory so far (bytes; VmHWM on Linux, 0 where unknown).
double peak_rss_bytes();

}  // namespace vmsim::core
