#pragma once
// BCR-STM files (Image Metrology SPIP's format, written by SPIP and by STM/AFM software): a text header of
// "key = value" lines ('%' starts a comment) padded to `headersize` characters, then xpixels x ypixels points,
// x fastest. Four variants: "fileformat = bcrstm" (int16 points) and "bcrf" (float32), each with an ASCII header
// or a UTF-16 one ("bcrstm_unicode", "bcrf_unicode"; headersize then counts 2-byte characters).
//   xlength, ylength    the scan size in xunit / yunit (default nm): spacing = length / pixels
//   xoffset, yoffset    the position of the first point, same units (default 0)
//   bit2nm, zunit       height = point * bit2nm in zunit (default nm), as Gwyddion's bcrfile and SurfaceTopography
//                       read it
//   intelmode           1 little-endian, 0 big-endian points
//   voidpixels          when present and non-zero, the void points are those holding the format's void value,
//                       32767 (bcrstm) or 3.402823E+38 (bcrf, FLT_MAX); some writers put that value in the key
//                       itself, which is read the same way. Without the key every stored value is a height.
// Rows are stored from y = y0 upward (row j of the file is row j of the grid).
#include "core/height_grid.hpp"

#include <filesystem>
#include <string>
#include <string_view>

namespace vmsim::metrology {

// True when the bytes start like a BCR-STM file (either header encoding).
bool looks_like_bcr(std::string_view head);

// Throws core::Error naming the file, the header key or byte offset, and what was expected.
core::HeightGrid read_bcr(const std::filesystem::path& file);
core::HeightGrid read_bcr_bytes(std::string_view bytes, const std::string& name);

}  // namespace vmsim::metrology
