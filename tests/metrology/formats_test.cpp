// Surface file formats: the official samples in ../shared/data/surface read to the values their XML states
// (missing point, valid mask, int16 scaling, absolute axis, point list), and every format vmsim writes reads back.
#include "core/error.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/sdf.hpp"
#include "metrology/sur.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/units.hpp"
#include "metrology/x3p.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

using namespace vmsim;
namespace fs = std::filesystem;

namespace {

fs::path samples() { return fs::path(VMSIM_SHARED_DIR) / "data" / "surface"; }

#define REQUIRE_SAMPLES()     \
  if (!fs::exists(samples())) \
  GTEST_SKIP() << samples() << " is absent (a fresh clone has no ../shared); the format samples are not checked"

fs::path tmp(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("vmsim_metrology_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d / name;
}

// The heights of ISO5436-sample1, row by row (metres in the file), with the missing point at (row 1, column 3).
const double kSample1[16] = {
    4.86219120804151E-0001, 3.46341436648013E-0003, -8.08368571682830E-0001, -5.79793099037002E-0001,
    8.57622027393310E-0001, 1.04759602566142E+0000, 1.01879225277798E+0000,  NAN,
    8.23683772970184E-0001, 7.97872489327661E-0001, -5.57459388341694E-0001, -2.33247858849220E-0001,
    6.75397146760858E-0001, 4.20737549074718E-0001, 6.42069248110950E-0001,  -2.15696638464903E-0001};

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expect_same_grid(const core::HeightGrid& a, const core::HeightGrid& b) {
  ASSERT_EQ(a.nx(), b.nx());
  ASSERT_EQ(a.ny(), b.ny());
  EXPECT_TRUE(same_bits(a.x0_mm, b.x0_mm)) << a.x0_mm << " " << b.x0_mm;
  EXPECT_TRUE(same_bits(a.y0_mm, b.y0_mm)) << a.y0_mm << " " << b.y0_mm;
  EXPECT_TRUE(same_bits(a.dx_mm, b.dx_mm)) << a.dx_mm << " " << b.dx_mm;
  EXPECT_TRUE(same_bits(a.dy_mm, b.dy_mm)) << a.dy_mm << " " << b.dy_mm;
  std::size_t differ = 0;
  for (Eigen::Index k = 0; k < a.z_mm.size(); ++k) {
    const double x = a.z_mm.data()[k], y = b.z_mm.data()[k];
    if (std::isnan(x) != std::isnan(y) || (!std::isnan(x) && !same_bits(x, y))) ++differ;
  }
  EXPECT_EQ(differ, 0u) << "of " << a.z_mm.size() << " heights";
}

// Heights whose mm -> m -> mm conversion is not exact in plain arithmetic, with invalid points and odd spacings.
core::HeightGrid awkward_grid(int nx, int ny, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  core::HeightGrid g;
  g.x0_mm = -12.345678901234567, g.y0_mm = 0.1 + 0.2, g.dx_mm = 0.005 * 3, g.dy_mm = 1.0 / 3.0;
  g.z_mm.resize(ny, nx);
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) g.z_mm.data()[k] = u(rng) * std::pow(10.0, (k % 7) - 4);
  g.z_mm(0, 0) = NAN;
  g.z_mm(ny - 1, nx / 2) = NAN;
  g.z_mm(1, 1) = -0.0;
  g.z_mm(1, 2) = 0.0;
  return g;
}

}  // namespace

TEST(Units, DecimalExponentShiftIsExact) {
  EXPECT_EQ(*metrology::parse_decimal_scaled("5E-5", 3), 0.05);
  EXPECT_EQ(*metrology::parse_decimal_scaled(" 1.60160000000000E-0002 ", 3), 16.016);
  EXPECT_EQ(*metrology::parse_decimal_scaled("-0.5", 0), -0.5);
  EXPECT_FALSE(metrology::parse_decimal_scaled("1e", 0));
  EXPECT_FALSE(metrology::parse_decimal_scaled("nan", 0));
  EXPECT_FALSE(metrology::parse_decimal_scaled("1.2.3", 0));
  EXPECT_FALSE(metrology::parse_decimal_scaled("", 0));
  EXPECT_EQ(metrology::format_scaled(0.05, -3), "5E-05");
  std::mt19937_64 rng(7);
  for (int k = 0; k < 100000; ++k) {
    double v;
    const std::uint64_t bits = rng();
    std::memcpy(&v, &bits, 8);
    if (!std::isfinite(v) || std::abs(v) > 1e300 || (v != 0 && std::abs(v) < 1e-300)) continue;
    ASSERT_TRUE(same_bits(*metrology::parse_decimal_scaled(metrology::format_scaled(v, -3), 3), v)) << v;
  }
  EXPECT_EQ(*metrology::length_unit_pow10("\xc2\xb5m"), -6);
  EXPECT_EQ(*metrology::length_unit_pow10("nm"), -9);
  EXPECT_FALSE(metrology::length_unit_pow10("furlong"));
}

