#pragma once
// Shared by the render tests: one headless window per test process (made once: EGL and VTK's shaders), the DISPLAY
// removed so that nothing can fall back to X11, and small pixel helpers.
#include "render/image.hpp"
#include "render/window.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <memory>

namespace vmsim::render::test {

inline Window& shared_window() {
  static std::unique_ptr<Window> w = [] {
    ::unsetenv("DISPLAY");
    return std::make_unique<Window>();
  }();
  return *w;
}

inline double colour_distance(const Rgb8& a, const Rgb8& b) {
  double d = 0;
  for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(double(a[c]) - double(b[c])));
  return d;
}

inline Rgb8 to8(double r, double g, double b) {
  auto q = [](double v) { return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255)); };
  return {q(r), q(g), q(b)};
}

// Smallest distance to `want` among the pixels within `radius` of (x, y).
inline double nearest_match(const Image& img, double x, double y, const Rgb8& want, int radius) {
  double best = 1e9;
  const int cx = static_cast<int>(std::floor(x)), cy = static_cast<int>(std::floor(y));
  for (int dy = -radius; dy <= radius; ++dy)
    for (int dx = -radius; dx <= radius; ++dx) {
      const int px = cx + dx, py = cy + dy;
      if (px < 0 || py < 0 || px >= img.width || py >= img.height) continue;
      best = std::min(best, colour_distance(img.at(px, py), want));
    }
  return best;
}

// When the current test has failed, keeps the picture for a look: $TMPDIR/vmsim_render_<test>.png.
inline void keep_if_failed(const Image& img, const std::string& tag = "") {
  if (!testing::Test::HasFailure()) return;
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  const auto file = std::filesystem::temp_directory_path() /
                    (std::string("vmsim_render_") + info->test_suite_name() + "_" + info->name() + tag + ".png");
  write_png(file, img);
  std::printf("picture kept: %s\n", file.string().c_str());
}

// Number of distinct colours (a uniform picture has one).
inline std::size_t distinct_colours(const Image& img) {
  std::vector<std::uint32_t> c;
  c.reserve(static_cast<std::size_t>(img.width) * img.height);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const Rgb8 p = img.at(x, y);
      c.push_back((std::uint32_t(p[0]) << 16) | (std::uint32_t(p[1]) << 8) | p[2]);
    }
  std::sort(c.begin(), c.end());
  return static_cast<std::size_t>(std::unique(c.begin(), c.end()) - c.begin());
}

}  // namespace vmsim::render::test
