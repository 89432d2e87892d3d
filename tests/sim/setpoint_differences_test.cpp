// sim::largest_setpoint_differences (issue 21, session 10: two rows per instruction) against its definition written
// here: std::max folded in order from 0 over |x_k - x_k-1| (k >= 1) and |x_k - 2 x_k-1 + x_k-2| (k >= 2), which skips
// a NaN difference. Bit for bit on random setpoint columns of every length from 0 to 40 and a long one, with repeated
// values, signed zeros, infinities and NaN among them.
#include "sim/drive_checks.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace {

bool setdiff_same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

void setdiff_reference(const std::vector<double>& x, double& d1, double& d2) {
  d1 = 0, d2 = 0;
  for (std::size_t k = 1; k < x.size(); ++k) {
    d1 = std::max(d1, std::abs(x[k] - x[k - 1]));
    if (k >= 2) d2 = std::max(d2, std::abs(x[k] - 2 * x[k - 1] + x[k - 2]));
  }
}

std::vector<double> setdiff_column(std::size_t n, int special, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  std::vector<double> x(n);
  double held = u(rng);
  for (std::size_t k = 0; k < n; ++k) {
    if (rng() % 3 == 0) held = u(rng);  // runs of one value: zero differences
    x[k] = (rng() % 7 == 0) ? ((rng() & 1) ? 0.0 : -0.0) : held + 1e-3 * u(rng) * (rng() % 2);
  }
  if (n > 0 && special != 0) {
    const double v = special == 1   ? std::numeric_limits<double>::quiet_NaN()
                     : special == 2 ? std::numeric_limits<double>::infinity()
                                    : -std::numeric_limits<double>::infinity();
    x[rng() % n] = v;
  }
  return x;
}

TEST(SetpointDifferences, LargestStepsEqualTheInOrderFold) {
  std::mt19937_64 rng(1127);
  int cases = 0;
  for (int special = 0; special < 4; ++special)
    for (std::size_t n = 0; n <= 40; ++n)
      for (int rep = 0; rep < 20; ++rep) {
        const std::vector<double> x = setdiff_column(n, special, rng);
        double r1 = 0, r2 = 0, d1 = -1, d2 = -1;
        setdiff_reference(x, r1, r2);
        vmsim::sim::largest_setpoint_differences(x.data(), static_cast<Eigen::Index>(n), d1, d2);
        ASSERT_TRUE(setdiff_same_bits(r1, d1)) << "n " << n << " special " << special << ": " << r1 << " vs " << d1;
        ASSERT_TRUE(setdiff_same_bits(r2, d2)) << "n " << n << " special " << special << ": " << r2 << " vs " << d2;
        ++cases;
      }
  for (int special = 0; special < 4; ++special) {
    const std::vector<double> x = setdiff_column(100003, special, rng);
    double r1 = 0, r2 = 0, d1 = -1, d2 = -1;
    setdiff_reference(x, r1, r2);
    vmsim::sim::largest_setpoint_differences(x.data(), static_cast<Eigen::Index>(x.size()), d1, d2);
    EXPECT_TRUE(setdiff_same_bits(r1, d1)) << special;
    EXPECT_TRUE(setdiff_same_bits(r2, d2)) << special;
  }
  EXPECT_EQ(cases, 4 * 41 * 20);
}

}  // namespace
