// The cheaper pictures' choices (issue 21): the PNG compression level changes the file's size, never its pixels; FXAA
// and 4x multisampling change a 3-D view's pixels only along its edges (the raking light's shading inside a face is
// the same), and never touch a Top map; a chart's antialiasing is a choice the picture states.
// References: the pixels written (PNG is lossless: every level must read back the same bytes) and the picture drawn
// without antialiasing (its edges found from its own colour jumps).
#include "render/chart.hpp"
#include "render/scene.hpp"
#include "render_test_support.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <unistd.h>

using namespace vmsim;
using namespace vmsim::render;

namespace {

std::filesystem::path costtest_dir() {
  auto d = std::filesystem::temp_directory_path() / ("vmsim_render_cost_" + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  return d;
}

// A block with a bump and a tilted top: silhouettes against the background on every side.
core::HeightGrid costtest_block() {
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = 0.1;
  g.z_mm.resize(101, 151);
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i)
      g.z_mm(j, i) = 0.05 * g.x(i) + 1.5 * std::exp(-std::pow(g.x(i) - 7, 2) / 4 - std::pow(g.y(j) - 5, 2) / 3);
  return g;
}

// Pixels whose colour differs by more than `jump` from one of their 8 neighbours: edges, including the soft ones
// between two faces of the block.
std::vector<char> costtest_edges(const Image& img, double jump) {
  std::vector<char> e(static_cast<std::size_t>(img.width) * img.height, 0);
  for (int y = 1; y + 1 < img.height; ++y)
    for (int x = 1; x + 1 < img.width; ++x)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if (test::colour_distance(img.at(x, y), img.at(x + dx, y + dy)) > jump)
            e[static_cast<std::size_t>(y) * img.width + x] = 1;
  return e;
}

bool costtest_near(const std::vector<char>& mask, int w, int h, int x, int y, int r) {
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const int px = x + dx, py = y + dy;
      if (px >= 0 && py >= 0 && px < w && py < h && mask[static_cast<std::size_t>(py) * w + px]) return true;
    }
  return false;
}

}  // namespace

TEST(PictureCost, PngLevelChangesSizeNotPixels) {
  // A real picture (a part under the raking light), not noise: what the levels are chosen for.
  PartPicture pic;
  pic.width = 480, pic.height = 360;
  pic.caption = {"block"};
  const Image img = render_part(test::shared_window(), costtest_block(), nullptr, pic).image;
  const auto dir = costtest_dir();
  std::vector<std::uintmax_t> size;
  for (int level : {0, 1, 3, 12}) {
    const auto f = dir / ("l" + std::to_string(level) + ".png");
    write_png(f, img, level);
    EXPECT_EQ(read_png(f).rgb, img.rgb) << "level " << level;
    size.push_back(std::filesystem::file_size(f));
  }
  EXPECT_GT(size[0], 2 * size[1]);  // stored (level 0) against deflated
  EXPECT_GE(size[1], size[3]);      // libdeflate's level 12 is no larger than level 1
  EXPECT_THROW(write_png(dir / "x.png", img, 13), core::Error);
  EXPECT_THROW(write_png(dir / "x.png", img, -1), core::Error);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
  std::filesystem::remove_all(dir);
}

TEST(PictureCost, AntialiasingTouchesEdgesOnly) {
  PartPicture pic;
  pic.width = 480, pic.height = 360;
  pic.caption = {"block"};
  const core::HeightGrid g = costtest_block();
  pic.antialiasing = Antialiasing::None;
  const Image none = render_part(test::shared_window(), g, nullptr, pic).image;
  const std::vector<char> edges = costtest_edges(none, 10);
  for (Antialiasing aa : {Antialiasing::Fxaa, Antialiasing::Msaa4}) {
    pic.antialiasing = aa;
    const Image smooth = render_part(test::shared_window(), g, nullptr, pic).image;
    int changed = 0, away = 0;
    for (int y = 0; y < none.height; ++y)
      for (int x = 0; x < none.width; ++x) {
        if (test::colour_distance(none.at(x, y), smooth.at(x, y)) <= 3) continue;
        ++changed;
        if (!costtest_near(edges, none.width, none.height, x, y, 2)) ++away;
      }
    const char* name = aa == Antialiasing::Fxaa ? "FXAA" : "MSAA";
    std::printf("%s: %d pixels changed, %d of them away from edges\n", name, changed, away);
    EXPECT_GT(changed, 100) << name << " smoothed nothing";
    EXPECT_LE(away, changed / 100) << name << ": " << away << " of " << changed
                                   << " changed pixels lie away from edges";
    test::keep_if_failed(smooth, name);
  }
  // A Top map stays exact whatever is asked.
  pic.view.direction = ViewDirection::Top;
  pic.antialiasing = Antialiasing::None;
  const Image map_none = render_part(test::shared_window(), g, nullptr, pic).image;
  pic.antialiasing = Antialiasing::Msaa4;
  EXPECT_EQ(render_part(test::shared_window(), g, nullptr, pic).image.rgb, map_none.rgb);
}

TEST(PictureCost, ChartAntialiasingIsAChoice) {
  ChartPicture pic;
  pic.width = 640, pic.height = 360;
  Chart c;
  c.x_title = "t [s]";
  c.y_title = "v [mm/s]";
  Eigen::ArrayXd x = Eigen::ArrayXd::LinSpaced(400, 0, 10);
  c.series.push_back(make_series("sine", x, (x * 1.3).sin() * 50, 0, 1.6));
  pic.charts.push_back(c);
  const Image plain = render_charts(test::shared_window(), pic).image;
  EXPECT_EQ(render_charts(test::shared_window(), pic).image.rgb, plain.rgb);  // the default is repeatable
  pic.antialiasing = Antialiasing::Msaa4;
  const Image msaa = render_charts(test::shared_window(), pic).image;
  EXPECT_NE(msaa.rgb, plain.rgb);
  // Multisampling blends the sloped curve's edges: more distinct colours than the plain picture's few.
  EXPECT_GT(test::distinct_colours(msaa), test::distinct_colours(plain));
}
