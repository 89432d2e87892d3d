// M4 per pixel column (see decimate.hpp). Written here rather than taken from VTK: vtkPlotLine draws every point it
// is given (10 000 bins x 2 points per signal, ~7 per pixel column at 1600 px), and each vertical stroke of that
// zig-zag is rasterised in full; the picture cannot show more than this.
#include "render/decimate.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace vmsim::render {

Polyline column_envelope(const Eigen::ArrayXd& x, const Eigen::ArrayXd& y, double x_lo, double x_hi, int columns) {
  if (x.size() != y.size()) throw core::Error(fmt::format("column_envelope: {} x and {} y values", x.size(), y.size()));
  if (columns < 1 || !std::isfinite(x_lo) || !std::isfinite(x_hi) || !(x_hi > x_lo))
    throw core::Error(fmt::format("column_envelope: {} columns over [{}, {}]", columns, x_lo, x_hi));
  const double per_x = columns / (x_hi - x_lo);
  // Points far outside the range share the column just beyond its end (they are outside the plot either way).
  auto column = [&](double v) {
    return static_cast<long>(std::clamp(std::floor((v - x_lo) * per_x), -1.0, static_cast<double>(columns)));
  };
  std::vector<Eigen::Index> kept;
  kept.reserve(static_cast<std::size_t>(std::min<Eigen::Index>(x.size(), 4 * (columns + 2))));
  constexpr Eigen::Index kBreak = -1;
  bool in_run = false, pending_break = false;
  long run_column = 0;
  Eigen::Index first = 0, lo = 0, hi = 0, last = 0;
  auto flush = [&] {
    if (!in_run) return;
    std::array<Eigen::Index, 4> k{first, lo, hi, last};
    std::sort(k.begin(), k.end());
    for (std::size_t i = 0; i < k.size(); ++i)
      if (i == 0 || k[i] != k[i - 1]) kept.push_back(k[i]);
    in_run = false;
  };
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) {
      flush();
      pending_break = !kept.empty();
      continue;
    }
    const long c = column(x[i]);
    if (in_run && c == run_column) {
      if (y[i] < y[lo]) lo = i;
      if (y[i] > y[hi]) hi = i;
      last = i;
      continue;
    }
    flush();
    if (pending_break) kept.push_back(kBreak), pending_break = false;
    in_run = true, run_column = c;
    first = lo = hi = last = i;
  }
  flush();
  Polyline out;
  out.x.resize(static_cast<Eigen::Index>(kept.size()));
  out.y.resize(out.x.size());
  for (std::size_t k = 0; k < kept.size(); ++k) {
    const auto j = static_cast<Eigen::Index>(k);
    if (kept[k] == kBreak) {
      out.x[j] = out.y[j] = std::numeric_limits<double>::quiet_NaN();
    } else {
      out.x[j] = x[kept[k]];
      out.y[j] = y[kept[k]];
    }
  }
  return out;
}

}  // namespace vmsim::render
