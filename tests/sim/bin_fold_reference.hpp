#pragma once
// The signal bins' definition (sim/signals.hpp) written out for the tests: per bin of bin_samples rows, the minimum
// and maximum of the finite values in row order (std::min / std::max: the first of equal values stays, so +0 before
// -0 gives +0), NaN for a bin without one. SignalBinner's folds are checked bit for bit against it.
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace vmsim_test {

inline bool same_double_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

struct BinRange {
  Eigen::ArrayXd lo, hi;
};

// VALUE(k) is row k's value, for k in [0, rows).
template <class Value>
BinRange fold_bins_in_row_order(Eigen::Index rows, Eigen::Index bin_samples, const Value& value) {
  const Eigen::Index bins = (rows + bin_samples - 1) / bin_samples;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  BinRange c{Eigen::ArrayXd::Constant(bins, nan), Eigen::ArrayXd::Constant(bins, nan)};
  for (Eigen::Index k = 0; k < rows; ++k) {
    const double v = value(k);
    if (!std::isfinite(v)) continue;
    const Eigen::Index b = k / bin_samples;
    c.lo[b] = std::isnan(c.lo[b]) ? v : std::min(c.lo[b], v);
    c.hi[b] = std::isnan(c.hi[b]) ? v : std::max(c.hi[b], v);
  }
  return c;
}

}  // namespace vmsim_test
