#pragma once
// Meshes to VTK's XML PolyData (.vtp, opens in ParaView), with their per-vertex scalars.
#include "core/mesh.hpp"

#include <filesystem>

namespace vmsim::render {

// Written through vtkXMLPolyDataWriter (binary, zlib-compressed) to a temporary file, then renamed.
void write_vtp(const std::filesystem::path& file, const core::TriangleMesh& mesh);

}  // namespace vmsim::render
