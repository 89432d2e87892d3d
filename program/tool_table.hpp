#pragma once
// LinuxCNC tool tables: one tool a line, e.g. "T1 P1 Z+0.511 D0.125 ;1/8 end mill".
// Values are in the machine's length units (LinuxCNC's INI LINEAR_UNITS); the reader keeps them as written.
#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::program {

struct ToolEntry {
  int number = 0;         // T
  int pocket = 0;         // P
  double offset[6] = {};  // X Y Z A B C offsets (length units of the table, degrees)
  double diameter = 0;    // D
  int index = 0;          // 1-based order in the file (what LinuxCNC's CHANGE_TOOL reports)
  int source_line = 0;
};

struct ToolTable {
  std::string source_path;
  std::vector<ToolEntry> tools;
  const ToolEntry* find(int number) const;
};

// Throws core::Error naming the file, the line and the offending field.
ToolTable read_tool_table(const std::filesystem::path& path);
ToolTable parse_tool_table(const std::string& text, const std::string& source_path);

}  // namespace vmsim::program
