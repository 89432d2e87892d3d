#pragma once
// What the signal tests share: the bins' definition (sim/signals.hpp) written out, which SignalBinner's folds are
// checked against bit for bit, and a drive response cut into blocks of rows as the streamed run hands them over.
#include <Eigen/Core>

#include "drives/simulate.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace vmsim_test {

inline bool same_double_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

struct BinRange {
  Eigen::ArrayXd lo, hi;
};

// Per bin of bin_samples rows, the minimum and maximum of the finite values in row order (std::min / std::max: the
// first of equal values stays, so +0 before -0 gives +0), NaN for a bin without one. VALUE(k) is row k's value, for k
// in [0, rows).
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

// Rows [k0, k0 + n) of a drive response.
inline vmsim::drives::AxisResponse response_rows(const vmsim::drives::AxisResponse& r, Eigen::Index k0,
                                                 Eigen::Index n) {
  vmsim::drives::AxisResponse b;
  b.period_s = r.period_s;
  b.axis_names = r.axis_names;
  b.position = r.position.middleRows(k0, n);
  b.velocity = r.velocity.middleRows(k0, n);
  b.acceleration = r.acceleration.middleRows(k0, n);
  b.jerk = r.jerk.middleRows(k0, n);
  b.current_mean_A = r.current_mean_A.middleRows(k0, n);
  b.current_peak_A = r.current_peak_A.middleRows(k0, n);
  return b;
}

}  // namespace vmsim_test
