#pragma once
// Rendered pictures as plain pixels: what the render functions return, what tests inspect, what PNG files hold.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
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

// PNG row filters (libpng's): each row is stored as its difference from a prediction before zlib sees it.
enum class PngFilter {
  None,      // the bytes as they are
  Sub,       // minus the pixel to the left
  Up,        // minus the pixel above
  Paeth,     // minus the best of left, above, upper-left
  Adaptive,  // libpng's choice per row among all five: the smallest files, ~4x the filtering CPU
};

// What compresses the filtered rows (both write the same zlib stream format; any PNG reader reads either).
enum class PngDeflater {
  Libdeflate,  // libdeflate, whole image at once: levels 0..12; at 4 ~1/3 less CPU than zlib at 3, ~10 % smaller
  Zlib,        // zlib through libpng: levels 0..9; needed for the Adaptive filter and the RLE strategy
};

struct PngEncoding {
  PngDeflater deflater = PngDeflater::Libdeflate;
  int level = 4;  // the deflater's compression level
  PngFilter filter = PngFilter::Up;
  bool rle = false;  // zlib's run-length strategy (matches at distance 1 only): cheaper, larger (Zlib only)
};

// The PNG file's bytes (8-bit RGB, no interlacing). The default encoding is what vmsim writes its pictures with
// (bench/README.md "Pictures' CPU, round 2" and "round 4"). Throws core::Error for a level outside the deflater's
// range, a filter or strategy the deflater does not offer, or an incomplete image.
std::string encode_png(const Image& image, const PngEncoding& encoding = {});
// encode_png's bytes written through core::write_file_atomic (no half-written file). Throws core::Error naming the
// file.
void write_png(const std::filesystem::path& file, const Image& image, const PngEncoding& encoding);
// With the default deflater at `level`.
void write_png(const std::filesystem::path& file, const Image& image, int level = PngEncoding{}.level);
// For tests and tools that check a written picture. Throws core::Error naming the file.
Image read_png(const std::filesystem::path& file);

}  // namespace vmsim::render
