// core/memory (the memory a process may still take) against the kernel's own figures read here independently, and
// core/regular_file (readers refuse FIFOs, devices and directories before opening them: opening a FIFO blocks).
#include "core/error.hpp"
#include "core/memory.hpp"
#include "core/regular_file.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

namespace {

double meminfo_bytes(const std::string& key) {
  std::ifstream in("/proc/meminfo");
  std::string k, unit;
  double kb = 0;
  while (in >> k >> kb >> unit)
    if (k == key + ":") return kb * 1024;
  return NAN;
}

// Reference: /proc/meminfo as the kernel gives it. The figure is at most MemAvailable (a control group can only
// lower it) and, on Linux, finite and positive; MemAvailable moves between the two reads, hence the 5 % slack.
TEST(AvailableMemory, IsAtMostTheKernelsMemAvailable) {
  const double avail = meminfo_bytes("MemAvailable");
  if (std::isnan(avail)) GTEST_SKIP() << "no /proc/meminfo";
  const vmsim::core::AvailableMemory m = vmsim::core::available_memory();
  EXPECT_GT(m.bytes, 0);
  EXPECT_LE(m.bytes, avail * 1.05 + 64e6);
  EXPECT_LE(m.bytes, meminfo_bytes("MemTotal"));
  EXPECT_FALSE(m.source.empty());
}

TEST(AvailableMemory, FormatsSizes) {
  EXPECT_EQ(vmsim::core::format_bytes(4.4e9), "4.4 GB");
  EXPECT_EQ(vmsim::core::format_bytes(640e6), "640 MB");
  EXPECT_EQ(vmsim::core::format_bytes(INFINITY), "unlimited");
}

std::string refusal(const std::filesystem::path& p) {
  try {
    vmsim::core::require_regular_file(p);
  } catch (const vmsim::core::Error& e) {
    return e.what();
  }
  return "";
}

TEST(RegularFile, RefusesFifosDevicesAndDirectoriesAndPassesFiles) {
  std::random_device rd;
  const auto dir = std::filesystem::temp_directory_path() / ("vmsim_regular_" + std::to_string(rd()));
  std::filesystem::create_directories(dir);
  const auto fifo = dir / "pipe", file = dir / "file.txt";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::ofstream(file) << "x\n";
  EXPECT_NE(refusal(fifo).find("FIFO"), std::string::npos) << refusal(fifo);
  EXPECT_NE(refusal(fifo).find(fifo.string()), std::string::npos);
  EXPECT_NE(refusal("/dev/zero").find("device"), std::string::npos) << refusal("/dev/zero");
  EXPECT_NE(refusal(dir).find("is a directory"), std::string::npos) << refusal(dir);
  EXPECT_EQ(refusal(file), "");
  EXPECT_EQ(refusal(dir / "missing"), "");  // each reader says "cannot open" itself
  std::filesystem::remove_all(dir);
}

}  // namespace
