// (Named to sort last: test files compile in unity batches of 8 in name order, and the existing files keep theirs.)
// core/huge_pages: the advice reaches the kernel for the whole 2 MB pages inside a large array and for nothing else.
// The reference is the kernel's own account of the process' mappings, /proc/self/smaps: a range advised with
// MADV_HUGEPAGE carries the "hg" VmFlag (proc(5)). Whether huge pages are then granted depends on the machine's free
// memory, so the test asserts the advice, not the pages. The values an array holds do not depend on it (checked).
#include "core/huge_pages.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

// The VmFlags of the mapping holding address a (empty when /proc/self/smaps has none).
std::string huge_pages_vm_flags(const void* a) {
  std::ifstream in("/proc/self/smaps");
  const auto x = reinterpret_cast<std::uintptr_t>(a);
  std::string line;
  bool inside = false;
  while (std::getline(in, line)) {
    std::uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = x >= lo && x < hi;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line;
  }
  return {};
}

bool huge_pages_advised(const void* a) { return huge_pages_vm_flags(a).find(" hg") != std::string::npos; }

TEST(HugePages, LargeArraysAreAdvisedOnTheirWhole2MbPagesOnly) {
  if (!std::ifstream("/proc/self/smaps") || !std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled"))
    GTEST_SKIP() << "no /proc/self/smaps or transparent huge pages on this system";
  // 24 MB: at least ten whole 2 MB pages inside, wherever malloc puts it.
  std::vector<double> big;
  vmsim::core::reserve_huge(big, std::size_t{3} << 20);
  ASSERT_GE(big.capacity(), std::size_t{3} << 20);
  const auto base = reinterpret_cast<std::uintptr_t>(big.data());
  const std::uintptr_t page = std::uintptr_t{2} << 20;
  const std::uintptr_t first = (base + page - 1) & ~(page - 1);
  EXPECT_TRUE(huge_pages_advised(reinterpret_cast<const void*>(first))) << huge_pages_vm_flags(big.data());
  EXPECT_TRUE(huge_pages_advised(reinterpret_cast<const void*>(first + 5 * page + 12345)));
  // The bytes before the first whole page (malloc's header page) are not advised.
  if (first != base) {
    EXPECT_FALSE(huge_pages_advised(big.data())) << huge_pages_vm_flags(big.data());
  }
  // The values written are the values read.
  for (std::size_t k = 0; k < (std::size_t{3} << 20); ++k) big.push_back(static_cast<double>(k) * 0.5);
  for (std::size_t k = 0; k < big.size(); k += 4099) ASSERT_EQ(big[k], static_cast<double>(k) * 0.5);

  // Below kHugePageMinBytes nothing is advised.
  std::vector<double> small;
  vmsim::core::reserve_huge(small, (vmsim::core::kHugePageMinBytes / sizeof(double)) / 2);
  EXPECT_FALSE(huge_pages_advised(small.data() + small.capacity() / 2)) << huge_pages_vm_flags(small.data());
  // A vector already large enough is left as it is (no reallocation).
  const double* before = big.data();
  vmsim::core::reserve_huge(big, 10);
  EXPECT_EQ(big.data(), before);
}

}  // namespace
