#pragma once
// Planning a measurement (what `vmsim measure` reports): the scan a confocal point sensor (metrology/sensor.hpp)
// would take of a predicted surface, the texture it would see, and, given the reference surface the prediction
// departs from, which of the predicted marks such a scan resolves.
#include "core/height_grid.hpp"
#include "metrology/areal.hpp"
#include "metrology/marks.hpp"
#include "metrology/sensor.hpp"

#include <optional>
#include <vector>

namespace vmsim::metrology {

// A mark of the prediction (against the reference) and what the scan shows of it: the deepest deviation of the
// scan from the reference, of the mark's sign, within the mark's half-depth box widened by one scan step.
struct MarkSeen {
  Mark mark;
  double scan_depth_mm = 0;
  bool resolved = false;  // the scan shows at least half the predicted depth, and the depth is above 3 noise sigmas
};

struct ScanPlan {
  core::HeightGrid scan;
  SensorReport sensor;
  ArealParameters predicted_areal, scan_areal;     // least-squares planes removed
  std::optional<core::HeightGrid> scan_deviation;  // with a reference: the scan minus the reference, scan's grid
  std::vector<MarkSeen> marks;                     // with a reference: the predicted marks, deepest first
};

// Marks are the regions of the prediction's deviation from `reference` deeper than mark_threshold_mm (at least
// 3 x 3 nodes, at most 10), measured along the prediction's lay.
ScanPlan plan_scan(const core::HeightGrid& predicted, const SensorOptions& sensor, const core::HeightGrid* reference,
                   double mark_threshold_mm);

}  // namespace vmsim::metrology
