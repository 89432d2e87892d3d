#pragma once
// Digital Surf .sur files (MountainsMap's studiable format, which STIL's software exports): a 512-byte
// little-endian header (signature "DIGITAL SURF", or "DSCOMPRESSED" with zlib-compressed data), a comment zone,
// a private zone, then int16 or int32 points, x fastest. The header layout and the height formula
//   z = (point - Zmin) * Zspacing * Zunit_ratio + Zoffset   (in the header's Z unit)
// follow the MountainsMap format description as RosettaSciIO's reader implements it; non-measured points are
// flagged by "special points" = 1 and stored as Zmin - 2.
#include "core/height_grid.hpp"

#include <filesystem>

namespace vmsim::metrology {

// Surfaces (object type 2) and profiles (type 1, one row); the first object of multi-object files.
// Throws core::Error naming the file, the header field or byte offset, and what was expected.
core::HeightGrid read_sur(const std::filesystem::path& file);

// Uncompressed int32 surface, lengths in mm, heights quantised to 2^30 steps over their range (to within
// range / 2^31 of the grid: .sur stores integers), invalid points as non-measured points. Written atomically.
void write_sur(const std::filesystem::path& file, const core::HeightGrid& grid);

}  // namespace vmsim::metrology
