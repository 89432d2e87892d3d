#include "metrology/scan_plan.hpp"

#include "metrology/processing.hpp"
#include "metrology/register.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::metrology {

namespace {

double deepest_seen(const core::HeightGrid& dev_scan, const Mark& m, double step_mm) {
  double deepest = 0;
  const double rx = 0.5 * m.x_extent_mm + step_mm, ry = 0.5 * m.y_extent_mm + step_mm;
  for (Eigen::Index j = 0; j < dev_scan.ny(); ++j)
    for (Eigen::Index i = 0; i < dev_scan.nx(); ++i) {
      const double v = dev_scan.z_mm(j, i);
      if (std::isfinite(v) && std::abs(dev_scan.x(i) - m.x_mm) <= rx && std::abs(dev_scan.y(j) - m.y_mm) <= ry &&
          (v < 0) == m.overcut)
        deepest = std::max(deepest, std::abs(v));
    }
  return deepest;
}

}  // namespace

ScanPlan plan_scan(const core::HeightGrid& pred, const SensorOptions& sensor, const core::HeightGrid* reference,
                   double mark_threshold_mm) {
  ScanPlan p;
  p.scan = simulate_scan(pred, sensor, &p.sensor);
  // Texture as the prediction has it and as the scan sees it (planes removed).
  p.predicted_areal = areal_parameters(process_surface(pred, {1, {}}));
  p.scan_areal = areal_parameters(process_surface(p.scan, {1, {}}));
  if (!reference) return p;
  const core::HeightGrid dev_pred = deviation(pred, *reference);
  const core::HeightGrid ref_on_scan = resample_scan(*reference, RigidTransform{}, p.scan);
  p.scan_deviation = deviation(p.scan, ref_on_scan);
  const double dir_rad = lay_of(pred).direction_rad;
  for (const Mark& m : find_marks(dev_pred, mark_threshold_mm, 10, dir_rad, 9)) {
    const double deepest = deepest_seen(*p.scan_deviation, m, sensor.step_mm);
    p.marks.push_back({m, deepest, deepest >= 0.5 * m.depth_mm && m.depth_mm > 3 * sensor.noise_mm});
  }
  return p;
}

}  // namespace vmsim::metrology
