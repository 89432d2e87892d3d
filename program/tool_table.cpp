#include "program/tool_table.hpp"
#include "core/regular_file.hpp"

#include "core/error.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

namespace vmsim::program {

namespace {

double parse_number(const std::string& token, const std::string& file, int line) {
  std::string digits = token.substr(1);
  if (!digits.empty() && digits[0] == '+') digits.erase(0, 1);
  double v = 0.0;
  const char* first = digits.data();
  const char* last = digits.data() + digits.size();
  const auto res = std::from_chars(first, last, v);
  if (digits.empty() || res.ec != std::errc() || res.ptr != last || !std::isfinite(v))
    throw core::Error(core::located(file, line, "tool table field \"" + token + "\" is not a number"));
  return v;
}

int parse_int(const std::string& token, const std::string& file, int line) {
  const double v = parse_number(token, file, line);
  if (v != std::floor(v) || std::fabs(v) > 1e9)
    throw core::Error(core::located(file, line, "tool table field \"" + token + "\" must be a whole number"));
  return static_cast<int>(v);
}

}  // namespace

const ToolEntry* ToolTable::find(int number) const {
  for (const ToolEntry& t : tools)
    if (t.number == number) return &t;
  return nullptr;
}

ToolTable parse_tool_table(const std::string& text, const std::string& source_path) {
  ToolTable table;
  table.source_path = source_path;
  std::istringstream in(text);
  std::string raw;
  int line = 0;
  while (std::getline(in, raw)) {
    ++line;
    const std::size_t semicolon = raw.find(';');
    if (semicolon != std::string::npos) raw.resize(semicolon);
    std::istringstream fields(raw);
    std::string token;
    ToolEntry entry;
    bool has_t = false;
    bool any = false;
    while (fields >> token) {
      any = true;
      const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(token[0])));
      switch (letter) {
        case 'T':
          entry.number = parse_int(token, source_path, line);
          if (entry.number < 0) throw core::Error(core::located(source_path, line, "tool number must not be negative"));
          has_t = true;
          break;
        case 'P':
          entry.pocket = parse_int(token, source_path, line);
          break;
        case 'X':
          entry.offset[0] = parse_number(token, source_path, line);
          break;
        case 'Y':
          entry.offset[1] = parse_number(token, source_path, line);
          break;
        case 'Z':
          entry.offset[2] = parse_number(token, source_path, line);
          break;
        case 'A':
          entry.offset[3] = parse_number(token, source_path, line);
          break;
        case 'B':
          entry.offset[4] = parse_number(token, source_path, line);
          break;
        case 'C':
          entry.offset[5] = parse_number(token, source_path, line);
          break;
        case 'D':
          entry.diameter = parse_number(token, source_path, line);
          break;
        // Lathe data (front/back angle, orientation) and U V W offsets: read, not used by a milling machine.
        case 'I':
        case 'J':
        case 'Q':
          parse_number(token, source_path, line);
          break;
        case 'U':
        case 'V':
        case 'W':
          if (parse_number(token, source_path, line) != 0.0)
            throw core::Error(
                core::located(source_path, line, "tool offset \"" + token + "\": U, V and W axes are not supported"));
          break;
        default:
          throw core::Error(core::located(
              source_path, line, "unknown tool table field \"" + token + "\" (expected T P X Y Z A B C D I J Q)"));
      }
    }
    if (!any) continue;
    if (!has_t) throw core::Error(core::located(source_path, line, "tool table line has no T (tool number) field"));
    if (table.find(entry.number) != nullptr)
      throw core::Error(core::located(source_path, line, "tool T" + std::to_string(entry.number) + " is listed twice"));
    entry.index = static_cast<int>(table.tools.size()) + 1;
    entry.source_line = line;
    table.tools.push_back(entry);
  }
  return table;
}

ToolTable read_tool_table(const std::filesystem::path& path) {
  core::require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::Error(path.string() + ": cannot open the tool table");
  std::ostringstream buf;
  buf << in.rdbuf();
  return parse_tool_table(buf.str(), path.string());
}

}  // namespace vmsim::program
