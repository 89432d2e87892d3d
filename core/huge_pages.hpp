#pragma once
// Transparent huge pages for the large arrays a run writes once (issue 21: flower_mold's 3.7 M setpoints, their
// tool tips and the contour error's path: ~1 GB touched page by page, 264 k minor faults). Where the kernel gives
// huge pages on request only (THP "madvise" mode, Debian's default), an array advised before it is first written
// faults once per 2 MB instead of once per 4 kB. Only the whole 2 MB pages inside the array are advised, so an
// array holds no page it does not reach into (peak RSS: a fully written array's pages are all present either way).
#include <cstddef>
#include <vector>

namespace vmsim::core {

// Arrays smaller than this are left alone: a huge page or two would not pay the system call.
inline constexpr std::size_t kHugePageMinBytes = std::size_t{8} << 20;

// Advises [data, data + bytes) for huge pages (madvise MADV_HUGEPAGE on its aligned 2 MB pages). Call it before the
// memory is first written: pages already present stay small. A no-op for small arrays, where the kernel has no
// transparent huge pages, and on other systems; never throws (the advice changes no value, only how pages fault).
void advise_huge_pages(const void* data, std::size_t bytes) noexcept;

// An Eigen array or matrix, after resize() and before it is written.
template <class Dense>
void advise_huge_pages(const Dense& a) noexcept {
  advise_huge_pages(static_cast<const void*>(a.data()), sizeof(*a.data()) * static_cast<std::size_t>(a.size()));
}

// A vector about to grow to n elements, which value-initialising resize() would write at once: its capacity reserved
// and advised first (then resize() or push_back() fill it).
template <class T, class A>
void reserve_huge(std::vector<T, A>& v, std::size_t n) {
  if (n <= v.capacity()) return;
  v.reserve(n);
  advise_huge_pages(static_cast<const void*>(v.data() + v.size()), sizeof(T) * (v.capacity() - v.size()));
}

}  // namespace vmsim::core
