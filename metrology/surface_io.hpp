#pragma once
// Any surface or profile file vmsim reads, recognised by its content (and, for ASCII files, its extension):
//   X3P (zip "PK\3\4")                          read_x3p (SUR and PRF matrices; PCL point lists on a lattice)
//   Digital Surf "DIGITAL SURF"/"DSCOMPRESSED"    read_sur_data (surfaces and profiles)
//   SDF "aISO-1.0"/"bISO-1.0"                   read_sdf
//   BCR-STM "fileformat = bcrstm"/"bcrf"        read_bcr (ASCII or UTF-16 header)
//   Bruker Dektak CSV ("Scan Data", "Lateral")  read_dektak_csv (a profile)
//   vmsim matrix CSV ("# x0_mm=" header)        read_height_csv
//   .xyz, or 3-column text with x y z           read_xyz_grid
//   other text: matrix with a header            read_matrix_grid
// A gzip-compressed file ("\x1f\x8b") is inflated first (zlib) and recognised by its content the same way
// (text formats, .sur and BCR-STM; an X3P is already a zip and an SDF is not sent so).
#include "core/height_grid.hpp"
#include "metrology/profile.hpp"

#include <filesystem>
#include <optional>
#include <string>

namespace vmsim::metrology {

struct SurfaceFile {
  core::HeightGrid grid;            // a profile is here too, as one row
  std::optional<LineScan> profile;  // set when the file holds a profile (a stylus trace, X3P PRF, .sur profile)
  std::string format;  // "x3p", "sur", "sdf", "bcr", "dektak", "csv", "xyz", "matrix"; "+gzip" when inflated
  std::string note;    // what the reader wants the user to know (a folder inside an X3P zip, ...)
};

SurfaceFile read_surface_file(const std::filesystem::path& file);
inline core::HeightGrid read_surface(const std::filesystem::path& file) { return read_surface_file(file).grid; }

// By extension: .x3p, .sdf, .sur, .csv (vmsim matrix CSV), .xyz, .npy. Written atomically.
void write_surface(const std::filesystem::path& file, const core::HeightGrid& grid);

}  // namespace vmsim::metrology
