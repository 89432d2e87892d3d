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

// Written through VTK's PNG writer to a temporary name, then renamed (DESIGN: no half-written outputs).
void write_png(const std::filesystem::path& file, const Image& image);
// For tests and tools that check a written picture. Throws core::Error naming the file.
Image read_png(const std::filesystem::path& file);

}  // namespace vmsim::render
