#pragma once
// The memory this process may still take: what the kernel says is available (MemAvailable of /proc/meminfo) and,
// when the process runs in a control group with a memory limit (containers, batch systems), that limit less the
// group's usage (cgroup v2 memory.max - memory.current, or v1 memory.limit_in_bytes - memory.usage_in_bytes).
// vmsim's guards compare their estimates with it before each stage that allocates (issue 18).
#include <string>

namespace vmsim::core {

struct AvailableMemory {
  double bytes = 0;    // infinity when nothing could be read (not Linux): the guards then rely on their fixed limits
  std::string source;  // which figure set it, for messages: "MemAvailable", "cgroup v2 memory.max", ...
};

// Test hook: the environment variable VMSIM_TEST_AVAILABLE_BYTES, when set, is returned instead (a number of bytes;
// anything else throws core::Error naming it), so tests can reach the guards' refusals on any machine.
AvailableMemory available_memory();

// "3.2 GB" / "640 MB": sizes in messages.
std::string format_bytes(double bytes);

}  // namespace vmsim::core
