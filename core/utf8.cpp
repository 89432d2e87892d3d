#include "core/utf8.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <cstdint>
#include <string>

namespace vmsim::core {

namespace fs = std::filesystem;

bool is_valid_utf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    std::size_t n;
    std::uint32_t cp;
    if (c < 0x80) {
      ++i;
      continue;
    }
    if ((c & 0xE0) == 0xC0) {
      n = 1;
      cp = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      n = 2;
      cp = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      n = 3;
      cp = c & 0x07;
    } else
      return false;
    if (i + n >= s.size()) return false;  // truncated sequence
    for (std::size_t k = 1; k <= n; ++k) {
      const auto d = static_cast<unsigned char>(s[i + k]);
      if ((d & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (d & 0x3F);
    }
    // Overlong forms, surrogates and values beyond U+10FFFF are not UTF-8 (RFC 3629).
    if ((n == 1 && cp < 0x80) || (n == 2 && cp < 0x800) || (n == 3 && cp < 0x10000) || cp > 0x10FFFF ||
        (cp >= 0xD800 && cp <= 0xDFFF))
      return false;
    i += n + 1;
  }
  return true;
}

void require_utf8_path(const fs::path& path, std::string_view what) {
  if (is_valid_utf8(path.native())) return;
  // The message shows the bytes that are not UTF-8 as \xNN, so the user can find the file.
  std::string shown;
  for (const unsigned char c : path.native()) {
    if (c >= 0x20 && c < 0x7F)
      shown += static_cast<char>(c);
    else
      shown += fmt::format("\\x{:02x}", c);
  }
  throw Error(
      fmt::format("{}: {} is not valid UTF-8; report.json and X3P files hold UTF-8 text and cannot record it "
                  "losslessly: rename it (or a directory above it)",
                  shown, what));
}

}  // namespace vmsim::core