TEST(X3pSamples, Sample1HeightsInXmlWithAMissingPoint) {
  REQUIRE_SAMPLES();
  const auto d = metrology::read_x3p(samples() / "ISO5436-sample1.x3p");
  EXPECT_EQ(d.meta.feature_type, "SUR");
  EXPECT_FALSE(d.meta.binary);
  EXPECT_TRUE(d.meta.main_checksum_checked);
  EXPECT_FALSE(d.meta.rotation_identity == false);  // the sample's rotation is the identity
  ASSERT_EQ(d.grid.nx(), 4);
  ASSERT_EQ(d.grid.ny(), 4);
  EXPECT_DOUBLE_EQ(d.grid.dx_mm, 16.016);
  EXPECT_DOUBLE_EQ(d.grid.dy_mm, 16.016);
  EXPECT_EQ(d.meta.invalid_points, 1u);
  for (int k = 0; k < 16; ++k) {
    if (std::isnan(kSample1[k])) {
      EXPECT_TRUE(std::isnan(d.grid.z_mm.data()[k]));
    } else {
      EXPECT_NEAR(d.grid.z_mm.data()[k], kSample1[k] * 1000.0, 1e-12) << k;
    }
  }
}

TEST(X3pSamples, Sample1BinaryWithValidMaskEqualsTheXmlVersion) {
  REQUIRE_SAMPLES();
  const auto xml = metrology::read_x3p(samples() / "ISO5436-sample1.x3p");
  const auto bin = metrology::read_x3p(samples() / "ISO5436-sample1_bin.x3p");
  EXPECT_TRUE(bin.meta.binary);
  EXPECT_TRUE(bin.meta.valid_mask);
  EXPECT_EQ(bin.meta.invalid_points, 1u);
  EXPECT_TRUE(std::isnan(bin.grid.z_mm(1, 3)));
  for (int k = 0; k < 16; ++k) {
    if (std::isnan(kSample1[k])) continue;
    EXPECT_NEAR(bin.grid.z_mm.data()[k], xml.grid.z_mm.data()[k], 1e-12) << k;
  }
}

TEST(X3pSamples, Sample4Int16WithIncrementAndOffset) {
  REQUIRE_SAMPLES();
  const auto d = metrology::read_x3p(samples() / "ISO5436-sample4_bin.x3p");
  EXPECT_EQ(d.meta.data_type[2], 'I');
  EXPECT_TRUE(std::isnan(d.grid.z_mm(1, 3)));
  // data.bin starts with int16 0x03da = 986: z = -0.5 + 0.001 * 986 m = 0.486 m.
  EXPECT_NEAR(d.grid.z_mm(0, 0), (-0.5 + 0.001 * 986) * 1000, 1e-9);
  // The samples' heights quantised to 1 mm steps: within half a step of sample 1 (offset 0.5 m removed).
  for (int k = 0; k < 16; ++k) {
    if (std::isnan(kSample1[k])) continue;
    EXPECT_NEAR(d.grid.z_mm.data()[k], kSample1[k] * 1000, 0.5 + 1e-9) << k;
  }
}

TEST(X3pSamples, Sample3AbsoluteYAxis) {
  REQUIRE_SAMPLES();
  const auto d = metrology::read_x3p(samples() / "ISO5436-sample3.x3p");
  // CY absolute, int16 with Increment 2 m and Offset 1 m: rows at y = 1 + 2 k m for k = 1..4.
  ASSERT_EQ(d.grid.ny(), 4);
  EXPECT_DOUBLE_EQ(d.grid.y0_mm, 3000.0);
  EXPECT_DOUBLE_EQ(d.grid.dy_mm, 2000.0);
  EXPECT_DOUBLE_EQ(d.grid.x0_mm, 100.0);
  EXPECT_DOUBLE_EQ(d.grid.dx_mm, 16.016);
  // CZ has Offset 2 m.
  EXPECT_NEAR(d.grid.z_mm(0, 0), (2.0 + 4.86219120804151E-0001) * 1000, 1e-9);
  EXPECT_TRUE(std::isnan(d.grid.z_mm(1, 3)));
}

