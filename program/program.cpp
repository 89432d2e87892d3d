#include "program/program.hpp"

#include "program/apt.hpp"
#include "core/error.hpp"
#include "program/gcode.hpp"

#include <algorithm>
#include <cctype>

namespace vmsim::program {

core::ToolPath read_program(const std::filesystem::path& path, const ProgramOptions& options) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".apt" || ext == ".cl" || ext == ".cls" || ext == ".aptsource") return read_apt(path);
  if (ext == ".ngc" || ext == ".nc" || ext == ".gcode" || ext == ".tap" || ext == ".txt") {
    GcodeOptions g;
    g.tool_table = options.tool_table;
    g.no_motion_mcodes = options.no_motion_mcodes;
    g.start_mm = options.start_mm;
    g.max_blocks = options.max_blocks;
    return read_gcode(path, g);
  }
  throw core::Error(path.string() + ": unknown program type \"" + ext +
              "\" (expected G-code: .ngc .nc .gcode .tap, or APT CL: .apt .cl .cls)");
}

}  // namespace vmsim::program
