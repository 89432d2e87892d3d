// core::append_shortest (the height grids' CSV numbers, issue 21) against fmt's "{}" (fmt's own shortest-digits
// formatter, Dragonbox, which the grids were written with before), and against the value itself: std::from_chars reads
// every number back as the same double, bit for bit.
#include "core/csv.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace vmsim::core {
namespace {

std::vector<double> shortest_digits_values() {
  std::vector<double> v = {0.0,
                           -0.0,
                           1.0,
                           -1.0,
                           0.1,
                           0.5,
                           1e-4,
                           1.5e-4,
                           1e-5,
                           9.99999e-5,
                           0.00012345678901234567,
                           100000.0,
                           1e15,
                           1e16,
                           9.999999999999998e15,
                           1.2345678901234567e15,
                           123456789012345680.0,
                           5e-324,
                           std::numeric_limits<double>::min(),
                           std::numeric_limits<double>::max(),
                           std::numeric_limits<double>::lowest(),
                           1.0 / 3.0,
                           -2.404,
                           57.15};
  // Every power of ten the doubles hold, and its neighbours: where the fixed and exponent forms switch.
  for (int e = -323; e <= 308; ++e) {
    const double p = std::pow(10.0, e);
    for (double x : {p, std::nextafter(p, 0.0), std::nextafter(p, HUGE_VAL), 1.5 * p, 9.5 * p}) {
      v.push_back(x);
      v.push_back(-x);
    }
  }
  std::mt19937_64 rng(2131);
  // Heights of a z-map in mm (a few um of marks on a mould's depth) and grid coordinates k * spacing.
  std::uniform_real_distribution<double> z(-12.0, 2.0);
  for (int k = 0; k < 300000; ++k) v.push_back(z(rng));
  for (int k = 0; k < 20000; ++k) v.push_back(k * 0.1), v.push_back(k * 0.025 - 250.0), v.push_back(k);
  std::uniform_real_distribution<double> mant(-10.0, 10.0);
  std::uniform_int_distribution<int> ex(-30, 30);
  for (int k = 0; k < 200000; ++k) v.push_back(mant(rng) * std::pow(10.0, ex(rng)));
  std::uniform_int_distribution<std::uint64_t> bits;
  for (int k = 0; k < 500000; ++k) {
    const double d = std::bit_cast<double>(bits(rng));
    if (std::isfinite(d)) v.push_back(d);
  }
  return v;
}

TEST(ShortestDigits, AreFmtsBytesAndReadBackBitForBit) {
  std::string line;
  for (const double x : shortest_digits_values()) {
    line.clear();
    append_shortest(line, x);
    ASSERT_EQ(line, fmt::format("{}", x)) << "value bits " << std::bit_cast<std::uint64_t>(x);
    double back = 1.0;
    const auto r = std::from_chars(line.data(), line.data() + line.size(), back);
    ASSERT_EQ(r.ec, std::errc()) << line;
    ASSERT_EQ(r.ptr, line.data() + line.size()) << line;
    ASSERT_EQ(std::bit_cast<std::uint64_t>(back), std::bit_cast<std::uint64_t>(x)) << line;
  }
  line = "a,";
  append_shortest(line, 0.25);
  EXPECT_EQ(line, "a,0.25");
  // Not finite: as to_chars writes it (the grids' writer puts its own "nan" token there).
  line.clear();
  append_shortest(line, std::numeric_limits<double>::infinity());
  EXPECT_EQ(line, "inf");
}

}  // namespace
}  // namespace vmsim::core
