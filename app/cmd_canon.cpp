// vmsim canon: LinuxCNC's canonical machining calls for a G-code program, numbered as `rs274 -g` prints them.
#include "app/commands.hpp"
#include "program/gcode.hpp"

#include <cstdio>

namespace vmsim::app {

int run_canon(const std::filesystem::path& program, const std::optional<std::filesystem::path>& tool_table,
              const std::vector<int>& no_motion_mcodes) {
  program::GcodeOptions options;
  options.tool_table = tool_table;
  options.no_motion_mcodes = no_motion_mcodes;
  // Interpret everything first: an error prints nothing but the message (no half listing).
  const program::GcodeResult result = program::interpret_gcode(program, options);
  std::string out;
  out.reserve(result.canon.size() * 80);
  int number = 0;
  for (const program::CanonCall& call : result.canon) {
    out += program::format_canon_line(++number, call);
    out += '\n';
  }
  std::fwrite(out.data(), 1, out.size(), stdout);
  return std::fflush(stdout) == 0 ? 0 : 1;
}

}  // namespace vmsim::app
