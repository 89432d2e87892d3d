// Pictures from the command line, with no DISPLAY: vmsim run draws them into OUT/images, vmsim render redraws them
// from the files, signals.csv carries the charts' data; a missing EGL driver is an error, not an abort. References:
// the plane-cylinder fast pass leaves an undercut (material left) of ~19 um at the fillet, so its deviation map
// must hold the red end of the colour map and none of the blue end.
#include "render/image.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_util.hpp"
#include "tests/test_paths.hpp"

using vmsim_test::CliRun;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace fs = std::filesystem;
using vmsim::render::Image;
using vmsim::render::read_png;

namespace {

// Runs vmsim with no DISPLAY (as on a server), `env` prepended to the command (e.g. "VAR=value").
CliRun run_headless(const std::string& args, const TempDir& tmp, const std::string& env = "") {
  return run_vmsim(args, tmp, "env -u DISPLAY " + env + " ");
}

// Pixels left of x_end for which pred(r, g, b) holds.
std::size_t count_pixels(const Image& img, int x_end, bool (*pred)(int, int, int)) {
  std::size_t n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < std::min(x_end, img.width); ++x) {
      const auto p = img.at(x, y);
      if (pred(p[0], p[1], p[2])) ++n;
    }
  return n;
}

bool deep_red(int r, int g, int b) { return r > 110 && g < 60 && b < 70; }
bool deep_blue(int r, int g, int b) { return b > 110 && r < 60 && g < 120; }

using vmsim::test::kSourceDir;

}  // namespace

TEST(RenderCli, RunDrawsThePicturesAndRenderRedrawsThem) {
  TempDir tmp;
  const fs::path out = tmp.path() / "out";
  const std::string job = kSourceDir + "/parts/plane_cylinder/job_fast.toml";
  CliRun r = run_headless("run '" + job + "' --quiet --image-size 800x600 --out '" + out.string() + "'", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("images: "), std::string::npos) << r.out;
  for (const char* f :
       {"part.png", "part_mark.png", "deviation.png", "deviation_mark.png", "deviation_3d.png", "contour_error.png",
        "feed.png", "currents.png", "axis_X.png", "axis_Z.png", "position_X.png", "position_Z.png"}) {
    ASSERT_TRUE(fs::exists(out / "images" / f)) << f;
    const Image img = read_png(out / "images" / f);
    EXPECT_EQ(img.width, 800) << f;
    EXPECT_EQ(img.height, 600) << f;
    std::vector<std::uint32_t> colours;
    for (int y = 0; y < img.height; y += 3)
      for (int x = 0; x < img.width; x += 3) {
        const auto p = img.at(x, y);
        colours.push_back((std::uint32_t(p[0]) << 16) | (std::uint32_t(p[1]) << 8) | p[2]);
      }
    std::sort(colours.begin(), colours.end());
    EXPECT_GT(std::unique(colours.begin(), colours.end()) - colours.begin(), 40) << f << " is (nearly) uniform";
  }
  // The axes that do not move get no pictures.
  EXPECT_FALSE(fs::exists(out / "images" / "axis_Y.png"));
  // The fast pass leaves material (undercut): the zoomed map holds the red end of the scale, not the blue end (the
  // map only: the colour scale on the right holds both).
  const Image map = read_png(out / "images" / "deviation_mark.png");
  EXPECT_GT(count_pixels(map, 640, deep_red), 200u);
  EXPECT_EQ(count_pixels(map, 640, deep_blue), 0u);
  // report.json lists the pictures; signals.csv holds the limits and the binned signals.
  const std::string rep = slurp(out / "report.json");
  EXPECT_NE(rep.find("\"images/deviation.png\""), std::string::npos);
  EXPECT_NE(rep.find("\"render\""), std::string::npos);
  EXPECT_NE(rep.find("\"signals.csv\""), std::string::npos);
  const std::string sig = slurp(out / "signals.csv");
  EXPECT_EQ(sig.rfind("# vmsim signals 1", 0), 0u);
  EXPECT_NE(sig.find("# limit X_velocity_mm_per_s=500\n"), std::string::npos);
  EXPECT_NE(sig.find("# axes=X:mm,Z:mm\n"), std::string::npos);
  EXPECT_NE(sig.find("contour_error_mm.min,contour_error_mm.max"), std::string::npos);
  // report.html shows every picture, and the report's figures.
  vmsim_test::expect_report_html(out, "--pictures yes");

  // vmsim render: the same directory, other size, a given region and colour limits, into another directory that
  // holds a stale picture of an axis that does not move here (removed) and a file of the user's (kept).
  const fs::path again = tmp.path() / "again";
  fs::create_directories(again);
  std::ofstream(again / "axis_Y.png") << "stale";
  std::ofstream(again / "notes.png") << "mine";
  CliRun rr =
      run_headless("render '" + out.string() +
                       "' --size 640x360 --region 78,94,0,10 --limit-um 30 --isolines 2 --out '" + again.string() + "'",
                   tmp);
  ASSERT_EQ(rr.code, 0) << rr.err;
  std::stringstream lines(rr.out);
  std::string line;
  int n = 0;
  while (std::getline(lines, line)) {
    ASSERT_TRUE(fs::exists(line)) << line;
    const Image img = read_png(line);
    EXPECT_EQ(img.width, 640);
    EXPECT_EQ(img.height, 360);
    ++n;
  }
  EXPECT_EQ(n, 12);
  EXPECT_FALSE(fs::exists(again / "axis_Y.png"));
  EXPECT_TRUE(fs::exists(again / "notes.png"));
}

