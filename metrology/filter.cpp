#include "metrology/filter.hpp"
#include "core/units.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace vmsim::metrology {

namespace {

using core::units::kPi;

// Kernel taps w_k = exp(-pi (k h / (alpha lc))^2), |k h| <= lc (the constant factor cancels in the normalisation).
std::vector<double> taps(double h, double cutoff) {
  const double alpha = std::sqrt(std::log(2.0) / kPi);
  const long half = static_cast<long>(std::floor(cutoff / h + 1e-9));
  std::vector<double> w(static_cast<std::size_t>(2 * half + 1));
  for (long k = -half; k <= half; ++k) {
    const double u = static_cast<double>(k) * h / (alpha * cutoff);
    w[static_cast<std::size_t>(k + half)] = std::exp(-kPi * u * u);
  }
  return w;
}

}  // namespace

core::HeightGrid gaussian_mean_surface(const core::HeightGrid& g, double cutoff) {
  if (!(cutoff > 0) || !std::isfinite(cutoff))
    throw core::Error(fmt::format("Gaussian filter: cut-off {} mm must be positive", cutoff));
  const Eigen::Index nx = g.nx(), ny = g.ny();
  const std::vector<double> wx = taps(g.dx_mm, cutoff), wy = taps(g.dy_mm, cutoff);
  const long hx = static_cast<long>(wx.size() / 2), hy = static_cast<long>(wy.size() / 2);
  // Pass 1, along x: numerator (z v) and denominator (v) per node.
  core::HeightArray num1(ny, nx), den1(ny, nx);
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < ny; ++j) {
    std::vector<double> zv(static_cast<std::size_t>(nx)), v(static_cast<std::size_t>(nx));
    for (Eigen::Index i = 0; i < nx; ++i) {
      const double z = g.z_mm(j, i);
      const bool ok = std::isfinite(z);
      zv[static_cast<std::size_t>(i)] = ok ? z : 0.0;  // weight 0: takes no part, is not a height of 0
      v[static_cast<std::size_t>(i)] = ok ? 1.0 : 0.0;
    }
    for (Eigen::Index i = 0; i < nx; ++i) {
      const long k0 = std::max<long>(-hx, -static_cast<long>(i)),
                 k1 = std::min<long>(hx, static_cast<long>(nx - 1 - i));
      double n = 0, d = 0;
      for (long k = k0; k <= k1; ++k) {
        const double w = wx[static_cast<std::size_t>(k + hx)];
        n += w * zv[static_cast<std::size_t>(i + k)];
        d += w * v[static_cast<std::size_t>(i + k)];
      }
      num1(j, i) = n, den1(j, i) = d;
    }
  }
  // Pass 2, along y, column blocks for cache locality.
  core::HeightGrid out = g;
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < ny; ++j) {
    const long l0 = std::max<long>(-hy, -static_cast<long>(j)), l1 = std::min<long>(hy, static_cast<long>(ny - 1 - j));
    std::vector<double> n(static_cast<std::size_t>(nx), 0.0), d(static_cast<std::size_t>(nx), 0.0);
    for (long l = l0; l <= l1; ++l) {
      const double w = wy[static_cast<std::size_t>(l + hy)];
      const double* nr = &num1(j + l, 0);
      const double* dr = &den1(j + l, 0);
      for (Eigen::Index i = 0; i < nx; ++i)
        n[static_cast<std::size_t>(i)] += w * nr[i], d[static_cast<std::size_t>(i)] += w * dr[i];
    }
    for (Eigen::Index i = 0; i < nx; ++i)
      if (std::isfinite(g.z_mm(j, i))) out.z_mm(j, i) = n[static_cast<std::size_t>(i)] / d[static_cast<std::size_t>(i)];
  }
  return out;
}

core::HeightGrid gaussian_highpass(const core::HeightGrid& g, double cutoff) {
  core::HeightGrid out = gaussian_mean_surface(g, cutoff);
  out.z_mm = g.z_mm - out.z_mm;  // NaN stays NaN
  return out;
}

OutlierReport mask_outliers(core::HeightGrid& g, const OutlierOptions& o) {
  if (o.window < 3 || o.window % 2 == 0 || o.window > 51)
    throw core::Error(fmt::format("outliers: window {} must be odd, from 3 to 51", o.window));
  if (!(o.k_sigma > 0)) throw core::Error("outliers: the threshold must be positive");
  const Eigen::Index nx = g.nx(), ny = g.ny();
  const int h = o.window / 2;
  core::HeightArray dep = core::HeightArray::Constant(ny, nx, std::numeric_limits<double>::quiet_NaN());
  core::HeightArray near = dep;
  const auto ok = [&](Eigen::Index b, Eigen::Index a) { return a >= 0 && b >= 0 && a < nx && b < ny && g.valid(b, a); };
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < ny; ++j) {
    std::vector<double> pred;
    pred.reserve(static_cast<std::size_t>(o.window * o.window));
    for (Eigen::Index i = 0; i < nx; ++i) {
      if (!g.valid(j, i)) continue;
      // Predictions of the node's height that are exact on any plane, so slopes bias nothing: the mean of each
      // pair of valid neighbours symmetric about it, nearest ring first; further rings only while fewer than two
      // pairs were found (at edges and holes), since their curvature bias grows with the square of the distance.
      pred.clear();
      for (int ring = 1; ring <= h && pred.size() < 2; ++ring)
        for (int b = 0; b <= ring; ++b)
          for (int a = -ring; a <= ring; ++a) {
            if (std::max(std::abs(a), b) != ring || (b == 0 && a <= 0)) continue;  // this ring, each pair once
            if (ok(j + b, i + a) && ok(j - b, i - a))
              pred.push_back(0.5 * (g.z_mm(j + b, i + a) + g.z_mm(j - b, i - a)));
          }
      if (pred.size() < 2) continue;  // a corner or an isolated point: not judged
      // Departure from the median of the predictions (robust to a spike among the neighbours), and from the
      // closest prediction: a spike is far from all of them, while a point on a crease (a track's edge, a sharp
      // corner) departs from the median but agrees with the pair along the crease, and is not a spike.
      std::sort(pred.begin(), pred.end());
      const std::size_t m = pred.size();
      const double median = m % 2 ? pred[m / 2] : 0.5 * (pred[m / 2 - 1] + pred[m / 2]);
      double close = HUGE_VAL;
      for (double v : pred) close = std::min(close, std::abs(g.z_mm(j, i) - v));
      dep(j, i) = g.z_mm(j, i) - median;
      near(j, i) = close;
    }
  }
  std::vector<double> a;
  a.reserve(static_cast<std::size_t>(dep.size()));
  for (Eigen::Index k = 0; k < dep.size(); ++k)
    if (std::isfinite(dep.data()[k])) a.push_back(std::abs(dep.data()[k]));
  OutlierReport r;
  if (a.empty()) return r;
  auto mid = a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2);
  std::nth_element(a.begin(), mid, a.end());
  // Departures scatter around 0, so their MAD is the median of |departure|.
  r.sigma_mm = std::max(1.4826 * *mid, 1e-7);  // floor 0.1 nm: a perfectly smooth synthetic surface has MAD 0
  r.threshold_mm = o.k_sigma * r.sigma_mm;
  for (Eigen::Index k = 0; k < dep.size(); ++k)
    if (std::isfinite(dep.data()[k]) && std::abs(dep.data()[k]) > r.threshold_mm && near.data()[k] > r.threshold_mm) {
      g.z_mm.data()[k] = std::numeric_limits<double>::quiet_NaN();
      ++r.masked;
    }
  return r;
}

}  // namespace vmsim::metrology
