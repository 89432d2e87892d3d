#pragma once
// STL files (binary and ASCII) to and from core::TriangleMesh, and the closedness check that makes a mesh usable
// as a stock (crossing parity along a ray only means "inside" for a closed, consistently oriented surface).
//
// Units: an STL file carries no unit; vmsim reads its numbers as mm.
// Format detection: a file whose size is exactly 84 + 50 n bytes, n being the count in bytes 80..83, is binary,
// even if its header starts with "solid" (several CAD exporters write such headers) -- unless everything after
// the header is printable text, which only an ASCII file can be. Any other file starting with "solid" is ASCII;
// anything else is refused with both readings explained.
// Welding: vertices are shared between triangles when their coordinates are equal (exactly, by default: binary
// files store each corner as the same 32-bit floats, ASCII writers print the same digits), or, with
// StlReadOptions::weld_tolerance_mm > 0, when they lie within that distance of an earlier vertex.
// Hostile files: counts are checked against the file size before anything is allocated, every number must be
// finite and within +-1e9 mm, and every error is a core::Error naming the file (and, for ASCII, the line).
#include "core/mesh.hpp"

#include <filesystem>
#include <optional>
#include <string>

namespace vmsim::core {

struct StlReadOptions {
  // 0: weld exactly equal vertices only. > 0: weld vertices closer than this (Euclidean), each to the first
  // vertex read within reach; for files whose writers printed shared corners with different rounding.
  double weld_tolerance_mm = 0.0;
};

// Reads a binary or ASCII STL. Triangles keep the file's vertex order (counter-clockwise seen from outside, as
// the STL convention says); facet normals in the file are ignored (many writers leave them zero).
TriangleMesh read_stl(const std::filesystem::path& path, const StlReadOptions& options = {});

// The first reason the mesh is not the closed, consistently oriented boundary of a solid, or nothing:
//   - a vertex index out of range, or a non-finite vertex;
//   - an edge used by only one triangle (a hole) or by more than two (non-manifold);
//   - two triangles crossing a shared edge in the same direction (one of them flipped).
// Triangles with a repeated vertex (after welding) bound no area and are ignored; if the mesh is open, the
// message says how many of them there are, since dropping corners is a common cause of holes.
// "First" is deterministic: the problem edge whose lowest triangle index is smallest.
std::optional<std::string> closed_mesh_problem(const TriangleMesh& mesh);

// Throws core::Error "<file>: <problem>" when closed_mesh_problem finds one; `file` names the mesh's source.
void check_closed(const TriangleMesh& mesh, const std::string& file);

// Binary STL (the compact form, 50 bytes a triangle; coordinates rounded to 32-bit floats), written to a
// temporary name and renamed. The header never starts with "solid", so no reader mistakes it for ASCII.
void write_stl_binary(const std::filesystem::path& path, const TriangleMesh& mesh);

// ASCII STL with the shortest decimal that reads back to the same double (exact round trip), written atomically.
void write_stl_ascii(const std::filesystem::path& path, const TriangleMesh& mesh,
                     const std::string& solid_name = "vmsim");

}  // namespace vmsim::core
