#pragma once
// Meshes to VTK's XML PolyData (.vtp, opens in ParaView), with their per-vertex scalars.
#include "core/mesh.hpp"

#include <filesystem>

namespace vmsim::render {

// Written through vtkXMLPolyDataWriter to a temporary file, then renamed: appended raw binary data (not base64),
// zlib-compressed at `zlib_level` 1..9 (VTK's default is 5), the triangles as 32-bit connectivity and offsets. VTK's
// reader (ParaView) gives back the same points, triangles and point data bit for bit (tests/render/vtp_io_test.cpp).
void write_vtp(const std::filesystem::path& file, const core::TriangleMesh& mesh, int zlib_level = 5);

}  // namespace vmsim::render
