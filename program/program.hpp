#pragma once
// Reading a CNC program into a ToolPath, whatever its dialect: RS274/NGC G-code (LinuxCNC) or APT CL files.
#include "core/toolpath.hpp"

#include <filesystem>
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

namespace vmsim::program {

struct ProgramOptions {
  std::optional<std::filesystem::path> tool_table;  // LinuxCNC tool table for G43 H / T words
  std::vector<int> no_motion_mcodes;                 // G-code: remapped M codes without motion (see gcode.hpp)
  std::optional<std::array<double, 3>> start_mm;     // G-code: where the tool starts (see gcode.hpp)
  std::uint64_t max_blocks = 20'000'000;             // G-code: blocks executed before "possible endless loop"
};

// Chooses the reader by extension: .ngc .nc .gcode .tap .txt -> G-code; .apt .cl .cls .aptsource -> APT CL.
core::ToolPath read_program(const std::filesystem::path& path, const ProgramOptions& options = {});

}  // namespace vmsim::program
