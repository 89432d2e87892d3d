#pragma once
// Paths as text: report.json (JSON) and X3P's main.xml (XML) hold UTF-8 only.
#include <filesystem>
#include <string_view>

namespace vmsim::core {

// Whether BYTES are UTF-8 (RFC 3629: no overlong forms, no surrogates, nothing beyond U+10FFFF).
bool is_valid_utf8(std::string_view bytes);

// Refuses (core::Error naming WHAT and the path, its stray bytes shown as \xNN) a path that is not valid UTF-8. Paths
// go into report.json and X3P files; escaping them would make a path no reader can open again, so the path is refused
// before the run rather than lost (or mangled) after it.
void require_utf8_path(const std::filesystem::path& path, std::string_view what);

}  // namespace vmsim::core
