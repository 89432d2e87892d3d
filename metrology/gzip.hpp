#pragma once
// gzip-compressed files (RFC 1952, "\x1f\x8b"): text grids and profiles are often stored so (matrix-4.txt.gz).
// Inflated with zlib (Debian's zlib1g; libzip depends on it already) rather than by hand.
#include <filesystem>
#include <string>
#include <string_view>

namespace vmsim::metrology {

inline bool looks_like_gzip(std::string_view head) {
  return head.size() >= 2 && static_cast<unsigned char>(head[0]) == 0x1f && static_cast<unsigned char>(head[1]) == 0x8b;
}

// The inflated bytes of every gzip member in the file, at most `max_bytes` of them. Throws core::Error naming the
// file when it is not gzip, is corrupt or truncated, or inflates to more than `max_bytes`.
std::string gunzip_file(const std::filesystem::path& file, std::size_t max_bytes = std::size_t{1} << 31);

}  // namespace vmsim::metrology
