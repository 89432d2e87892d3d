// interpret_gcode: read the file and the tool table, run LinuxCNC's interpreter model over the program.
#include "program/gcode.hpp"
#include "core/regular_file.hpp"

#include "core/error.hpp"
#include "program/gcode_interp.hpp"
#include "program/gcode_lexer.hpp"
#include "program/tool_table.hpp"

#include <fstream>
#include <sstream>

namespace vmsim::program {

GcodeResult interpret_gcode(const std::filesystem::path& program, const GcodeOptions& options) {
  core::require_regular_file(program);
  std::ifstream in(program, std::ios::binary);
  if (!in) throw core::Error(program.string() + ": cannot open the G-code program");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw core::Error(program.string() + ": cannot read the G-code program");

  std::optional<ToolTable> tools;
  if (options.tool_table) tools = read_tool_table(*options.tool_table);

  const gcode::ParsedProgram parsed = gcode::parse_program(text.str());
  gcode::Interpreter interpreter(parsed, program.string(), options, tools ? &*tools : nullptr);
  return interpreter.run();
}

}  // namespace vmsim::program
