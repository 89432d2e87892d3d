#pragma once
// Contour error figures over the samples that matter: those on cutting (feed) moves. A rapid's corner lag is
// large and says nothing about the part.
#include "motion/contour.hpp"
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"

#include <nlohmann/json.hpp>

namespace vmsim::sim {

struct ContourStats {
  double max_abs_mm = 0, rms_mm = 0, mse_um2 = 0;
  Eigen::Index samples = 0;
};

// Samples k of `ce` on a feed move of `program` (the setpoints' move index; settling rows take the last move).
ContourStats cutting_contour_stats(const motion::ContourError& ce, const core::Setpoints& sp,
                                   const core::ToolPath& program);

nlohmann::json contour_json(const motion::ContourError& ce, const ContourStats& cutting);

}  // namespace vmsim::sim
