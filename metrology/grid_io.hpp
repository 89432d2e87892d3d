#pragma once
// Height grids to and from the simple file formats: vmsim's matrix CSV, NumPy .npy, ASCII point lists (x y z per
// line) and ASCII matrices with a header giving spacing and units (as Gwyddion exports them). X3P, SDF and .sur
// have their own headers; surface_io.hpp reads any of them by content.
#include "core/height_grid.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <istream>
#include <string>

namespace vmsim::metrology {

// Matrix CSV: '#' header lines giving x0, y0, dx, dy (mm) and the size, then one line per row j (y), nx values
// (mm, "nan" where invalid). Numbers are written with the shortest digits that read back as the same double, so
// a grid read back is the same bit for bit. Written atomically.
void write_height_csv(const std::filesystem::path& file, const core::HeightGrid& grid);
core::HeightGrid read_height_csv(const std::filesystem::path& file);
core::HeightGrid read_height_csv(std::istream& in, const std::string& name);  // `name` starts every error

// NumPy .npy (float64, shape ny x nx, C order; NaN where invalid) for Python users, plus the grid geometry in a
// JSON sidecar file.npy.json. Written atomically.
void write_height_npy(const std::filesystem::path& file, const core::HeightGrid& grid);

// Per node of a grid a small index (NumPy .npy int8, shape ny x nx, C order; -1: none), e.g. which tool last cut each
// node of a run with several tools (tool_map.npy); `meaning` goes into the JSON sidecar beside the geometry of `on`
// (the grid it indexes, as write_height_npy's). Written atomically.
using IndexGrid = Eigen::Array<std::int8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
void write_index_npy(const std::filesystem::path& file, const IndexGrid& index, const core::HeightGrid& on,
                     const std::string& meaning);
// Reads such a file as NumPy writes int8 (also uint8 values up to 127) 2-D arrays: NPY 1.0-3.0, C or Fortran order.
// Throws core::Error naming the file and what was expected.
IndexGrid read_index_npy(const std::filesystem::path& file);

// Points that lie on a regular x/y lattice (columns of equal x, rows of equal y, to 1e-3 of the step; some nodes
// may be missing) to a grid whose missing nodes are invalid. Throws core::Error starting with `what` (a file
// name) when the points are not on a lattice, when two fall on one node, or when the lattice would be far larger
// than the points (more than 16 nodes per point).
core::HeightGrid points_to_grid(const Eigen::Matrix<double, Eigen::Dynamic, 3>& points_mm, const std::string& what);

// ASCII point list: one point per line, "x y z" separated by blanks, tabs, commas or semicolons; lines starting
// with '#' or '//' are comments, and a comment "# unit: um" (m, mm, um, nm) gives the unit of all three columns
// (default mm). A z of "nan" is an invalid point. The points must lie on a lattice (points_to_grid).
core::HeightGrid read_xyz_grid(const std::filesystem::path& file);
core::HeightGrid read_xyz_grid(std::istream& in, const std::string& name);
// One line "x y z" (mm, shortest exact digits) per valid node, for CloudCompare and other point tools.
void write_xyz(const std::filesystem::path& file, const core::HeightGrid& grid);

// ASCII matrix with a header: header lines "key: value [unit]" or "key = value [unit]" ('#' lines anywhere, or
// lines before the first row that are not all numbers; several "k=v" pairs may share one: "h=305 w=75"), then one
// row of heights per line (y = y0 + j dy), separated by blanks, tabs, commas or semicolons; "nan" is invalid.
// Keys (any case), as Gwyddion's and SPIP's ASCII exports and interferometer exports write them:
//   Width, Height / x-length, y-length   the grid's extent, nx dx and ny dy (x-unit, y-unit give a bare number's unit)
//   dx, dy / x spacing, y spacing        the spacing; "pixel size" the spacing along both
//   x0, y0 / x offset, y offset          the position of node (0, 0); default 0
//   Value units / z unit / z-unit        the unit of the heights (default mm); "data unit" the unit of the values
//   height conversion factor (-> m)      heights = value x factor, in the unit named in the key (for values in a
//                                        unit that is not a length, e.g. an interferometer's phase in rad)
//   h, w                                 the numbers of rows and columns (checked)
// Lengths name their unit after the number. Values in a unit that is not a length with no conversion factor are
// an error.
core::HeightGrid read_matrix_grid(const std::filesystem::path& file);
core::HeightGrid read_matrix_grid(std::istream& in, const std::string& name);

}  // namespace vmsim::metrology