TEST(X3pSamples, Sample2PointListOnALattice) {
  REQUIRE_SAMPLES();
  const auto d = metrology::read_x3p(samples() / "ISO5436-sample2.x3p");
  EXPECT_EQ(d.meta.feature_type, "PCL");
  ASSERT_EQ(d.points_mm.rows(), 16);
  // x = 0.1 m + {0..3} um, y = 2 m + {0..3} um, z = 2 m + value.
  EXPECT_NEAR(d.points_mm(1, 0), 100.001, 1e-9);
  EXPECT_NEAR(d.points_mm(4, 1), 2000.001, 1e-9);
  EXPECT_NEAR(d.points_mm(0, 2), 2486.219120804151, 1e-9);
  ASSERT_EQ(d.grid.nx(), 4);
  ASSERT_EQ(d.grid.ny(), 4);
  EXPECT_NEAR(d.grid.dx_mm, 0.001, 1e-12);
  EXPECT_NEAR(d.grid.z_mm(3, 3), 2000 - 215.696638464903, 1e-9);
}

TEST(X3pSamples, PyramidFloat32FromX3ptools) {
  REQUIRE_SAMPLES();
  const auto d = metrology::read_x3p(samples() / "pyramid.x3p");
  ASSERT_EQ(d.grid.nx(), 5);
  ASSERT_EQ(d.grid.ny(), 5);
  EXPECT_EQ(d.meta.data_type[2], 'F');
  EXPECT_DOUBLE_EQ(d.grid.z_mm(0, 0), 2000.0);
  EXPECT_DOUBLE_EQ(d.grid.z_mm(2, 2), 10000.0);  // the apex, 10 m
  EXPECT_TRUE(d.meta.main_checksum_checked);     // md5checksum.hex without the file name also counts
}

TEST(SdfSamples, IsoExampleAscii) {
  REQUIRE_SAMPLES();
  const core::HeightGrid g = metrology::read_sdf(samples() / "sdf-1.sdf");
  ASSERT_EQ(g.nx(), 7);
  ASSERT_EQ(g.ny(), 4);
  EXPECT_DOUBLE_EQ(g.dx_mm, 0.001);
  EXPECT_NEAR(g.z_mm(0, 1), 0.99874e-3, 1e-15);
  EXPECT_NEAR(g.z_mm(3, 5), 0.94907e-3, 1e-15);
  EXPECT_EQ(metrology::read_surface_file(samples() / "sdf-1.sdf").format, "sdf");
}

TEST(RoundTrip, X3pBitForBitWithInvalidPoints) {
  const core::HeightGrid g = awkward_grid(37, 23, 1);
  const fs::path p = tmp("rt.x3p");
  metrology::write_x3p(p, g);
  const auto d = metrology::read_x3p(p);
  EXPECT_TRUE(d.meta.valid_mask);
  EXPECT_TRUE(d.meta.main_checksum_checked);
  EXPECT_EQ(d.meta.invalid_points, 2u);
  expect_same_grid(g, d.grid);
  EXPECT_EQ(metrology::read_surface_file(p).format, "x3p");
}

TEST(RoundTrip, X3pWithoutInvalidPointsHasNoMask) {
  core::HeightGrid g = awkward_grid(8, 5, 2);
  g.z_mm(0, 0) = 1, g.z_mm(4, 4) = 2;
  const fs::path p = tmp("rt_nomask.x3p");
  metrology::write_x3p(p, g);
  const auto d = metrology::read_x3p(p);
  EXPECT_FALSE(d.meta.valid_mask);
  expect_same_grid(g, d.grid);
}

TEST(RoundTrip, SdfBitForBit) {
  const core::HeightGrid g = awkward_grid(31, 17, 3);
  const fs::path p = tmp("rt.sdf");
  metrology::write_sdf(p, g);
  expect_same_grid(g, metrology::read_sdf(p));
}

