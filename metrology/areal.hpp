#pragma once
// Areal texture parameters of ISO 25178-2 on a height grid, over its valid points.
#include "core/height_grid.hpp"

#include <cstddef>

namespace vmsim::metrology {

struct ArealParameters {
  std::size_t points = 0;           // valid points used for the height parameters
  std::size_t gradient_points = 0;  // points where both gradients could be formed (Sdq, Sdr)
  double mean_mm = 0;               // the reference height the others are measured from
  double Sa_mm = 0, Sq_mm = 0, Sp_mm = 0, Sv_mm = 0, Sz_mm = 0;
  double Ssk = 0, Sku = 0;  // dimensionless; NaN when Sq = 0
  double Sdq = 0;           // root mean square gradient (dimensionless)
  double Sdr_percent = 0;   // developed interfacial area ratio, %
};

// ISO 25178-2 section 4, with the integrals over the definition area taken as means over the grid's nodes:
//   heights z are measured from the mean of the valid heights (so with form removal beforehand they are measured
//   from the least-squares plane or polynomial; with none, from the mean height, as Gwyddion's statistics do);
//   Sa = mean |z|, Sq = sqrt(mean z^2), Sp = max z, Sv = -min z, Sz = Sp + Sv,
//   Ssk = mean z^3 / Sq^3, Sku = mean z^4 / Sq^4,
//   Sdq = sqrt(mean (zx^2 + zy^2)), Sdr = 100 mean (sqrt(1 + zx^2 + zy^2) - 1) %,
//   with the gradients zx, zy by central differences (one-sided at the edges and next to invalid points; a node
//   with no valid neighbour along x or along y takes no part in Sdq and Sdr).
// Throws core::Error when the grid has no valid point.
ArealParameters areal_parameters(const core::HeightGrid& grid);

}  // namespace vmsim::metrology
