#include "metrology/marks.hpp"

#include "core/error.hpp"
#include "metrology/register.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
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

namespace {
void require_same_grid(const core::HeightGrid& a, const core::HeightGrid& b, const char* what) {
  if (a.nx() != b.nx() || a.ny() != b.ny() || std::abs(a.dx_mm - b.dx_mm) > 1e-12 ||
      std::abs(a.dy_mm - b.dy_mm) > 1e-12 || std::abs(a.x0_mm - b.x0_mm) > 1e-9 || std::abs(a.y0_mm - b.y0_mm) > 1e-9)
    throw core::Error(std::string(what) + ": the deviation and the reference are not sampled on the same grid");
}

// d r / d(axis) at a node from its two neighbours along the axis (central), or the one valid neighbour
// (one-sided), or 0 without either. `at(k)` is the height k nodes away along the axis (NaN off the grid).
template <class At>
double derivative(const At& at, double h) {
  const double zm = at(-1), z0 = at(0), zp = at(1);
  const bool m = std::isfinite(zm), p = std::isfinite(zp);
  if (m && p) return (zp - zm) / (2 * h);
  if (p) return (zp - z0) / h;
  if (m) return (z0 - zm) / h;
  return 0.0;
}
}  // namespace

Slope slope_of(const core::HeightGrid& r) {
  const Eigen::Index nx = r.nx(), ny = r.ny();
  Slope s{r, r};
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  auto z = [&](Eigen::Index j, Eigen::Index i) { return j < 0 || j >= ny || i < 0 || i >= nx ? nan : r.z_mm(j, i); };
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < ny; ++j) {
    for (Eigen::Index i = 0; i < nx; ++i) {
      if (!std::isfinite(r.z_mm(j, i))) {
        s.slope_rad.z_mm(j, i) = s.normal_factor.z_mm(j, i) = nan;
        continue;
      }
      const double gx = derivative([&](int k) { return z(j, i + k); }, r.dx_mm);
      const double gy = derivative([&](int k) { return z(j + k, i); }, r.dy_mm);
      const double g2 = gx * gx + gy * gy;
      s.slope_rad.z_mm(j, i) = std::atan(std::sqrt(g2));
      s.normal_factor.z_mm(j, i) = 1.0 / std::sqrt(1.0 + g2);  // exactly 1 where the reference is flat
    }
  }
  return s;
}

core::HeightGrid normal_deviation(const core::HeightGrid& vertical, const Slope& slope) {
  require_same_grid(vertical, slope.normal_factor, "normal_deviation");
  core::HeightGrid d = vertical;
  d.z_mm = vertical.z_mm * slope.normal_factor.z_mm;  // NaN propagates
  return d;
}

SteepWalls steep_walls(const Slope& ref, double slope_deg) {
  const double limit = slope_deg * 3.14159265358979323846 / 180.0;
  SteepWalls w;
  std::size_t valid = 0;
  for (Eigen::Index j = 0; j < ref.slope_rad.ny(); ++j)
    for (Eigen::Index i = 0; i < ref.slope_rad.nx(); ++i) {
      const double a = ref.slope_rad.z_mm(j, i);
      if (std::isfinite(a)) ++valid, w.nodes += a > limit ? 1 : 0;
    }
  w.fraction = valid ? static_cast<double>(w.nodes) / static_cast<double>(valid) : 0.0;
  return w;
}

double wall_step_max_mm(const core::HeightGrid& surf, double slope_deg) {
  const double tan_limit = std::tan(slope_deg * 3.14159265358979323846 / 180.0);
  double worst = 0.0;
  for (Eigen::Index j = 0; j < surf.ny(); ++j)
    for (Eigen::Index i = 0; i < surf.nx(); ++i) {
      const double z0 = surf.z_mm(j, i);
      if (i + 1 < surf.nx()) {
        const double step = std::abs(surf.z_mm(j, i + 1) - z0);  // NaN compares false
        if (step > tan_limit * surf.dx_mm) worst = std::max(worst, step);
      }
      if (j + 1 < surf.ny()) {
        const double step = std::abs(surf.z_mm(j + 1, i) - z0);
        if (step > tan_limit * surf.dy_mm) worst = std::max(worst, step);
      }
    }
  return worst;
}

void add_vertical(std::vector<Mark>& marks, const core::HeightGrid& vertical, const Slope& slope) {
  require_same_grid(vertical, slope.slope_rad, "add_vertical");
  const double limit = kSteepWallSlopeDeg * 3.14159265358979323846 / 180.0;
  for (Mark& m : marks) {
    const auto i = static_cast<Eigen::Index>(std::lround((m.x_mm - vertical.x0_mm) / vertical.dx_mm));
    const auto j = static_cast<Eigen::Index>(std::lround((m.y_mm - vertical.y0_mm) / vertical.dy_mm));
    if (i < 0 || j < 0 || i >= vertical.nx() || j >= vertical.ny()) continue;
    m.depth_vertical_mm = std::abs(vertical.z_mm(j, i));
    m.slope_rad = slope.slope_rad.z_mm(j, i);
    m.steep_wall = m.slope_rad > limit;
  }
}

