#include "sim/contour_stats.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::sim {

ContourStats cutting_contour_stats(const motion::ContourError& ce, const core::Setpoints& sp,
                                   const core::ToolPath& program) {
  ContourStats s;
  double sum2 = 0;
  for (Eigen::Index k = 0; k < ce.signed_mm.size(); ++k) {
    const int mi = sp.move_index[std::min(k, sp.samples() - 1)];
    if (mi < 0 || program.moves[static_cast<std::size_t>(mi)].rapid) continue;
    const double e = ce.signed_mm[k];
    s.max_abs_mm = std::max(s.max_abs_mm, std::abs(e));
    sum2 += e * e;
    ++s.samples;
  }
  if (s.samples > 0) {
    s.mse_um2 = sum2 / static_cast<double>(s.samples) * 1e6;
    s.rms_mm = std::sqrt(sum2 / static_cast<double>(s.samples));
  }
  return s;
}

nlohmann::json contour_json(const motion::ContourError& ce, const ContourStats& c) {
  return {{"cutting_moves",
           {{"max_abs_mm", c.max_abs_mm}, {"rms_mm", c.rms_mm}, {"mse_um2", c.mse_um2}, {"samples", c.samples}}},
          {"all_moves", {{"max_abs_mm", ce.max_abs_mm}, {"rms_mm", ce.rms_mm}, {"mse_um2", ce.mse_um2}}}};
}

}  // namespace vmsim::sim
