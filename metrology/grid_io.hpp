#pragma once
// Height grids to and from files. This holds the simple formats; X3P, SDF and .sur come with the metrology issue.
#include "core/height_grid.hpp"

#include <filesystem>

namespace vmsim::metrology {

// Matrix CSV: '#' header lines giving x0, y0, dx, dy (mm) and the size, then one line per row j (y), nx values
// (mm, "nan" where invalid). Written atomically.
void write_height_csv(const std::filesystem::path& file, const core::HeightGrid& grid);
core::HeightGrid read_height_csv(const std::filesystem::path& file);

// NumPy .npy (float64, shape ny x nx, C order; NaN where invalid) for Python users, plus the grid geometry in a
// JSON sidecar file.npy.json. Written atomically.
void write_height_npy(const std::filesystem::path& file, const core::HeightGrid& grid);

}  // namespace vmsim::metrology
