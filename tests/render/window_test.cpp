// The headless window: works with no DISPLAY (Mesa EGL surfaceless), many pictures in one process neither leak nor
// print errors, several windows can live side by side, PNG files round-trip.
#include "render/chart.hpp"
#include "render/image.hpp"
#include "render/scene.hpp"
#include "render/window.hpp"
#include "render_test_support.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

using namespace vmsim;
using namespace vmsim::render;
using render::test::shared_window;

namespace {

double resident_mb() {
  std::ifstream in("/proc/self/statm");
  long size = 0, resident = 0;
  in >> size >> resident;
  return static_cast<double>(resident) * static_cast<double>(::sysconf(_SC_PAGESIZE)) / 1e6;
}

core::HeightGrid small_grid() {
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = 0.1;
  g.z_mm.resize(51, 101);
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i) g.z_mm(j, i) = 0.2 * std::sin(g.x(i)) * std::cos(g.y(j));
  return g;
}

std::filesystem::path temp_dir() {
  std::random_device rd;
  auto d =
      std::filesystem::temp_directory_path() / ("vmsim_render_" + std::to_string(rd()) + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace

TEST(Window, MadeWithoutDisplay) {
  Window& w = shared_window();
  EXPECT_EQ(std::getenv("DISPLAY"), nullptr);
  EXPECT_NE(w.gl_description().find("OpenGL"), std::string::npos) << w.gl_description();
}

// 50 pictures (part scenes and charts, alternately) in one window: the resident memory after the first 5 and after
// all 50 differ by less than a small bound, and VTK says nothing on stderr.
TEST(Window, FiftyRendersNoGrowthNoMessages) {
  Window& w = shared_window();
  const core::HeightGrid g = small_grid();
  core::HeightGrid d = g;
  d.z_mm = g.z_mm * 0.01;
  ChartPicture cp;
  cp.width = 320, cp.height = 200;
  Chart c;
  c.x_title = "t [s]";
  c.y_title = "y [mm]";
  Series s;
  s.x = Eigen::ArrayXd::LinSpaced(500, 0, 1);
  s.y = s.x.square();
  c.series.push_back(s);
  c.levels.push_back({"limit", 0.8});
  cp.charts.push_back(c);
  PartPicture pp;
  pp.width = 320, pp.height = 240;
  pp.caption = {"render"};
  pp.deviation = DeviationColours{};
  pp.deviation->isolines = 2;
  double after5 = 0;
  testing::internal::CaptureStderr();
  for (int k = 0; k < 50; ++k) {
    if (k % 2 == 0) {
      pp.view.direction = k % 4 == 0 ? ViewDirection::Isometric : ViewDirection::Top;
      const PartImage img = render_part(w, g, &d, pp);
      ASSERT_GT(test::distinct_colours(img.image), 50u) << k;
    } else {
      const ChartImage img = render_charts(w, cp);
      ASSERT_GT(test::distinct_colours(img.image), 10u) << k;
    }
    if (k == 4) after5 = resident_mb();
  }
  const std::string err = testing::internal::GetCapturedStderr();
  const double after50 = resident_mb();
  EXPECT_EQ(err, "");
  EXPECT_LT(after50 - after5, 12.0) << "resident memory " << after5 << " MB after 5 pictures, " << after50
                                    << " MB after 50";
  std::printf("resident memory: %.1f MB after 5 pictures, %.1f MB after 50\n", after5, after50);
}

// Windows made and destroyed one after another (each its own EGL context), and two alive at once.
TEST(Window, ManyWindowsComeAndGo) {
  ChartPicture cp;
  cp.width = 200, cp.height = 120;
  Chart c;
  Series s;
  s.x = Eigen::ArrayXd::LinSpaced(10, 0, 1);
  s.y = s.x;
  c.series.push_back(s);
  c.legend = false;
  cp.charts.push_back(c);
  double after2 = 0;
  for (int k = 0; k < 8; ++k) {
    Window w;
    EXPECT_NO_THROW(render_charts(w, cp));
    if (k == 1) after2 = resident_mb();
  }
  EXPECT_LT(resident_mb() - after2, 30.0);
  Window a, b;
  const ChartImage ia = render_charts(a, cp), ib = render_charts(b, cp);
  EXPECT_EQ(ia.image.rgb, ib.image.rgb);
  EXPECT_EQ(render_charts(a, cp).image.rgb, ia.image.rgb);  // a is still usable after b rendered
}

TEST(Window, PngRoundTripAndErrors) {
  Image img;
  img.width = 7, img.height = 5;
  img.rgb.resize(7 * 5 * 3);
  for (std::size_t k = 0; k < img.rgb.size(); ++k) img.rgb[k] = static_cast<std::uint8_t>(k * 37);
  const auto dir = temp_dir();
  write_png(dir / "a.png", img);
  const Image back = read_png(dir / "a.png");
  EXPECT_EQ(back.width, 7);
  EXPECT_EQ(back.height, 5);
  EXPECT_EQ(back.rgb, img.rgb);
  EXPECT_EQ(back.at(6, 4), img.at(6, 4));
  EXPECT_THROW(write_png(dir / "missing" / "a.png", img), core::Error);
  EXPECT_THROW(read_png(dir / "none.png"), core::Error);
  std::ofstream(dir / "text.png") << "not a png";
  EXPECT_THROW(read_png(dir / "text.png"), core::Error);
  Image bad = img;
  bad.rgb.pop_back();
  EXPECT_THROW(write_png(dir / "b.png", bad), core::Error);
  // No temporary file is left behind by the failed writes.
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 2u);  // a.png, text.png
  std::filesystem::remove_all(dir);
}
