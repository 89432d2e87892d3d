// The PNG writer (render/png.cpp: one fixed row filter, the rows deflated by libdeflate or by zlib through libpng):
// PNG is lossless, so whatever the deflater, filter, level or zlib strategy, the file must decode to exactly the
// pixels given. References: VTK's vtkPNGReader (read_png),
// Python's PIL (its own PNG parser over zlib; skipped when /usr/bin/python3 or PIL is missing), and the PNG
// specification itself (W3C PNG, 2nd edition): the signature, the IHDR fields, and one filter-type byte before every
// scanline of the inflated IDAT stream, which must be the filter asked for.
#include "render/image.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

using namespace vmsim;
using namespace vmsim::render;

namespace {

// A picture with what vmsim's pictures hold: flat areas, gradients, sharp edges, noise (every byte value occurs).
Image pngw_test_image(int w, int h) {
  Image img;
  img.width = w, img.height = h;
  img.rgb.resize(static_cast<std::size_t>(w) * h * 3);
  std::uint32_t seed = 12345;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      seed = seed * 1664525u + 1013904223u;
      std::uint8_t* p = img.rgb.data() + (static_cast<std::size_t>(y) * w + x) * 3;
      if (x < w / 3) {  // flat
        p[0] = 30, p[1] = 32, p[2] = 40;
      } else if (x < 2 * w / 3) {  // gradient with an edge
        p[0] = static_cast<std::uint8_t>(y * 255 / h);
        p[1] = static_cast<std::uint8_t>(x * 3);
        p[2] = (x + y) % 17 == 0 ? 255 : 0;
      } else {  // noise
        p[0] = static_cast<std::uint8_t>(seed >> 24), p[1] = static_cast<std::uint8_t>(seed >> 16);
        p[2] = static_cast<std::uint8_t>(seed >> 8);
      }
    }
  return img;
}

// This test's own scratch directory, emptied ($TMPDIR/vmsim_render_png/<Suite.Test>; render tests do not include
// tests/test_paths.hpp: its vmsim::test would clash with render's test helpers in a unity batch).
std::filesystem::path pngw_scratch_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const auto dir = std::filesystem::temp_directory_path() / "vmsim_render_png" /
                   (std::string(info->test_suite_name()) + "." + info->name());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::uint32_t pngw_be32(const std::string& b, std::size_t at) {
  return (std::uint32_t(std::uint8_t(b[at])) << 24) | (std::uint32_t(std::uint8_t(b[at + 1])) << 16) |
         (std::uint32_t(std::uint8_t(b[at + 2])) << 8) | std::uint32_t(std::uint8_t(b[at + 3]));
}

// The inflated image data (all IDAT chunks, in order) of a PNG file's bytes.
std::string pngw_inflated_idat(const std::string& png, std::uint32_t& width, std::uint32_t& height) {
  std::string idat;
  std::size_t at = 8;
  while (at + 8 <= png.size()) {
    const std::uint32_t len = pngw_be32(png, at);
    const std::string type = png.substr(at + 4, 4);
    if (type == "IHDR") width = pngw_be32(png, at + 8), height = pngw_be32(png, at + 12);
    if (type == "IDAT") idat += png.substr(at + 8, len);
    at += 12 + len;  // length, type, data, CRC
  }
  std::string raw(static_cast<std::size_t>(height) * (1 + 3 * static_cast<std::size_t>(width)), '\0');
  uLongf n = static_cast<uLongf>(raw.size());
  EXPECT_EQ(uncompress(reinterpret_cast<Bytef*>(raw.data()), &n, reinterpret_cast<const Bytef*>(idat.data()),
                       static_cast<uLong>(idat.size())),
            Z_OK);
  EXPECT_EQ(n, raw.size());
  return raw;
}

}  // namespace

TEST(PngWriter, EveryFilterLevelAndStrategyDecodesToThePixelsGiven) {
  const Image img = pngw_test_image(97, 61);  // odd sizes: no row or byte alignment to lean on
  const auto dir = pngw_scratch_dir();
  for (PngFilter f : {PngFilter::None, PngFilter::Sub, PngFilter::Up, PngFilter::Paeth, PngFilter::Adaptive})
    for (int level : {0, 1, 3, 9})
      for (bool rle : {false, true}) {
        PngEncoding enc;
        enc.deflater = PngDeflater::Zlib;
        enc.filter = f, enc.level = level, enc.rle = rle;
        const auto file = dir / "p.png";
        write_png(file, img, enc);
        const Image back = read_png(file);
        ASSERT_EQ(back.width, img.width);
        ASSERT_EQ(back.height, img.height);
        EXPECT_EQ(back.rgb, img.rgb) << "filter " << static_cast<int>(f) << " level " << level << " rle " << rle;
      }
}

