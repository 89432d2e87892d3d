#pragma once
// Reading a CNC program into a ToolPath, whatever its dialect: RS274/NGC G-code (LinuxCNC) or APT CL files.
#include "core/toolpath.hpp"

#include <filesystem>
#include <optional>

namespace vmsim::core {

struct ProgramOptions {
  std::optional<std::filesystem::path> tool_table;  // LinuxCNC tool table for G43 H / T words
};

// Chooses the reader by extension: .ngc .nc .gcode .tap .txt -> G-code; .apt .cl .cls .aptsource -> APT CL.
ToolPath read_program(const std::filesystem::path& path, const ProgramOptions& options = {});

}  // namespace vmsim::core
