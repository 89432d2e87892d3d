#pragma once
// Rendered pictures as plain pixels: what the render functions return, what tests inspect, what PNG files hold.
#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace vmsim::render {

using Rgb8 = std::array<std::uint8_t, 3>;

// 8-bit RGB, row 0 at the top (as in the PNG file), x to the right.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // width * height * 3

  Rgb8 at(int x, int y) const {
    const std::size_t o =
        (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3;
    return {rgb[o], rgb[o + 1], rgb[o + 2]};
  }
};

// Written through VTK's PNG writer to a temporary name, then renamed (DESIGN: no half-written outputs). zlib level 3
// by default: on vmsim's pictures as cheap as level 1 and 6 % smaller; VTK's own 5 costs ~50 % more CPU for 11 %
// fewer bytes (bench/README.md "Pictures' CPU"). Throws core::Error for a level outside 0..9.
void write_png(const std::filesystem::path& file, const Image& image, int zlib_level = 3);
// For tests and tools that check a written picture. Throws core::Error naming the file.
Image read_png(const std::filesystem::path& file);

}  // namespace vmsim::render
