#include "program/program.hpp"
#include "core/regular_file.hpp"

#include "core/error.hpp"
#include "program/apt.hpp"
#include "program/gcode.hpp"
#include "program/sinumerik.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>

namespace vmsim::program {

Dialect parse_dialect(const std::string& name) {
  if (name == "auto") return Dialect::Auto;
  if (name == "rs274ngc") return Dialect::Rs274ngc;
  if (name == "sinumerik") return Dialect::Sinumerik;
  if (name == "apt") return Dialect::Apt;
  throw core::Error("program dialect \"" + name + "\": expected auto, rs274ngc, sinumerik or apt");
}

const char* dialect_name(Dialect dialect) {
  switch (dialect) {
    case Dialect::Auto:
      return "auto";
    case Dialect::Rs274ngc:
      return "rs274ngc";
    case Dialect::Sinumerik:
      return "sinumerik";
    case Dialect::Apt:
      return "apt";
  }
  return "auto";
}

namespace {
// The first 64 KiB: enough for the content test, which looks at the first lines only.
std::string head_of(const std::filesystem::path& path) {
  core::require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::Error(path.string() + ": cannot open the program");
  std::string text(64 * 1024, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  return text;
}
}  // namespace

Dialect program_dialect(const std::filesystem::path& path, Dialect requested) {
  if (requested != Dialect::Auto) return requested;
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".mpf" || ext == ".spf") return Dialect::Sinumerik;
  if (ext == ".apt" || ext == ".cl" || ext == ".cls" || ext == ".aptsource") return Dialect::Apt;
  if (ext == ".ngc" || ext == ".nc" || ext == ".gcode" || ext == ".tap" || ext == ".txt") {
    const std::string head = head_of(path);
    if (looks_like_apt(head)) return Dialect::Apt;
    return looks_like_sinumerik_program(head) ? Dialect::Sinumerik : Dialect::Rs274ngc;
  }
  throw core::Error(path.string() + ": unknown program type \"" + ext +
                    "\" (expected G-code: .ngc .nc .gcode .tap .txt, Sinumerik: .mpf .spf, or APT CL: .apt .cl .cls; "
                    "[job] program_dialect or --dialect names the dialect of other files)");
}

core::ToolPath read_program(const std::filesystem::path& path, const ProgramOptions& options) {
  switch (program_dialect(path, options.dialect)) {
    case Dialect::Apt: {
      AptOptions a;
      a.default_unit = options.program_units;
      a.lenient = options.lenient;
      return read_apt(path, a);
    }
    case Dialect::Sinumerik: {
      SinumerikOptions s;
      s.lenient = options.lenient;
      s.no_motion_mcodes = options.no_motion_mcodes;
      s.start_mm = options.start_mm;
      s.machine = options.machine;
      s.max_blocks = options.max_blocks;
      SinumerikResult r = interpret_sinumerik(path, s);
      r.path.warnings = std::move(r.warnings);
      r.path.program_tolerance_mm = r.contour_tolerance_mm;
      r.path.tool_names = std::move(r.tools);
      return std::move(r.path);
    }
    case Dialect::Rs274ngc:
    case Dialect::Auto:
      break;
  }
  GcodeOptions g;
  g.tool_table = options.tool_table;
  g.no_motion_mcodes = options.no_motion_mcodes;
  g.start_mm = options.start_mm;
  g.max_blocks = options.max_blocks;
  return read_gcode(path, g);
}

}  // namespace vmsim::program
