#pragma once
// APT CL files (cutter location source) as CAM systems write them for 3- and 5-axis work, NX CLSF included.
#include "core/toolpath.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace vmsim::program {

enum class LengthUnit { Mm, Inch };

struct AptOptions {
  // The unit of a file without UNITS/ ([job] program_units). Unset and no UNITS/: read as mm with a warning.
  std::optional<LengthUnit> default_unit;
  // Records known not to move the tool whose effect vmsim does not model (DELAY, DWELL, CUTCOM other than OFF,
  // ORIGIN): warnings (ToolPath::warnings) instead of errors ([job] program_lenient).
  bool lenient = false;
};

// GOTO/x,y,z[,i,j,k], FEDRAT/, RAPID, CIRCLE/, CUTTER/, TLDATA/, UNITS/, MSYS/, comments, ... Errors name the file,
// line and record; what was accepted without being modelled is in ToolPath::warnings.
core::ToolPath read_apt(const std::filesystem::path& program, const AptOptions& options = {});
// The same for text in memory; `name` stands for the file in messages.
core::ToolPath read_apt_text(const std::string& text, const std::string& name, const AptOptions& options = {});

// Whether text reads as an APT CL file: its first record (after an NX information-listing header, blank lines and $$
// comments) is an APT major word with a slash (TOOL PATH/, TLDATA/, GOTO/, ...) or PARTNO. For .txt files, which
// NX's information window writes.
bool looks_like_apt(std::string_view text);

}  // namespace vmsim::program
