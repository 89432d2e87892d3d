#include "render/colormap.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::render {

namespace {

// ColorBrewer RdBu-11 from blue to red (Cynthia Brewer, colorbrewer2.org): a diverging map with a white centre,
// readable by colour-blind viewers, whose two halves are equally dark at equal |t|.
constexpr unsigned char kPoints[11][3] = {{0x05, 0x30, 0x61}, {0x21, 0x66, 0xac}, {0x43, 0x93, 0xc3},
                                          {0x92, 0xc5, 0xde}, {0xd1, 0xe5, 0xf0}, {0xf7, 0xf7, 0xf7},
                                          {0xfd, 0xdb, 0xc7}, {0xf4, 0xa5, 0x82}, {0xd6, 0x60, 0x4d},
                                          {0xb2, 0x18, 0x2b}, {0x67, 0x00, 0x1f}};

}  // namespace

Rgb diverging_colour(double t) {
  if (!std::isfinite(t)) t = 0;
  t = std::clamp(t, -1.0, 1.0);
  const double u = (t + 1) * 5;  // 0..10
  const int k = std::min(9, static_cast<int>(std::floor(u)));
  const double f = u - k;
  Rgb c;
  for (int i = 0; i < 3; ++i) c[i] = ((1 - f) * kPoints[k][i] + f * kPoints[k + 1][i]) / 255.0;
  return c;
}

Rgb table_colour(double v, double limit) {
  const double t = std::clamp(v / limit, -1.0, 1.0);
  const int k = std::clamp(static_cast<int>(std::floor((t + 1) / 2 * kColourTableSize)), 0, kColourTableSize - 1);
  return diverging_colour(-1 + (2.0 * k + 1) / kColourTableSize);
}

double nice_ceil(double x) {
  if (!(x > 0) || !std::isfinite(x)) return 1;
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * p >= x * (1 - 1e-12)) return m * p;
  return 10 * p;
}

double symmetric_limit(std::span<const double> values, double floor) {
  double m = 0;
  for (double v : values)
    if (std::isfinite(v)) m = std::max(m, std::abs(v));
  return nice_ceil(std::max(m, floor));
}

}  // namespace vmsim::render
