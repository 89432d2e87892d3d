// X3P files written by vmsim open in Gwyddion (a peer, not a dependency; the test skips without it): Gwyddion 2.62
// converts one to its own .gwy format headless (`gwyddion --convert-to-gwy`), and the data field it made must
// have vmsim's size, extent, heights in metres and the invalid points in its mask.
#include "metrology/x3p.hpp"

#include <gtest/gtest.h>

#include "tests/metrology/gwy_reader.hpp"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

using namespace vmsim;
using vmsim_test::GwyObject;
using vmsim_test::GwyReader;
namespace fs = std::filesystem;

TEST(Gwyddion, OpensVmsimX3pWithItsSizeHeightsAndMask) {
  if (std::system("command -v gwyddion > /dev/null 2>&1") != 0)
    GTEST_SKIP() << "Gwyddion is not installed (apt-get install gwyddion); the peer check is skipped";
  const fs::path dir = fs::temp_directory_path() / ("vmsim_gwy_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  core::HeightGrid g;
  g.dx_mm = 0.0025, g.dy_mm = 0.004;
  g.z_mm.resize(17, 23);
  for (int j = 0; j < 17; ++j)
    for (int i = 0; i < 23; ++i) g.z_mm(j, i) = 0.01 * std::sin(0.3 * i) * std::cos(0.2 * j) - 0.2;
  g.z_mm(4, 5) = NAN;
  g.z_mm(16, 22) = NAN;
  metrology::write_x3p(dir / "scan.x3p", g);
  const std::string cmd =
      "cd '" + dir.string() + "' && timeout 120 gwyddion --convert-to-gwy=scan.gwy scan.x3p > gwy.log 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "see " << dir / "gwy.log";
  std::ifstream in(dir / "scan.gwy", std::ios::binary);
  ASSERT_TRUE(in) << "Gwyddion wrote no scan.gwy: it did not open the X3P file";
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string bytes = ss.str();
  ASSERT_EQ(bytes.substr(0, 4), "GWYP");
  GwyReader r{bytes, 4};
  const GwyObject top = r.object();
  ASSERT_TRUE(top.objects.count("/0/data")) << "no image channel";
  const GwyObject& f = top.objects.at("/0/data");
  EXPECT_EQ(f.type, "GwyDataField");
  EXPECT_EQ(f.numbers.at("xres"), 23);
  EXPECT_EQ(f.numbers.at("yres"), 17);
  EXPECT_NEAR(f.numbers.at("xreal"), 23 * 0.0025e-3, 1e-18);  // metres
  EXPECT_NEAR(f.numbers.at("yreal"), 17 * 0.004e-3, 1e-18);
  const auto& d = f.arrays.at("data");
  ASSERT_EQ(d.size(), 23u * 17u);
  ASSERT_TRUE(top.objects.count("/0/mask")) << "Gwyddion did not mask the invalid points";
  const auto& m = top.objects.at("/0/mask").arrays.at("data");
  for (int j = 0; j < 17; ++j)
    for (int i = 0; i < 23; ++i) {
      const std::size_t k = static_cast<std::size_t>(j * 23 + i);
      if (std::isnan(g.z_mm(j, i))) {
        EXPECT_EQ(m[k], 1.0) << j << " " << i;  // Gwyddion marks them and fills them in for display
      } else {
        EXPECT_EQ(m[k], 0.0) << j << " " << i;
        EXPECT_NEAR(d[k], g.z_mm(j, i) / 1000, 1e-18) << j << " " << i;
      }
    }
  fs::remove_all(dir);
}
