#pragma once
// The result files of a run (sim/run.hpp) in an output directory: heights as CSV, .npy and X3P, the reference and
// the deviation, the needles' CSV, the part mesh (STL, VTK XML, the level set's .vdb), the drive signals. `vmsim run`
// and the Python module's job.run(out=...) write them through this one writer, so they write the same files.
#include "core/job.hpp"
#include "core/mesh.hpp"
#include "sim/run.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace vmsim::sim {

// Writes a mesh as VTK XML PolyData: render/mesh_io.hpp's write_vtp, which sim/ may not call (render/ is above it
// in the layering), so the caller passes it.
// The third argument is the zlib level (1..9).
using VtpWriter = std::function<void(const std::filesystem::path&, const core::TriangleMesh&, int)>;

// Every result file of `r` that the job's [outputs] asks for into `dir` (which exists), each through
// core/atomic_file; returns their names relative to dir, in the order report.json lists them. With `report`, adds
// report["outputs"]: which part mesh was written (its error bound when simplified), whether the CSV grids were, and
// a note saying how to get what a large grid's defaults left out. Throws core::Error naming the file that could not
// be written.
std::vector<std::string> write_run_outputs(const core::Job& job, const RunResult& r, const std::filesystem::path& dir,
                                           const VtpWriter& write_vtp, nlohmann::json* report = nullptr);

}  // namespace vmsim::sim