std::vector<Mark> find_marks(const core::HeightGrid& dev, double threshold, std::size_t max_marks, double path_dir,
                             std::size_t min_nodes) {
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
      if (cells.size() < min_nodes) continue;  // its nodes stay labelled: no later seed restarts it
      double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
      double amin = 1e300, amax = -1e300, cmin = 1e300, cmax = -1e300;  // along and across the path
      const bool dir = std::isfinite(path_dir);
      const double ux = dir ? std::cos(path_dir) : 1.0, uy = dir ? std::sin(path_dir) : 0.0;
      std::size_t deep = 0;
      for (Eigen::Index c : cells) {
        const Eigen::Index j = c / nx, i = c % nx;
        if (std::abs(dev.z_mm(j, i)) < 0.5 * m.depth_mm) continue;
        ++deep;
        xmin = std::min(xmin, dev.x(i)), xmax = std::max(xmax, dev.x(i));
        ymin = std::min(ymin, dev.y(j)), ymax = std::max(ymax, dev.y(j));
        const double a = ux * dev.x(i) + uy * dev.y(j), b = -uy * dev.x(i) + ux * dev.y(j);
        amin = std::min(amin, a), amax = std::max(amax, a), cmin = std::min(cmin, b), cmax = std::max(cmax, b);
      }
      m.x_extent_mm = xmax - xmin + dev.dx_mm;
      m.y_extent_mm = ymax - ymin + dev.dy_mm;
      if (dir) {
        // One node's footprint along a direction: |u.x| dx + |u.y| dy (exact along the axes).
        m.along_mm = amax - amin + std::abs(ux) * dev.dx_mm + std::abs(uy) * dev.dy_mm;
        m.width_mm = cmax - cmin + std::abs(uy) * dev.dx_mm + std::abs(ux) * dev.dy_mm;
        double d = std::remainder(path_dir, 3.14159265358979323846);
        if (d <= -1.5707963267948966) d += 3.14159265358979323846;
        m.direction_rad = d;
      }
      m.area_mm2 = static_cast<double>(deep) * dev.dx_mm * dev.dy_mm;
      marks.push_back(m);
    }
  }
  std::sort(marks.begin(), marks.end(), [](const Mark& a, const Mark& b) { return a.depth_mm > b.depth_mm; });
  if (marks.size() > max_marks) marks.resize(max_marks);
  return marks;
}

Lay lay_of(const core::HeightGrid& g) {
  // Structure tensor J = sum (gx^2, gx gy; gx gy, gy^2) over nodes with both central differences; the marks run
  // perpendicular to its principal eigenvector (the dominant gradient direction).
  const Eigen::Index nx = g.nx(), ny = g.ny();
  std::vector<double> rxx(static_cast<std::size_t>(ny), 0.0), rxy(static_cast<std::size_t>(ny), 0.0),
      ryy(static_cast<std::size_t>(ny), 0.0);
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 1; j < ny - 1; ++j) {
    double xx = 0, xy = 0, yy = 0;
    for (Eigen::Index i = 1; i < nx - 1; ++i) {
      const double gx = (g.z_mm(j, i + 1) - g.z_mm(j, i - 1)) / (2 * g.dx_mm);
      const double gy = (g.z_mm(j + 1, i) - g.z_mm(j - 1, i)) / (2 * g.dy_mm);
      if (!std::isfinite(gx) || !std::isfinite(gy)) continue;
      xx += gx * gx, xy += gx * gy, yy += gy * gy;
    }
    rxx[static_cast<std::size_t>(j)] = xx, rxy[static_cast<std::size_t>(j)] = xy, ryy[static_cast<std::size_t>(j)] = yy;
  }
  double xx = 0, xy = 0, yy = 0;
  for (Eigen::Index j = 0; j < ny; ++j)
    xx += rxx[static_cast<std::size_t>(j)], xy += rxy[static_cast<std::size_t>(j)],
        yy += ryy[static_cast<std::size_t>(j)];
  Lay lay;
  const double tr = xx + yy;
  if (!(tr > 0)) return lay;
  const double gradient_dir = 0.5 * std::atan2(2 * xy, xx - yy);
  const double root = std::sqrt((xx - yy) * (xx - yy) + 4 * xy * xy);
  lay.anisotropy = root / tr;  // (l1 - l2) / (l1 + l2)
  double d = gradient_dir + 1.5707963267948966;
  d = std::remainder(d, 3.14159265358979323846);
  if (d <= -1.5707963267948966) d += 3.14159265358979323846;
  lay.direction_rad = d;
  return lay;
}

Profile profile(const core::HeightGrid& g, double x, double y, double dir, double half, double step) {
  if (!(step > 0) || !(half >= 0) || half / step > 1e6)
    throw core::Error("profile: the step must be positive and the length finite");
  const long n = static_cast<long>(std::floor(half / step + 1e-9));
  Profile p;
  p.s_mm.resize(2 * n + 1);
  p.z_mm.resize(2 * n + 1);
  const double ux = std::cos(dir), uy = std::sin(dir);
  for (long k = -n; k <= n; ++k) {
    const double s = static_cast<double>(k) * step;
    double z;
    p.s_mm[k + n] = s;
    p.z_mm[k + n] = sample_bilinear(g, x + s * ux, y + s * uy, z) ? z : std::numeric_limits<double>::quiet_NaN();
  }
  return p;
}

}  // namespace vmsim::metrology
