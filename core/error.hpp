#pragma once
// Errors a user can act on: every message names the file, the line or key, and what was expected.
#include <stdexcept>
#include <string>

namespace vmsim::core {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// "file:line: message" (line <= 0 omits the line).
inline std::string located(const std::string& file, int line, const std::string& message) {
  std::string s;
  s.reserve(file.size() + message.size() + 16);
  s.append(file);
  if (line > 0) s.append(":").append(std::to_string(line));
  s.append(": ").append(message);
  return s;
}

}  // namespace vmsim::core