TEST(RoundTrip, CsvBitForBit) {
  const core::HeightGrid g = awkward_grid(29, 13, 4);
  const fs::path p = tmp("rt.csv");
  metrology::write_height_csv(p, g);
  expect_same_grid(g, metrology::read_height_csv(p));
  expect_same_grid(g, metrology::read_surface(p));
}

TEST(RoundTrip, XyzBitForBit) {
  core::HeightGrid g = awkward_grid(11, 7, 5);
  g.x0_mm = 1.0, g.dx_mm = 0.25, g.y0_mm = -2.0, g.dy_mm = 0.5;  // positions the lattice finder recovers exactly
  const fs::path p = tmp("rt.xyz");
  metrology::write_xyz(p, g);
  expect_same_grid(g, metrology::read_surface(p));
}

TEST(RoundTrip, SurWithinItsQuantisation) {
  core::HeightGrid g = awkward_grid(19, 9, 6);
  g.x0_mm = 0.5, g.dx_mm = 0.25, g.y0_mm = 1.0, g.dy_mm = 0.125;  // exact in float32
  const fs::path p = tmp("rt.sur");
  metrology::write_sur(p, g);
  const core::HeightGrid r = metrology::read_surface(p);
  ASSERT_EQ(r.nx(), 19);
  ASSERT_EQ(r.ny(), 9);
  EXPECT_EQ(r.dx_mm, 0.25);
  EXPECT_EQ(r.y0_mm, 1.0);
  const double range = 4.0e2;  // heights span about +-200
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) {
    const double a = g.z_mm.data()[k], b = r.z_mm.data()[k];
    ASSERT_EQ(std::isnan(a), std::isnan(b)) << k;
    if (!std::isnan(a)) {
      EXPECT_NEAR(a, b, range / 1073741824.0 + 1e-6 * std::abs(a) + 1e-6) << k;
    }
  }
}

TEST(MatrixGrid, GwyddionAsciiExportHeader) {
  const fs::path p = tmp("gwy.txt");
  {
    std::ofstream f(p);
    f << "# Channel: Height\n# Width: 4.000 um\n# Height: 2.000 um\n# Value units: m\n"
      << "1e-6\t2e-6\t3e-6\t4e-6\n5e-6\tNaN\t7e-6\t8e-6\n";
  }
  const auto s = metrology::read_surface_file(p);
  EXPECT_EQ(s.format, "matrix");
  ASSERT_EQ(s.grid.nx(), 4);
  ASSERT_EQ(s.grid.ny(), 2);
  EXPECT_DOUBLE_EQ(s.grid.dx_mm, 0.001);
  EXPECT_DOUBLE_EQ(s.grid.dy_mm, 0.001);
  EXPECT_DOUBLE_EQ(s.grid.z_mm(1, 3), 0.008);
  EXPECT_TRUE(std::isnan(s.grid.z_mm(1, 1)));
}

TEST(MatrixGrid, MissingSpacingIsAClearError) {
  const fs::path p = tmp("nospacing.txt");
  { std::ofstream(p) << "1 2 3\n4 5 6\n"; }
  try {
    metrology::read_surface(p);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("x spacing"), std::string::npos) << e.what();
  }
}

TEST(Xyz, SparseOrOffLatticePointsAreErrors) {
  const fs::path p = tmp("off.xyz");
  { std::ofstream(p) << "0 0 1\n1 0 1\n2.5 0 1\n"; }
  EXPECT_THROW(metrology::read_surface(p), core::Error);
  { std::ofstream(p) << "0 0 1\n1e6 1e6 1\n0.001 0 2\n"; }
  EXPECT_THROW(metrology::read_surface(p), core::Error);
  { std::ofstream(p) << "# unit: um\n0 0 1\n5 0 2\n0 5 3\n5 5 nan\n"; }
  const auto g = metrology::read_surface(p);
  EXPECT_DOUBLE_EQ(g.dx_mm, 0.005);
  EXPECT_DOUBLE_EQ(g.z_mm(1, 0), 0.003);
  EXPECT_TRUE(std::isnan(g.z_mm(1, 1)));
}

TEST(X3pErrors, NotAZipNamesTheFile) {
  const fs::path q = tmp("notzip.x3p");
  { std::ofstream(q) << "PK\x03\x04garbage"; }
  try {
    metrology::read_x3p(q);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(q.string(), 0), 0u) << e.what();
  }
}
