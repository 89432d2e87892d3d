#include "core/memory.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace vmsim::core {

namespace {

// A number from a one-value file (cgroup files); NaN for "max", a missing or unreadable file.
double read_number(const std::string& file) {
  std::ifstream in(file);
  std::string s;
  if (!(in >> s) || s == "max") return NAN;
  try {
    return std::stod(s);
  } catch (...) {
    return NAN;
  }
}

double mem_available() {
  std::ifstream in("/proc/meminfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("MemAvailable:", 0) == 0) {
      std::istringstream ls(line.substr(13));
      double kb = NAN;
      ls >> kb;
      return kb * 1024.0;
    }
  }
  return NAN;
}

}  // namespace

AvailableMemory available_memory() {
  AvailableMemory m;
  // Test hook: the guards' refusals cannot be reached on a machine with much free memory otherwise. Read here only.
  if (const char* t = std::getenv("VMSIM_TEST_AVAILABLE_BYTES"); t && *t) {
    char* end = nullptr;
    const double v = std::strtod(t, &end);
    if (end == t || *end != '\0' || !(v >= 0) || !std::isfinite(v))
      throw Error(fmt::format("VMSIM_TEST_AVAILABLE_BYTES: expected a number of bytes >= 0, found \"{}\"", t));
    m.bytes = v;
    m.source = "VMSIM_TEST_AVAILABLE_BYTES, a test hook";
    return m;
  }
  m.bytes = INFINITY;
  const double avail = mem_available();
  if (std::isfinite(avail)) m.bytes = avail, m.source = "MemAvailable of /proc/meminfo";
  // The process's control groups: "0::/path" (v2), "N:memory:/path" or "N:...,memory,...:/path" (v1).
  std::ifstream cg("/proc/self/cgroup");
  std::string line;
  while (std::getline(cg, line)) {
    const auto c1 = line.find(':'), c2 = line.find(':', c1 + 1);
    if (c1 == std::string::npos || c2 == std::string::npos) continue;
    const std::string controllers = line.substr(c1 + 1, c2 - c1 - 1), path = line.substr(c2 + 1);
    double limit = NAN, usage = NAN;
    std::string what;
    if (controllers.empty()) {
      limit = read_number("/sys/fs/cgroup" + path + "/memory.max");
      usage = read_number("/sys/fs/cgroup" + path + "/memory.current");
      what = "cgroup v2 memory.max less memory.current";
    } else if (("," + controllers + ",").find(",memory,") != std::string::npos) {
      limit = read_number("/sys/fs/cgroup/memory" + path + "/memory.limit_in_bytes");
      usage = read_number("/sys/fs/cgroup/memory" + path + "/memory.usage_in_bytes");
      what = "cgroup v1 memory.limit_in_bytes less memory.usage_in_bytes";
    }
    // v1 reports "no limit" as a huge number (PAGE_COUNTER_MAX pages).
    if (std::isfinite(limit) && limit < 1e18) {
      const double left = limit - (std::isfinite(usage) ? usage : 0.0);
      if (left < m.bytes) m.bytes = std::max(0.0, left), m.source = what;
    }
  }
  return m;
}

std::string format_bytes(double bytes) {
  if (!std::isfinite(bytes)) return "unlimited";
  if (bytes >= 1e9) return fmt::format("{:.1f} GB", bytes / 1e9);
  if (bytes >= 1e6) return fmt::format("{:.0f} MB", bytes / 1e6);
  return fmt::format("{:.0f} kB", bytes / 1e3);
}

}  // namespace vmsim::core
