#pragma once
// APT CL files (cutter location source) as CAM systems write them for 3- and 5-axis work.
#include "core/toolpath.hpp"

#include <filesystem>

namespace vmsim::program {

// GOTO/x,y,z[,i,j,k], FEDRAT/, RAPID, CUTTER/, UNITS/, comments, ... Errors name the file, line and record.
core::ToolPath read_apt(const std::filesystem::path& program);

}  // namespace vmsim::program
