// vmsim canon: LinuxCNC's canonical machining calls for a G-code program, numbered as `rs274 -g` prints them; the same
// vocabulary for Sinumerik 840D programs (positions in the workpiece frame, mm and degrees).
#include "app/commands.hpp"
#include "core/error.hpp"
#include "program/gcode.hpp"
#include "program/program.hpp"
#include "program/sinumerik.hpp"

#include <cstdio>

namespace vmsim::app {

int run_canon(const CanonArgs& args) {
  const program::Dialect dialect = program::program_dialect(args.program, program::parse_dialect(args.dialect));
  if (dialect == program::Dialect::Apt)
    throw core::Error(args.program.string() + ": vmsim canon reads G-code and Sinumerik programs, not APT CL files");
  // Interpret everything first: an error prints nothing but the message (no half listing).
  std::vector<program::CanonCall> canon;
  if (dialect == program::Dialect::Sinumerik) {
    program::SinumerikOptions options;
    options.no_motion_mcodes = args.no_motion_mcodes;
    options.lenient = args.lenient;
    program::SinumerikResult result = program::interpret_sinumerik(args.program, options);
    for (const std::string& w : result.warnings) std::fprintf(stderr, "vmsim: warning: %s\n", w.c_str());
    canon = std::move(result.canon);
  } else {
    program::GcodeOptions options;
    options.tool_table = args.tool_table;
    options.no_motion_mcodes = args.no_motion_mcodes;
    canon = program::interpret_gcode(args.program, options).canon;
  }
  std::string out;
  out.reserve(canon.size() * 80);
  int number = 0;
  for (const program::CanonCall& call : canon) {
    out += program::format_canon_line(++number, call);
    out += '\n';
  }
  std::fwrite(out.data(), 1, out.size(), stdout);
  return std::fflush(stdout) == 0 ? 0 : 1;
}

}  // namespace vmsim::app
