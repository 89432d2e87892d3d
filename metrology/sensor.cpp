#include "metrology/sensor.hpp"
#include "core/units.hpp"

#include "core/error.hpp"
#include "metrology/filter.hpp"
#include "metrology/register.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <vector>

namespace vmsim::metrology {

namespace {

using core::units::kPi;

// splitmix64 of (seed, index, stream): a counter-based generator, so each node's noise is its own and the result
// does not depend on the order or the number of threads.
double uniform01(std::uint64_t seed, std::uint64_t index, std::uint64_t stream) {
  std::uint64_t z = seed * 0x9e3779b97f4a7c15ULL + index * 0xbf58476d1ce4e5b9ULL + stream * 0x94d049bb133111ebULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return (static_cast<double>(z >> 11) + 0.5) * (1.0 / 9007199254740992.0);  // (0, 1)
}

double normal(std::uint64_t seed, std::uint64_t index) {  // Box-Muller
  return std::sqrt(-2.0 * std::log(uniform01(seed, index, 1))) * std::cos(2 * kPi * uniform01(seed, index, 2));
}

}  // namespace

core::HeightGrid simulate_scan(const core::HeightGrid& pred, const SensorOptions& o, SensorReport* report) {
  if (!(o.step_mm > 0) || !(o.spot_mm >= 0) || !(o.noise_mm >= 0) || !(o.max_slope_deg > 0 && o.max_slope_deg <= 90) ||
      !(o.dropout_probability >= 0 && o.dropout_probability < 1))
    throw core::Error(
        "sensor: step > 0, spot >= 0, noise >= 0, 0 < max slope <= 90 deg and 0 <= dropout < 1 are required");
  const double x0 = o.x_min_mm.value_or(pred.x0_mm), x1 = o.x_max_mm.value_or(pred.x(pred.nx() - 1));
  const double y0 = o.y_min_mm.value_or(pred.y0_mm), y1 = o.y_max_mm.value_or(pred.y(pred.ny() - 1));
  if (!(x1 >= x0) || !(y1 >= y0)) throw core::Error("sensor: the scanned area is empty");
  const double nxd = std::floor((x1 - x0) / o.step_mm + 1e-9) + 1, nyd = std::floor((y1 - y0) / o.step_mm + 1e-9) + 1;
  if (nxd * nyd > static_cast<double>(1LL << 28))
    throw core::Error(fmt::format(
        "sensor: a {:.0f} x {:.0f} scan is more points than vmsim handles; choose a larger step", nxd, nyd));
  SensorReport r;
  // Spot: FWHM = 2 sqrt(2 ln 2) sigma. As an ISO 16610-61 kernel exp(-pi (x / (alpha lc))^2) = exp(-x^2 / (2 sigma^2)):
  // lc = sqrt(2 pi) sigma / alpha.
  r.spot_sigma_mm = o.spot_mm / (2 * std::sqrt(2 * std::log(2.0)));
  r.half_amplitude_wavelength_mm = r.spot_sigma_mm > 0 ? kPi * r.spot_sigma_mm * std::sqrt(2 / std::log(2.0)) : 0;
  const double alpha = std::sqrt(std::log(2.0) / kPi);
  // A spot narrower than a third of the grid step averages nothing the grid resolves: the surface as it is.
  const core::HeightGrid seen = r.spot_sigma_mm > std::min(pred.dx_mm, pred.dy_mm) / 3
                                    ? gaussian_mean_surface(pred, std::sqrt(2 * kPi) * r.spot_sigma_mm / alpha)
                                    : pred;
  core::HeightGrid s;
  s.x0_mm = x0, s.y0_mm = y0, s.dx_mm = s.dy_mm = o.step_mm;
  s.z_mm.resize(static_cast<Eigen::Index>(nyd), static_cast<Eigen::Index>(nxd));
  const double tan_max = std::tan(o.max_slope_deg * kPi / 180);
  std::vector<std::size_t> slope(static_cast<std::size_t>(s.ny()), 0), random(static_cast<std::size_t>(s.ny()), 0),
      outside(static_cast<std::size_t>(s.ny()), 0);
#pragma omp parallel for schedule(static)
  for (Eigen::Index j = 0; j < s.ny(); ++j)
    for (Eigen::Index i = 0; i < s.nx(); ++i) {
      double z, gx, gy;
      double& out = s.z_mm(j, i);
      out = std::numeric_limits<double>::quiet_NaN();
      if (!sample_bilinear(seen, s.x(i), s.y(j), z, &gx, &gy)) {
        ++outside[static_cast<std::size_t>(j)];
        continue;
      }
      if (std::hypot(gx, gy) > tan_max) {
        ++slope[static_cast<std::size_t>(j)];
        continue;
      }
      const std::uint64_t idx = static_cast<std::uint64_t>(j * s.nx() + i);
      if (o.dropout_probability > 0 && uniform01(o.seed, idx, 3) < o.dropout_probability) {
        ++random[static_cast<std::size_t>(j)];
        continue;
      }
      out = z + (o.noise_mm > 0 ? o.noise_mm * normal(o.seed, idx) : 0.0);
    }
  r.points = static_cast<std::size_t>(s.z_mm.size());
  for (Eigen::Index j = 0; j < s.ny(); ++j)
    r.slope_dropouts += slope[static_cast<std::size_t>(j)], r.random_dropouts += random[static_cast<std::size_t>(j)],
        r.outside += outside[static_cast<std::size_t>(j)];
  if (report) *report = r;
  return s;
}

}  // namespace vmsim::metrology
