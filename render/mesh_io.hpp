#pragma once
// Meshes to VTK's XML PolyData (.vtp, opens in ParaView), with their per-vertex scalars.
#include "core/mesh.hpp"

#include <filesystem>

namespace vmsim::render {

// Written through vtkXMLPolyDataWriter (binary, zlib-compressed at `zlib_level` 1..9; VTK's default is 5) to a
// temporary file, then renamed.
void write_vtp(const std::filesystem::path& file, const core::TriangleMesh& mesh, int zlib_level = 5);

}  // namespace vmsim::render
