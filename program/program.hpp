#pragma once
// Reading a CNC program into a ToolPath, whatever its dialect: RS274/NGC G-code (LinuxCNC) or APT CL files.
#include "core/toolpath.hpp"
#include "program/apt.hpp"

#include <filesystem>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::program {

class MachineTransform;  // program/sinumerik.hpp

// The program's language: chosen by the file's extension and content ("auto"), or named ([job] program_dialect).
enum class Dialect { Auto, Rs274ngc, Sinumerik, Apt };
// "auto", "rs274ngc", "sinumerik", "apt"; throws core::Error naming the accepted values.
Dialect parse_dialect(const std::string& name);
const char* dialect_name(Dialect dialect);

struct ProgramOptions {
  std::optional<std::filesystem::path> tool_table;  // LinuxCNC tool table for G43 H / T words
  std::vector<int> no_motion_mcodes;                // G-code: remapped M codes without motion (see gcode.hpp)
  std::optional<std::array<double, 3>> start_mm;    // G-code and Sinumerik: where the tool starts
  std::uint64_t max_blocks = 20'000'000;  // G-code and Sinumerik: blocks executed before "possible endless loop"
  Dialect dialect = Dialect::Auto;
  // Sinumerik and APT: statements known to have no motion that vmsim does not model become warnings (path.warnings).
  bool lenient = false;
  // APT CL: the unit of a file without UNITS/ ([job] program_units); unset: mm with a warning.
  std::optional<LengthUnit> program_units;
  // Sinumerik: the machine's kinematics where TRAORI/TRAFOOF switch and CYCLE800 swivels (sinumerik.hpp); null:
  // the identity (exact while the rotary axes stand at zero).
  const MachineTransform* machine = nullptr;
};

// The dialect a file is read in under `requested`: Auto chooses by extension (.mpf .spf -> Sinumerik; .apt .cl .cls
// .aptsource -> APT CL; .ngc .nc .gcode .tap .txt -> RS274/NGC unless the text reads as the 840D's: DEF, MSG(,
// CYCLEnnn(, TRAORI, T="..", GOTOF, ...), or as an APT CL file (its first record TOOL PATH/, TLDATA/, GOTO/, ...:
// NX's information window saves CLSF listings as .txt). Throws core::Error for an extension no reader takes.
Dialect program_dialect(const std::filesystem::path& path, Dialect requested = Dialect::Auto);

// Reads the program in its dialect (program_dialect) into a ToolPath in the workpiece frame.
core::ToolPath read_program(const std::filesystem::path& path, const ProgramOptions& options = {});

}  // namespace vmsim::program
