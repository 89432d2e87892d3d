#pragma once
// Helpers the removal tests share (one definition each: test files compile in batches).
#include <gtest/gtest.h>
#include <omp.h>

#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "removal/cut.hpp"
#include "removal/cut_internal.hpp"
#include "removal/cut_reference.hpp"
#include "removal/dexel_grid.hpp"
#include "removal/swept_tool.hpp"

namespace vmsim::removal::test {

// A torus-ended tool: radius R, corner radius rc (rc = R: ball, 0: flat end), length L, all mm.
inline Tool tool(double R, double rc, double L = 30) {
  Tool t;
  t.radius_mm = R;
  t.corner_radius_mm = rc;
  t.length_mm = L;
  return t;
}

// Two rays' intervals hold the same floats, bit for bit.
inline bool same_bits(const std::vector<Interval>& a, const std::vector<Interval>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(Interval)) == 0);
}

// Every ray of two grids of the same size, bit for bit; WHERE names the first ray that differs.
inline bool same_grid_bits(const DexelGrid& a, const DexelGrid& b, std::string& where) {
  std::vector<Interval> x, y;
  for (int j = 0; j < a.nv(); ++j)
    for (int i = 0; i < a.nu(); ++i) {
      a.intervals(i, j, x);
      b.intervals(i, j, y);
      if (!same_bits(x, y)) {
        where = "ray (" + std::to_string(i) + ", " + std::to_string(j) + ")";
        return false;
      }
    }
  return true;
}

// SWEEPS cut into fresh grids from MAKE_GRID by cut_reference and by cut on 1 thread, 2 threads and the generic build's
// kernels; every ray of the four grids bit for bit (LABEL names the case in a failure). Returns the statistics of
// the 1-thread and the generic cut, for the caller's checks on what the kernels did.
struct CutBothBuildsStats {
  CutStats one_thread, generic;
};
inline CutBothBuildsStats expect_cut_equals_reference(const std::function<DexelGrid()>& make_grid,
                                                      const std::vector<SweptTool>& sweeps, const std::string& label) {
  DexelGrid ref = make_grid(), one = make_grid(), two = make_grid(), generic = make_grid();
  cut_reference(ref, sweeps);
  const int threads = omp_get_max_threads();
  CutBothBuildsStats s;
  omp_set_num_threads(1);
  s.one_thread = cut(one, sweeps);
  omp_set_num_threads(2);
  cut(two, sweeps);
  detail::generic_kernels_only() = true;
  s.generic = cut(generic, sweeps);
  detail::generic_kernels_only() = false;
  omp_set_num_threads(threads);
  std::string where;
  EXPECT_TRUE(same_grid_bits(ref, one, where)) << label << ", cut_reference vs cut: " << where;
  EXPECT_TRUE(same_grid_bits(one, two, where)) << label << ", 1 vs 2 threads: " << where;
  EXPECT_TRUE(same_grid_bits(one, generic, where)) << label << ", AVX2 vs generic: " << where;
  return s;
}

}  // namespace vmsim::removal::test
