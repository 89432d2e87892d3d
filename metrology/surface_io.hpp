#pragma once
// Any surface file vmsim reads, recognised by its content (and, for ASCII files, its extension):
//   X3P (zip "PK\3\4")                       read_x3p (SUR and PRF matrices; PCL point lists on a lattice)
//   Digital Surf "DIGITAL SURF"/"DSCOMPRESSED" read_sur
//   SDF "aISO-1.0"/"bISO-1.0"                read_sdf
//   vmsim matrix CSV ("# x0_mm=" header)     read_height_csv
//   .xyz, or 3-column text with x y z        read_xyz_grid
//   other text: matrix with a header         read_matrix_grid
#include "core/height_grid.hpp"

#include <filesystem>
#include <string>

namespace vmsim::metrology {

struct SurfaceFile {
  core::HeightGrid grid;
  std::string format;   // "x3p", "sur", "sdf", "csv", "xyz", "matrix"
  std::string note;     // what the reader wants the user to know (e.g. an X3P rotation that was not applied)
};

SurfaceFile read_surface_file(const std::filesystem::path& file);
inline core::HeightGrid read_surface(const std::filesystem::path& file) { return read_surface_file(file).grid; }

// By extension: .x3p, .sdf, .sur, .csv (vmsim matrix CSV), .xyz, .npy. Written atomically.
void write_surface(const std::filesystem::path& file, const core::HeightGrid& grid);

}  // namespace vmsim::metrology
