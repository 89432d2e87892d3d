#pragma once
// X3P files (ISO 5436-2 XML, ISO 25178-72): a zip holding main.xml (the axes, the matrix or list dimension, the
// data or a link to binary data), bindata/data.bin (little-endian heights), bindata/valid.bin (one bit per point,
// least significant bit first, 1 = valid) and md5checksum.hex (the MD5 of main.xml as md5sum prints it).
// Files other tools write are read too: main.xml under a folder of the zip (the one main.xml outside __MACOSX/ and
// "._" / .DS_Store entries; the links are relative to its folder; two main.xml files are an error naming both), the
// root element ISO5436 (x3ptools), an empty <Offset/>. X3pMeta::notes says what was done.
// Lengths in the file are metres; vmsim gets mm (units.hpp says how they are converted without losing bits).
#include "core/height_grid.hpp"

#include <Eigen/Core>

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::metrology {

struct X3pMeta {
  std::string feature_type;  // SUR (surface), PRF (profile), PCL (point list)
  std::string revision;      // Record1/Revision
  std::string date, creator, manufacturer, model, serial, version, probing_type, probing_id, comment;  // Record2
  std::array<char, 3> axis_type{};     // 'I' incremental or 'A' absolute, for CX CY CZ
  std::array<char, 3> data_type{};     // 'I' int16, 'L' int32, 'F' float32, 'D' float64 ('\0' if not given)
  bool binary = false;                 // data in bindata/ (DataLink) rather than in main.xml (DataList)
  bool valid_mask = false;             // a valid-points file was present
  bool rotation_identity = true;       // Record1/Axes/Rotation absent or the identity
  bool main_checksum_checked = false;  // md5checksum.hex was present and matched
  std::size_t invalid_points = 0;      // points invalid in the mask, empty <Datum/>, NaN or infinite
  // What a user should know about a file written by another tool: main.xml found in a folder of the zip, junk
  // entries (__MACOSX/, .DS_Store) and entries main.xml does not name left aside, x3ptools' root element.
  std::vector<std::string> notes;
};

struct X3pData {
  // SUR and PRF: the matrix (PRF as one row). PCL: the points gridded when they lie on a regular x/y lattice
  // (nodes without a point are invalid), otherwise an empty grid (0 x 0).
  core::HeightGrid grid;
  // PCL only: the points as listed, mm (invalid points are left out).
  Eigen::Matrix<double, Eigen::Dynamic, 3> points_mm;
  X3pMeta meta;
};

struct X3pReadOptions {
  bool verify_checksums = true;  // MD5 of main.xml, data.bin and valid.bin must match what the file states
};

// Throws core::Error naming the file, the zip entry or XML element, and what was expected.
X3pData read_x3p(const std::filesystem::path& file, const X3pReadOptions& options = {});

struct X3pWriteOptions {
  std::string comment;                            // Record2/Comment
  std::string creator = "vmsim";                  // Record2/Creator
  std::string model = "vmsim virtual machining";  // Record2/Instrument/Model
  std::string probing_type = "Software";          // Software (a prediction) or NonContacting (a simulated scan)
  std::string probing_id = "vmsim";               // Record2/ProbingSystem/Identification
  std::string version = "vmsim";                  // Record2/Instrument/Version (the app puts its version here)
  std::string date;                               // xsd:dateTime; empty: now (UTC)
  // Deflate level of bindata/data.bin: 0 stores it (measured heights are noise in their last bits and deflate
  // to ~90 % at ~1 s per 4 M points), 1 (fast) .. 9 (small). The other entries are always deflated.
  int compression_level = 0;
};

// Writes a SUR matrix (CX, CY incremental; CZ absolute float64) atomically. Heights are stored in metres, with
// valid.bin only when some points are invalid (their data.bin value is NaN as well, so a reader that ignores the
// mask still sees no height there). A vendor-specific entry lets vmsim read the mm heights back bit for bit (the
// metre values alone cannot always give them back: x/1000*1000 differs from x in the last bit for ~1.4 % of
// doubles); other readers ignore it.
void write_x3p(const std::filesystem::path& file, const core::HeightGrid& grid, const X3pWriteOptions& options = {});

}  // namespace vmsim::metrology
