#pragma once
// Digital Surf .sur files (MountainsMap's studiable format, which STIL's and Digital Surf's software write): one or
// more objects, each a 512-byte little-endian header (signature "DIGITAL SURF", or "DSCOMPRESSED" with the points
// in zlib streams), a comment zone, a private zone, then int16 or int32 points, x fastest.
//
// How the header is read (the field layout is the MountainsMap description's; the meaning of each field is taken
// where the independent readers agree: Gwyddion 2.62's surffile module, ContactEngineering SurfaceTopography's SUR
// reader and its tests, RosettaSciIO's digitalsurf reader):
//   - lengths: x = XOffset + i * Xspacing in the X *step* unit (likewise y). The "unit ratio" fields relate the step
//     unit to the display (length) unit (sur-3.sur: step nm, length um, ratio 1000) and scale nothing; reading the
//     spacing in the length unit, or multiplying it by the ratio, is the factor-10^6 error vmsim made before.
//   - heights: z = point * Zspacing + Zoffset in the Z step unit. Points are signed (int16/int32), as all three
//     readers take them. Zmin is not subtracted (Gwyddion and SurfaceTopography; RosettaSciIO subtracts it, which
//     shifts every height by the same Zmin * Zspacing when Zmin != 0: no roughness figure changes).
//   - non-measured points: only when the header's "special points" flag is 1, the points equal to Zmin - 2
//     (SurfaceTopography and RosettaSciIO; Gwyddion 2.62 ignores the flag and shows them as heights at the floor).
//   - inversion 1: z -> -z; 2: -z and mirrored left-right; 3: -z and upside down (SurfaceTopography; Gwyddion
//     mirrors the same way but inverts z about the mean, a constant apart).
//   - multi-object files: the first object is read (a surface, a profile, the first of a series or multilayer);
//     the note says how many objects the file holds.
#include "core/height_grid.hpp"

#include <filesystem>
#include <string>
#include <string_view>

namespace vmsim::metrology {

struct SurData {
  core::HeightGrid grid;  // a profile (object type 1) is one row
  bool profile = false;   // the object read is a profile
  std::string note;       // what the user should know (other objects not read, a unit ratio that disagrees)
};

// Throws core::Error naming the file, the header field or byte offset, and what was expected.
SurData read_sur_data(const std::filesystem::path& file);
// The same from the file's bytes (e.g. after gzip); `name` starts every error message.
SurData read_sur_bytes(std::string_view bytes, const std::string& name);
inline core::HeightGrid read_sur(const std::filesystem::path& file) { return read_sur_data(file).grid; }

// Uncompressed int32 surface, lengths in mm, heights quantised to 2^30 steps over their range (to within
// range / 2^31 of the grid: .sur stores integers), invalid points as non-measured points. Written atomically.
void write_sur(const std::filesystem::path& file, const core::HeightGrid& grid);

}  // namespace vmsim::metrology
