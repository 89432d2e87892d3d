#include "metrology/marks.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace vmsim::metrology {

core::HeightGrid deviation(const core::HeightGrid& a, const core::HeightGrid& b) {
  if (a.nx() != b.nx() || a.ny() != b.ny() || std::abs(a.dx_mm - b.dx_mm) > 1e-12 ||
      std::abs(a.dy_mm - b.dy_mm) > 1e-12 || std::abs(a.x0_mm - b.x0_mm) > 1e-9 || std::abs(a.y0_mm - b.y0_mm) > 1e-9)
    throw core::Error("deviation: the two surfaces are not sampled on the same grid");
  core::HeightGrid d = a;
  d.z_mm = a.z_mm - b.z_mm;  // NaN propagates
  return d;
}

std::vector<Mark> find_marks(const core::HeightGrid& dev, double threshold, std::size_t max_marks) {
  const Eigen::Index nx = dev.nx(), ny = dev.ny();
  std::vector<int> label(static_cast<std::size_t>(nx * ny), -1);
  std::vector<Mark> marks;
  std::vector<Eigen::Index> stack;
  auto idx = [&](Eigen::Index j, Eigen::Index i) { return static_cast<std::size_t>(j * nx + i); };
  for (Eigen::Index j0 = 0; j0 < ny; ++j0) {
    for (Eigen::Index i0 = 0; i0 < nx; ++i0) {
      const double v0 = dev.z_mm(j0, i0);
      if (!(std::abs(v0) > threshold) || label[idx(j0, i0)] >= 0) continue;
      // Flood fill of the same-sign region above the threshold.
      const bool over = v0 < 0;
      std::vector<Eigen::Index> cells;
      stack.assign(1, j0 * nx + i0);
      label[idx(j0, i0)] = static_cast<int>(marks.size());
      Mark m;
      m.overcut = over;
      while (!stack.empty()) {
        const Eigen::Index c = stack.back();
        stack.pop_back();
        cells.push_back(c);
        const Eigen::Index j = c / nx, i = c % nx;
        const double v = std::abs(dev.z_mm(j, i));
        if (v > m.depth_mm) m.depth_mm = v, m.x_mm = dev.x(i), m.y_mm = dev.y(j);
        const Eigen::Index nb[4][2] = {{j - 1, i}, {j + 1, i}, {j, i - 1}, {j, i + 1}};
        for (const auto& q : nb) {
          if (q[0] < 0 || q[0] >= ny || q[1] < 0 || q[1] >= nx) continue;
          const double w = dev.z_mm(q[0], q[1]);
          if (!(std::abs(w) > threshold) || (w < 0) != over || label[idx(q[0], q[1])] >= 0) continue;
          label[idx(q[0], q[1])] = static_cast<int>(marks.size());
          stack.push_back(q[0] * nx + q[1]);
        }
      }
      double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
      std::size_t deep = 0;
      for (Eigen::Index c : cells) {
        const Eigen::Index j = c / nx, i = c % nx;
        if (std::abs(dev.z_mm(j, i)) < 0.5 * m.depth_mm) continue;
        ++deep;
        xmin = std::min(xmin, dev.x(i)), xmax = std::max(xmax, dev.x(i));
        ymin = std::min(ymin, dev.y(j)), ymax = std::max(ymax, dev.y(j));
      }
      m.x_extent_mm = xmax - xmin + dev.dx_mm;
      m.y_extent_mm = ymax - ymin + dev.dy_mm;
      m.area_mm2 = static_cast<double>(deep) * dev.dx_mm * dev.dy_mm;
      marks.push_back(m);
    }
  }
  std::sort(marks.begin(), marks.end(), [](const Mark& a, const Mark& b) { return a.depth_mm > b.depth_mm; });
  if (marks.size() > max_marks) marks.resize(max_marks);
  return marks;
}

}  // namespace vmsim::metrology
