#pragma once
// Helpers the removal tests share (one definition each: test files compile in batches).
#include <cstring>
#include <string>
#include <vector>

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

}  // namespace vmsim::removal::test