TEST(RenderCli, MotionWritesSignalsAndRenderDrawsItsCharts) {
  TempDir tmp;
  const fs::path out = tmp.path() / "motion";
  const std::string job = kSourceDir + "/parts/plane_cylinder/job_fast.toml";
  CliRun m = run_headless("motion '" + job + "' --out '" + out.string() + "'", tmp);
  ASSERT_EQ(m.code, 0) << m.err;
  ASSERT_TRUE(fs::exists(out / "signals.csv"));
  CliRun r = run_headless("render '" + out.string() + "' --size 480x320", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(out / "images" / "contour_error.png"));
  EXPECT_TRUE(fs::exists(out / "images" / "axis_X.png"));
  EXPECT_FALSE(fs::exists(out / "images" / "part.png"));  // no surface in a motion directory
}

TEST(RenderCli, ErrorsAreMessagesNotAborts) {
  TempDir tmp;
  // Nothing to draw: no report.json, so not a complete result (and nothing listed to draw).
  fs::create_directories(tmp.path() / "empty");
  CliRun e = run_headless("render '" + (tmp.path() / "empty").string() + "'", tmp);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("no report.json"), std::string::npos) << e.err;
  // A bad size is found before the simulation runs: no output at all.
  const std::string job = kSourceDir + "/parts/plane_cylinder/job_fast.toml";
  CliRun s =
      run_headless("run '" + job + "' --quiet --image-size 10x10 --out '" + (tmp.path() / "bad").string() + "'", tmp);
  EXPECT_EQ(s.code, 2);
  EXPECT_NE(s.err.find("image size"), std::string::npos) << s.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "bad" / "report.json"));
  // No EGL driver (GLVND finds no vendor): a clear error naming EGL, exit code 2, never abort()'s 134.
  const std::string no_egl = "__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent/vendor.json";
  fs::create_directories(tmp.path() / "sig");
  CliRun m = run_headless("motion '" + job + "' --out '" + (tmp.path() / "sig").string() + "'", tmp);
  ASSERT_EQ(m.code, 0) << m.err;
  CliRun g = run_headless("render '" + (tmp.path() / "sig").string() + "'", tmp, no_egl);
  EXPECT_EQ(g.code, 2);
  EXPECT_NE(g.err.find("headless OpenGL context"), std::string::npos) << g.err;
  EXPECT_NE(g.err.find("EGL"), std::string::npos) << g.err;
  // vmsim run keeps its results when the pictures fail, says so, and exits non-zero.
  CliRun rn = run_headless("run '" + job + "' --quiet --out '" + (tmp.path() / "run").string() + "'", tmp, no_egl);
  EXPECT_EQ(rn.code, 2);
  EXPECT_NE(rn.err.find("the results are written"), std::string::npos) << rn.err;
  EXPECT_TRUE(fs::exists(tmp.path() / "run" / "deviation.csv"));
  EXPECT_NE(slurp(tmp.path() / "run" / "report.json").find("render_error"), std::string::npos);
  // Its page shows everything else, and why there are no pictures.
  vmsim_test::expect_report_html(tmp.path() / "run",
                                 "--pictures no --note 'The pictures could not be drawn' --note EGL");
  // --no-render draws nothing.
  CliRun nr =
      run_headless("run '" + job + "' --quiet --no-render --out '" + (tmp.path() / "nr").string() + "'", tmp, no_egl);
  EXPECT_EQ(nr.code, 0) << nr.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "nr" / "images"));
  vmsim_test::expect_report_html(tmp.path() / "nr", "--pictures no --note 'run with --no-render'");
  // vmsim render draws them afterwards, and the page shows them.
  CliRun later = run_headless("render '" + (tmp.path() / "nr").string() + "' --size 480x320", tmp);
  ASSERT_EQ(later.code, 0) << later.err;
  vmsim_test::expect_report_html(tmp.path() / "nr", "--pictures yes");
}