TEST(PngWriter, LibdeflateEveryFilterAndLevelDecodesToThePixelsGiven) {
  const Image img = pngw_test_image(97, 61);
  const auto dir = pngw_scratch_dir();
  for (PngFilter f : {PngFilter::None, PngFilter::Sub, PngFilter::Up, PngFilter::Paeth})
    for (int level : {0, 1, 4, 12}) {
      PngEncoding enc;
      enc.filter = f, enc.level = level;
      const auto file = dir / "p.png";
      write_png(file, img, enc);
      const Image back = read_png(file);
      ASSERT_EQ(back.width, img.width);
      ASSERT_EQ(back.height, img.height);
      EXPECT_EQ(back.rgb, img.rgb) << "filter " << static_cast<int>(f) << " level " << level;
    }
  // The filtered rows are the same whichever deflater compresses them: the inflated streams agree byte for byte.
  for (PngFilter f : {PngFilter::None, PngFilter::Sub, PngFilter::Up, PngFilter::Paeth}) {
    PngEncoding a, b;
    a.filter = b.filter = f;
    b.deflater = PngDeflater::Zlib;
    std::uint32_t w = 0, h = 0;
    EXPECT_EQ(pngw_inflated_idat(encode_png(img, a), w, h), pngw_inflated_idat(encode_png(img, b), w, h))
        << "filter " << static_cast<int>(f);
  }
}

TEST(PngWriter, HeaderAndEveryScanlineFollowThePngSpecificationWithTheFilterAsked) {
  const Image img = pngw_test_image(64, 40);
  for (auto [f, byte] : {std::pair{PngFilter::None, 0}, std::pair{PngFilter::Sub, 1}, std::pair{PngFilter::Up, 2},
                         std::pair{PngFilter::Paeth, 4}})
    for (PngDeflater d : {PngDeflater::Libdeflate, PngDeflater::Zlib}) {
      PngEncoding enc;
      enc.filter = f;
      enc.deflater = d;
      const std::string png = encode_png(img, enc);
      ASSERT_GT(png.size(), 33u);
      EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
      EXPECT_EQ(png.substr(12, 4), "IHDR");
      EXPECT_EQ(pngw_be32(png, 16), 64u);  // width
      EXPECT_EQ(pngw_be32(png, 20), 40u);  // height
      EXPECT_EQ(png[24], 8);               // bit depth
      EXPECT_EQ(png[25], 2);               // colour type: RGB
      EXPECT_EQ(png[28], 0);               // no interlacing
      EXPECT_EQ(png.substr(png.size() - 8, 4), "IEND");
      std::uint32_t w = 0, h = 0;
      const std::string raw = pngw_inflated_idat(png, w, h);
      ASSERT_EQ(raw.size(), 40u * (1 + 64 * 3));
      for (std::uint32_t y = 0; y < h; ++y) EXPECT_EQ(raw[y * (1 + 64 * 3)], byte) << "row " << y;
    }
  // The default (what vmsim's pictures use) is one fixed filter, UP.
  std::uint32_t w = 0, h = 0;
  const std::string raw = pngw_inflated_idat(encode_png(img), w, h);
  for (std::uint32_t y = 0; y < h; ++y) EXPECT_EQ(raw[y * (1 + 64 * 3)], 2) << "row " << y;
}

TEST(PngWriter, PilReadsTheSamePixels) {
  const char* python = "/usr/bin/python3";
  if (!std::filesystem::exists(python)) GTEST_SKIP() << "no /usr/bin/python3: the independent PIL reader is absent";
  if (std::system("/usr/bin/python3 -c 'import PIL' 2>/dev/null") != 0)
    GTEST_SKIP() << "Python's PIL is not installed (Debian package python3-pil): the independent reader is absent";
  const auto dir = pngw_scratch_dir();
  const Image img = pngw_test_image(131, 77);
  write_png(dir / "pil.png", img);  // the default encoding
  std::ofstream(dir / "pil.rgb", std::ios::binary)
      .write(reinterpret_cast<const char*>(img.rgb.data()), static_cast<std::streamsize>(img.rgb.size()));
  const std::string cmd = std::string(python) +
                          " -c \"import sys; from PIL import Image; im = Image.open(sys.argv[1]); " +
                          "sys.exit(0 if im.mode == 'RGB' and im.size == (131, 77) and im.tobytes() == " +
                          "open(sys.argv[2], 'rb').read() else 3)\" '" + (dir / "pil.png").string() + "' '" +
                          (dir / "pil.rgb").string() + "'";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
}

TEST(PngWriter, RefusesBadInputAndLeavesNoFileBehind) {
  const auto dir = pngw_scratch_dir();
  const Image img = pngw_test_image(20, 20);
  PngEncoding enc;
  enc.level = 13;
  EXPECT_THROW(encode_png(img, enc), core::Error);
  enc.level = 10;
  enc.deflater = PngDeflater::Zlib;
  EXPECT_THROW(encode_png(img, enc), core::Error);
  PngEncoding adaptive;  // libdeflate has no per-row choice of filter, nor zlib's strategies
  adaptive.filter = PngFilter::Adaptive;
  EXPECT_THROW(encode_png(img, adaptive), core::Error);
  PngEncoding rle;
  rle.rle = true;
  EXPECT_THROW(encode_png(img, rle), core::Error);
  Image bad = img;
  bad.rgb.pop_back();
  EXPECT_THROW(encode_png(bad), core::Error);
  try {
    write_png(dir / "bad.png", bad);
    ADD_FAILURE() << "an incomplete image was written";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.png"), std::string::npos) << e.what();
  }
  EXPECT_THROW(write_png(dir / "no" / "such" / "dir.png", img), core::Error);
  for (const auto& e : std::filesystem::directory_iterator(dir)) ADD_FAILURE() << "left behind: " << e.path();
}
