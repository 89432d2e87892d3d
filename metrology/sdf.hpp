#pragma once
// ISO 25178-71 SDF (surface data file, from the SurfStand project): a header of keys, then the heights of NumPoints
// x NumProfiles points (x fastest), in ASCII ("aISO-1.0", "*"-separated sections, an optional trailer of
// "key = value" lines) or binary ("bISO-1.0", an 81-byte header, little-endian data). Heights are value x Zscale
// metres; Xscale and Yscale are the spacings in metres.
#include "core/height_grid.hpp"

#include <filesystem>

namespace vmsim::metrology {

// ASCII and binary. Data types 0-7 (uint8, uint16, uint32, float, int8, int16, int32, double); "NaN" tokens
// and, in binary integer data, the extreme value of the type (as Gwyddion reads them) are invalid points.
// The trailer keys XOffset and YOffset (metres), which vmsim writes, give the grid's origin; default 0.
// Throws core::Error naming the file, the line or byte offset, and what was expected.
core::HeightGrid read_sdf(const std::filesystem::path& file);

// ASCII, double data with Zscale 1.0E-3 (the values are mm, exact digits, so the grid reads back bit for bit),
// invalid points as NaN, the origin in the trailer. Written atomically.
void write_sdf(const std::filesystem::path& file, const core::HeightGrid& grid);

}  // namespace vmsim::metrology
