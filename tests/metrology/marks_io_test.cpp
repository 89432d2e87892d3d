// Deviation and marks on synthetic surfaces with known answers; height-grid files round trip.
#include "core/error.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/marks.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <cstring>
#include <random>

using namespace vmsim;

namespace {
core::HeightGrid grid(int nx, int ny, double h) {
  core::HeightGrid g;
  g.x0_mm = -1, g.y0_mm = 2, g.dx_mm = h, g.dy_mm = h;
  g.z_mm = core::HeightArray::Zero(ny, nx);
  return g;
}
std::filesystem::path marks_tmp(const std::string& name) {
  std::random_device rd;
  return std::filesystem::temp_directory_path() / (std::to_string(rd()) + "_" + name);
}
}  // namespace

// A Gaussian dip of 20 um, sigma 0.5 mm along x and 0.2 mm along y: one overcut mark of that depth at its centre;
// the region deeper than half the depth spans 2 sigma sqrt(2 ln 2) in each direction.
TEST(Marks, GaussianDipIsFoundWithItsDepthPlaceAndExtent) {
  core::HeightGrid ref = grid(401, 201, 0.01), pred = ref;
  for (int j = 0; j < 201; ++j)
    for (int i = 0; i < 401; ++i) {
      const double x = ref.x(i) - 1.0, y = ref.y(j) - 3.0;
      pred.z_mm(j, i) -= 0.020 * std::exp(-0.5 * (x * x / 0.25 + y * y / 0.04));
    }
  const core::HeightGrid dev = metrology::deviation(pred, ref);
  const auto marks = metrology::find_marks(dev, 1e-3);
  ASSERT_EQ(marks.size(), 1u);
  EXPECT_TRUE(marks[0].overcut);
  EXPECT_NEAR(marks[0].depth_mm, 0.020, 1e-9);
  EXPECT_NEAR(marks[0].x_mm, 1.0, 1e-9);
  EXPECT_NEAR(marks[0].y_mm, 3.0, 1e-9);
  const double fwhm = 2 * std::sqrt(2 * std::log(2.0));
  EXPECT_NEAR(marks[0].x_extent_mm, fwhm * 0.5, 0.011);
  EXPECT_NEAR(marks[0].y_extent_mm, fwhm * 0.2, 0.011);
}

TEST(Marks, DeviationNeedsTheSameGrid) {
  core::HeightGrid a = grid(10, 10, 0.1), b = grid(10, 11, 0.1);
  EXPECT_THROW(metrology::deviation(a, b), core::Error);
}

TEST(GridIo, CsvRoundTripKeepsValuesAndInvalidPoints) {
  core::HeightGrid g = grid(13, 7, 0.05);
  for (int j = 0; j < 7; ++j)
    for (int i = 0; i < 13; ++i) g.z_mm(j, i) = std::round((0.1 * i - 0.07 * j) * 1e7) / 1e7;
  g.z_mm(3, 4) = NAN;
  const auto p = marks_tmp("g.csv");
  metrology::write_height_csv(p, g);
  const core::HeightGrid r = metrology::read_height_csv(p);
  std::filesystem::remove(p);
  ASSERT_EQ(r.nx(), 13);
  ASSERT_EQ(r.ny(), 7);
  EXPECT_DOUBLE_EQ(r.dx_mm, 0.05);
  EXPECT_DOUBLE_EQ(r.x0_mm, -1);
  EXPECT_TRUE(std::isnan(r.z_mm(3, 4)));
  for (int j = 0; j < 7; ++j)
    for (int i = 0; i < 13; ++i)
      if (!(j == 3 && i == 4)) {
        EXPECT_NEAR(r.z_mm(j, i), g.z_mm(j, i), 1e-12);
      }
}

TEST(GridIo, NpyHasNumpysHeaderAndTheData) {
  core::HeightGrid g = grid(5, 3, 1.0);
  g.z_mm(2, 4) = 7.5;
  const auto p = marks_tmp("g.npy");
  metrology::write_height_npy(p, g);
  std::ifstream in(p, std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(in)), {});
  std::filesystem::remove(p);
  std::filesystem::remove(p.string() + ".json");
  ASSERT_GT(all.size(), 128u);
  EXPECT_EQ(all.substr(0, 6), "\x93NUMPY");
  const std::size_t hl = static_cast<unsigned char>(all[8]) | (static_cast<unsigned char>(all[9]) << 8);
  EXPECT_EQ((10 + hl) % 64, 0u);
  EXPECT_NE(all.find("'shape': (3, 5)"), std::string::npos);
  double last;
  std::memcpy(&last, all.data() + 10 + hl + 14 * 8, 8);
  EXPECT_EQ(last, 7.5);
}

TEST(GridIo, BadCsvNamesTheLine) {
  const auto p = marks_tmp("bad.csv");
  {
    std::ofstream f(p);
    f << "# x0_mm=0 y0_mm=0 dx_mm=1 dy_mm=1 nx=2 ny=2\n1,2\n3,x\n";
  }
  try {
    metrology::read_height_csv(p);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find(":3:"), std::string::npos) << e.what();
  }
  std::filesystem::remove(p);
}
