#pragma once
// What the surface readers (X3P, .sur, BCR, SDF, ASCII grids, Dektak) share: the largest grid they accept and the
// blank-trimming of header text.
#include <cctype>
#include <cstdint>
#include <string>
#include <string_view>

namespace vmsim::metrology {

// The largest grid a reader accepts: 2^28 points (2 GiB of doubles) is far beyond a confocal scan (a 2000 x 2000
// STIL scan has 4 M). Nothing is allocated for the points before the data's size is checked against it.
inline constexpr std::uint64_t kMaxGridPoints = std::uint64_t{1} << 28;

// s without leading and trailing white space (C locale).
inline std::string trim_blanks(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return std::string(s);
}

}  // namespace vmsim::metrology
