// Scans that instruments and other tools really wrote (../shared/data/real/scans, described in its README), read by
// vmsim and held against figures from outside vmsim:
//   - Gwyddion 2.62 (Debian's package), where it reads the file: the same grid size and spacing, the same heights
//     point by point, and the mean, Sq, Ssk and Sku of its heights (computed here from Gwyddion's data) against
//     vmsim's areal parameters with no form removed;
//   - the published figures of ContactEngineering SurfaceTopography's test suite (MIT; test_sur.py, test_bcr.py,
//     test_text.py: sizes, rms heights, counts of undefined points), and the README's counts;
//   - tests/metrology/independent_stats.py (plain Python, nothing from vmsim) where Gwyddion cannot read the file.
// Every test skips with a message when ../shared/data/real is absent; the Gwyddion and Python parts skip when those
// programs are not installed.
#include "core/error.hpp"
#include "metrology/areal.hpp"
#include "metrology/dektak.hpp"
#include "metrology/profile.hpp"
#include "metrology/surface_io.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "tests/metrology/gwy_reader.hpp"

using namespace vmsim;
namespace fs = std::filesystem;

namespace {

fs::path real() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "scans"; }
fs::path scratch() { return fs::temp_directory_path() / ("vmsim_real_scans_" + std::to_string(::getpid())); }

#define REQUIRE_REAL(file)          \
  if (!fs::exists(real() / (file))) \
  GTEST_SKIP() << real() / (file)   \
               << " is absent (a fresh clone has no ../shared/data/real); this real file is not checked"

struct Moments {
  std::size_t n = 0;
  double mean = 0, sq = 0, ssk = 0, sku = 0;
};
// The reference side's statistics, computed here from another reader's heights (all finite values).
Moments moments(const std::vector<double>& v) {
  Moments m;
  double s = 0;
  for (double z : v) s += z, ++m.n;
  m.mean = s / static_cast<double>(m.n);
  double s2 = 0, s3 = 0, s4 = 0;
  for (double z : v) {
    const double d = z - m.mean;
    s2 += d * d, s3 += d * d * d, s4 += d * d * d * d;
  }
  const double n = static_cast<double>(m.n);
  m.sq = std::sqrt(s2 / n);
  m.ssk = s3 / n / (m.sq * m.sq * m.sq);
  m.sku = s4 / n / (s2 / n * (s2 / n));
  return m;
}

// vmsim's side: the ISO 25178-2 parameters of the raw heights (no form removed), lengths in mm.
void expect_moments(const core::HeightGrid& g, const Moments& ref_m, double rel, const std::string& what) {
  const metrology::ArealParameters p = metrology::areal_parameters(g);
  std::printf(
      "[ figures  ] %s: points %zu / %zu, mean %.10g / %.10g mm, Sq %.10g / %.10g mm, Ssk %.8g / %.8g, Sku %.8g / %.8g "
      "(vmsim / reference)\n",
      what.c_str(), p.points, ref_m.n, p.mean_mm, ref_m.mean * 1e3, p.Sq_mm, ref_m.sq * 1e3, p.Ssk, ref_m.ssk, p.Sku,
      ref_m.sku);
  EXPECT_EQ(p.points, ref_m.n) << what;
  EXPECT_NEAR(p.mean_mm, ref_m.mean * 1e3, rel * std::max(std::abs(ref_m.mean), ref_m.sq) * 1e3) << what << ": mean";
  EXPECT_NEAR(p.Sq_mm, ref_m.sq * 1e3, rel * ref_m.sq * 1e3) << what << ": Sq";
  EXPECT_NEAR(p.Ssk, ref_m.ssk, rel * std::max(1.0, std::abs(ref_m.ssk))) << what << ": Ssk";
  EXPECT_NEAR(p.Sku, ref_m.sku, rel * ref_m.sku) << what << ": Sku";
}

std::size_t invalid(const core::HeightGrid& g) {
  std::size_t n = 0;
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) n += std::isfinite(g.z_mm.data()[k]) ? 0 : 1;
  return n;
}

// Gwyddion's reading of the file; the test is skipped when Gwyddion is not installed.
#define GWYDDION_READ(var, file)                                                                               \
  if (!vmsim_test::gwyddion_available())                                                                       \
    GTEST_SKIP() << "Gwyddion is not installed (apt-get install gwyddion); the comparison with it is skipped"; \
  std::string gwy_log;                                                                                         \
  const auto var = vmsim_test::gwyddion_read(file, scratch(), &gwy_log);                                       \
  ASSERT_TRUE(var) << "Gwyddion did not read " << (file) << ": " << gwy_log

// Gwyddion's heights (metres) against vmsim's (mm), point by point, where vmsim's are valid; and Gwyddion's
// values where vmsim's are invalid, for the caller to judge.
void expect_same_heights(const vmsim_test::GwyField& gw, const core::HeightGrid& g, double rel,
                         std::vector<double>* at_invalid = nullptr) {
  ASSERT_EQ(gw.xres, g.nx());
  ASSERT_EQ(gw.yres, g.ny());
  ASSERT_EQ(gw.data.size(), static_cast<std::size_t>(g.z_mm.size()));
  double range = 0;
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k)
    if (std::isfinite(g.z_mm.data()[k])) range = std::max(range, std::abs(g.z_mm.data()[k]));
  std::size_t differ = 0;
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) {
    const double z = g.z_mm.data()[k];
    if (!std::isfinite(z)) {
      if (at_invalid) at_invalid->push_back(gw.data[static_cast<std::size_t>(k)]);
      continue;
    }
    if (std::abs(gw.data[static_cast<std::size_t>(k)] * 1e3 - z) > rel * range) ++differ;
  }
  EXPECT_EQ(differ, 0u) << "points whose height differs from Gwyddion's by more than " << rel << " of the largest |z|";
}

bool have_python() { return std::system("command -v python3 > /dev/null 2>&1") == 0; }

// tests/metrology/independent_stats.py's JSON for the file.
nlohmann::json independent(const std::string& mode, const fs::path& file, const std::string& extra = "") {
  const fs::path script = fs::path(VMSIM_SOURCE_DIR) / "tests" / "metrology" / "independent_stats.py";
  fs::create_directories(scratch());
  const fs::path out = scratch() / (file.filename().string() + "." + mode + ".json");
  const std::string cmd =
      "python3 '" + script.string() + "' " + mode + " '" + file.string() + "' " + extra + " > '" + out.string() + "'";
  if (std::system(cmd.c_str()) != 0) throw std::runtime_error("failed: " + cmd);
  std::ifstream in(out);
  return nlohmann::json::parse(in);
}

#define REQUIRE_PYTHON() \
  if (!have_python()) GTEST_SKIP() << "python3 is not installed; the independent Python reading is skipped"

}  // namespace

// ---- Digital Surf .sur ----

// sur-3.sur: x step unit nm with length unit um and ratio 1000; special points flagged; 233 009 points at Zmin - 2.
// vmsim used to read a spacing of 295.5 mm (the ratio multiplied in). The file means 0.2955 mm: 512 points span
// 0.151319552 m in SurfaceTopography's test and in Gwyddion.
TEST(RealScans, Sur3SpacingAndNonMeasuredPointsAsSurfaceTopographyReadsThem) {
  REQUIRE_REAL("SurfaceTopography/sur-3.sur");
  const auto f = metrology::read_surface_file(real() / "SurfaceTopography/sur-3.sur");
  EXPECT_EQ(f.format, "sur");
  ASSERT_EQ(f.grid.nx(), 512);
  ASSERT_EQ(f.grid.ny(), 512);
  // SurfaceTopography test_sur3_metadata: physical sizes 0.151319552 m (rtol 1e-6).
  EXPECT_NEAR(512 * f.grid.dx_mm, 151.319552, 151.319552e-6);
  EXPECT_NEAR(512 * f.grid.dy_mm, 151.319552, 151.319552e-6);
  // test_sur_non_measured_points: 233 009 undefined (the header's special-points flag, Zmin - 2).
  EXPECT_EQ(invalid(f.grid), 233009u);
  // test_sur3_metadata: rms height 0.0011131994265859693 m over the defined points (rtol 1e-6).
  const auto p = metrology::areal_parameters(f.grid);
  EXPECT_NEAR(p.Sq_mm, 1.1131994265859693, 1.1131994265859693e-6);
  EXPECT_LT(p.Ssk,
            0);  // the measured band's skewness is negative (-2.43); with the 233 009 floor points it flips to +2.6
}

// The same file through Gwyddion 2.62: the same grid and spacing; at every point vmsim takes as measured, the same
// height (Gwyddion adds the Z offset too); the points vmsim leaves out are all at Gwyddion's floor (the non-measured
// value Zmin - 2 that Gwyddion 2.62 shows as a height: it ignores the special-points flag, which is why it finds
// "all points valid" and a skewness of +2.6); and the statistics of Gwyddion's heights over vmsim's valid points
// are vmsim's.
TEST(RealScans, Sur3AgainstGwyddion) {
  REQUIRE_REAL("SurfaceTopography/sur-3.sur");
  const auto f = metrology::read_surface_file(real() / "SurfaceTopography/sur-3.sur");
  GWYDDION_READ(gw, real() / "SurfaceTopography/sur-3.sur");
  EXPECT_NEAR(gw->xreal / gw->xres * 1e3, f.grid.dx_mm, 1e-9 * f.grid.dx_mm);
  EXPECT_NEAR(gw->yreal / gw->yres * 1e3, f.grid.dy_mm, 1e-9 * f.grid.dy_mm);
  std::vector<double> at_invalid;
  expect_same_heights(*gw, f.grid, 1e-12, &at_invalid);
  const double floor_m = *std::min_element(gw->data.begin(), gw->data.end());
  ASSERT_EQ(at_invalid.size(), 233009u);
  std::size_t off_floor = 0;
  for (double z : at_invalid) off_floor += std::abs(z - floor_m) > 1e-15 ? 1 : 0;
  EXPECT_EQ(off_floor, 0u) << "vmsim masked points that Gwyddion does not show at its floor " << floor_m << " m";
  std::vector<double> valid;
  for (Eigen::Index k = 0; k < f.grid.z_mm.size(); ++k)
    if (std::isfinite(f.grid.z_mm.data()[k])) valid.push_back(gw->data[static_cast<std::size_t>(k)]);
  expect_moments(f.grid, moments(valid), 1e-9, "sur-3 vs Gwyddion over the measured points");
  // Gwyddion's statistics over all its points, as a user of Gwyddion would see them: the sign of Ssk flips.
  EXPECT_GT(moments(gw->data).ssk, 2.0);
}

// ---- BCR-STM ----

TEST(RealScans, BcrfAgainstGwyddionAndSurfaceTopography) {
  REQUIRE_REAL("SurfaceTopography/bcrf-1.bcrf");
  const auto f = metrology::read_surface_file(real() / "SurfaceTopography/bcrf-1.bcrf");
  EXPECT_EQ(f.format, "bcr");
  ASSERT_EQ(f.grid.nx(), 960);
  ASSERT_EQ(f.grid.ny(), 600);
  // SurfaceTopography test_bcr_metadata: physical sizes 1777404 x 1110878 nm, rms height 24.560207201442292 nm.
  EXPECT_NEAR(960 * f.grid.dx_mm, 1.777404, 1.777404e-6);
  EXPECT_NEAR(600 * f.grid.dy_mm, 1.110878, 1.110878e-6);
  EXPECT_NEAR(f.grid.x0_mm, 10.3595, 1e-9);  // xoffset = 10359500.0000 nm in the header
  EXPECT_EQ(invalid(f.grid), 0u);
  EXPECT_NEAR(metrology::areal_parameters(f.grid).Sq_mm, 24.560207201442292e-6, 24.56e-6 * 1e-6);
  GWYDDION_READ(gw, real() / "SurfaceTopography/bcrf-1.bcrf");
  EXPECT_NEAR(gw->xreal / gw->xres * 1e3, f.grid.dx_mm, 1e-9 * f.grid.dx_mm);
  EXPECT_NEAR(gw->yreal / gw->yres * 1e3, f.grid.dy_mm, 1e-9 * f.grid.dy_mm);
  EXPECT_TRUE(gw->mask.empty());
  EXPECT_NEAR(gw->data[0] * 1e3, f.grid.z_mm(0, 0), 1e-7 * f.grid.z_mm(0, 0));  // no flip: row 0 is the file's first
  // Gwyddion scales the float32 points by a factor it holds in single precision: 7.6e-9 apart, relative.
  expect_same_heights(*gw, f.grid, 1e-7);
  expect_moments(f.grid, moments(gw->data), 1e-6, "bcrf-1 vs Gwyddion");
}

// ---- X3P written by other tools ----

// MountainsMap 6.2's export: int32 x/y data type, anisotropic increments and offsets on CX and CY.
TEST(RealScans, X3pMountainsMapAnisotropicWithOffsets) {
  REQUIRE_REAL("SurfaceTopography/x3p-2.x3p");
  const fs::path file = real() / "SurfaceTopography/x3p-2.x3p";
  const auto f = metrology::read_surface_file(file);
  ASSERT_EQ(f.grid.nx(), 650);
  ASSERT_EQ(f.grid.ny(), 650);
  GWYDDION_READ(gw, file);
  EXPECT_NEAR(gw->xreal / gw->xres * 1e3, f.grid.dx_mm, 1e-9 * f.grid.dx_mm);
  EXPECT_NEAR(gw->yreal / gw->yres * 1e3, f.grid.dy_mm, 1e-9 * f.grid.dy_mm);
  EXPECT_GT(f.grid.dy_mm / f.grid.dx_mm, 2.4);  // anisotropic: 0.3146 um across, 0.1277 um along
  expect_same_heights(*gw, f.grid, 1e-12);
  expect_moments(f.grid, moments(gw->data), 1e-9, "x3p-2 vs Gwyddion");
  // The offsets: Gwyddion 2.62 does not keep them; the Python reading of main.xml gives them.
  REQUIRE_PYTHON();
  const auto py = independent("x3p", file);
  EXPECT_DOUBLE_EQ(f.grid.x0_mm, py["CX_offset_m"].get<double>() * 1e3);
  EXPECT_DOUBLE_EQ(f.grid.y0_mm, py["CY_offset_m"].get<double>() * 1e3);
  EXPECT_DOUBLE_EQ(f.grid.dx_mm, py["CX_increment_m"].get<double>() * 1e3);
}

// Alicona InfiniteFocus through the openGPS library: float32 heights with +inf at the 5 296 invalid points (README).
TEST(RealScans, X3pInfiniteFocusInfIsInvalid) {
  REQUIRE_REAL("KautschukInfiniteFocus.x3p");
  const fs::path file = real() / "KautschukInfiniteFocus.x3p";
  const auto f = metrology::read_surface_file(file);
  ASSERT_EQ(f.grid.nx(), 860);
  ASSERT_EQ(f.grid.ny(), 634);
  EXPECT_EQ(invalid(f.grid), 5296u);
  EXPECT_NEAR(f.grid.dx_mm, 2.28e-3, 0.001e-3);
  GWYDDION_READ(gw, file);
  std::size_t masked = 0;
  for (double m : gw->mask) masked += m != 0 ? 1 : 0;
  EXPECT_EQ(masked, 5296u);
  EXPECT_NEAR(gw->xreal / gw->xres * 1e3, f.grid.dx_mm, 1e-9 * f.grid.dx_mm);
  EXPECT_NEAR(gw->yreal / gw->yres * 1e3, f.grid.dy_mm, 1e-9 * f.grid.dy_mm);
  expect_same_heights(*gw, f.grid, 1e-12);
  std::vector<double> valid;
  for (std::size_t k = 0; k < gw->data.size(); ++k)
    if (gw->mask[k] == 0) valid.push_back(gw->data[k]);
  expect_moments(f.grid, moments(valid), 1e-9, "KautschukInfiniteFocus vs Gwyddion's unmasked points");
}

// x3ptools' export of a Sensofar scan: everything under sample-land/ in the zip, next to __MACOSX/ junk and an
// annotation image; root element ISO5436, an empty <Offset/>. Gwyddion 2.62 refuses it ("File contains no
// (importable) data"), so the references are the README (918 x 256, 2.58 um, 25 292 NaN) and the Python reading.
TEST(RealScans, X3pUnderAFolderWithMacJunk) {
  REQUIRE_REAL("sample-land.x3p");
  const fs::path file = real() / "sample-land.x3p";
  const auto f = metrology::read_surface_file(file);
  ASSERT_EQ(f.grid.nx(), 918);
  ASSERT_EQ(f.grid.ny(), 256);
  EXPECT_DOUBLE_EQ(f.grid.dx_mm, 2.58e-3);
  EXPECT_DOUBLE_EQ(f.grid.dy_mm, 2.58e-3);
  EXPECT_EQ(invalid(f.grid), 25292u);
  EXPECT_NE(f.note.find("sample-land/"), std::string::npos) << f.note;
  EXPECT_NE(f.note.find("__MACOSX"), std::string::npos) << f.note;
  EXPECT_NE(f.note.find("mask.png"), std::string::npos) << f.note;
  if (vmsim_test::gwyddion_available()) {  // the reason this test needs another reference
    std::string why;
    EXPECT_FALSE(vmsim_test::gwyddion_read(file, scratch(), &why)) << "Gwyddion reads it now: compare with it";
  }
  REQUIRE_PYTHON();
  const auto py = independent("x3p", file);
  EXPECT_EQ(py["folder"], "sample-land/");
  EXPECT_EQ(py["nan"].get<std::size_t>(), 25292u);
  Moments m;
  m.n = py["points"], m.mean = py["mean"], m.sq = py["Sq"], m.ssk = py["Ssk"], m.sku = py["Sku"];
  expect_moments(f.grid, m, 1e-9, "sample-land vs the Python reading");
}

// ---- text grids ----

// Gwyddion's own ASCII export format ("# Width: 10.00 um", values in m); Gwyddion 2.62 does not import it headless,
// so: SurfaceTopography test_example3 (256 x 256, 10e-6 m, rms 3.5222918750198742e-08 m) and the Python reading.
TEST(RealScans, MatrixTextAgainstSurfaceTopographyAndPython) {
  REQUIRE_REAL("SurfaceTopography/matrix-3.txt");
  const fs::path file = real() / "SurfaceTopography/matrix-3.txt";
  const auto f = metrology::read_surface_file(file);
  EXPECT_EQ(f.format, "matrix");
  ASSERT_EQ(f.grid.nx(), 256);
  ASSERT_EQ(f.grid.ny(), 256);
  EXPECT_NEAR(256 * f.grid.dx_mm, 10e-3, 1e-12);
  EXPECT_NEAR(256 * f.grid.dy_mm, 10e-3, 1e-12);
  EXPECT_NEAR(metrology::areal_parameters(f.grid).Sq_mm, 3.5222918750198742e-05, 3.52e-05 * 1e-9);
  REQUIRE_PYTHON();
  const auto py = independent("matrix", file);
  Moments m;
  m.n = py["points"], m.mean = py["mean"], m.sq = py["Sq"], m.ssk = py["Ssk"], m.sku = py["Sku"];
  expect_moments(f.grid, m, 1e-9, "matrix-3 vs the Python reading");
}

// gzip-compressed; the header ("h=305 w=75", "pixel size=3.69862e-007 m", "data unit=rad", "height conversion
// factor (-> m)=2.91818e-008") has no '#'. SurfaceTopography test_example4: 75 x 305 points, 2.773965e-05 x
// 0.00011280791 m, rms 1.1745891510991089e-07 m.
TEST(RealScans, GzipMatrixWithPixelSizeAndHeightFactor) {
  REQUIRE_REAL("SurfaceTopography/matrix-4.txt.gz");
  const fs::path file = real() / "SurfaceTopography/matrix-4.txt.gz";
  const auto f = metrology::read_surface_file(file);
  EXPECT_EQ(f.format, "matrix+gzip");
  ASSERT_EQ(f.grid.nx(), 75);
  ASSERT_EQ(f.grid.ny(), 305);
  EXPECT_NEAR(75 * f.grid.dx_mm, 2.773965e-02, 2.773965e-02 * 1e-6);
  EXPECT_NEAR(305 * f.grid.dy_mm, 0.11280791, 0.11280791 * 1e-6);
  EXPECT_NEAR(metrology::areal_parameters(f.grid).Sq_mm, 1.1745891510991089e-04, 1.1745891510991089e-04 * 1e-9);
  REQUIRE_PYTHON();
  const auto py = independent("matrix", file);
  Moments m;
  m.n = py["points"], m.mean = py["mean"], m.sq = py["Sq"], m.ssk = py["Ssk"], m.sku = py["Sku"];
  expect_moments(f.grid, m, 1e-9, "matrix-4 vs the Python reading");
}

// ---- a stylus profile ----

// Bruker Dektak export: 9 600 samples over 1500 um (0.15625 um apart, printed rounded to 0.1 um), heights in um.
// The export's own "Analytical Results" (the Dektak software's, between its cursors at 468 and 733 um, i.e. the
// samples nearest to them: the window is widened by half a sample): Ra 0.00525 um, Rq 0.01143 um, Skew 6.96, RzDin
// 0.04917 um. vmsim's parameters on that window, the least-squares line removed and Rz the mean of 5 section
// heights, match all four to their printed digits (Ra 0.0052462, Rq 0.0114327, Rsk 6.9619, Rz 0.0491709 um) -- on
// the stylus's uniform grid: fitting the line to the printed, rounded positions instead moves Rz to 0.0496 um.
TEST(RealScans, DektakProfileAgainstItsOwnResultsAndPython) {
  REQUIRE_REAL("SurfaceTopography/dektak-1.csv");
  const fs::path file = real() / "SurfaceTopography/dektak-1.csv";
  const auto f = metrology::read_surface_file(file);
  EXPECT_EQ(f.format, "dektak");
  ASSERT_TRUE(f.profile);
  const metrology::LineScan& p = *f.profile;
  ASSERT_EQ(p.size(), 9600);
  EXPECT_NEAR(p.dx_mm, 1.5 / 9600, 1e-9);  // the uniform grid the rounded values stand for
  EXPECT_TRUE(f.note.empty()) << f.note;   // within their rounding: no resampling
  metrology::ProfileEvaluation how;
  how.level = 1;
  const double h = p.dx_mm / 2;
  const auto w = metrology::evaluate_profile(metrology::crop(p, 0.468 - h, 0.733 + h), how).parameters;
  EXPECT_NEAR(w.Ra_mm * 1e3, 0.00525, 0.000005);
  EXPECT_NEAR(w.Rq_mm * 1e3, 0.01143, 0.000005);
  EXPECT_NEAR(w.Rsk, 6.96, 0.005);
  EXPECT_NEAR(w.Rz_mm * 1e3, 0.04917, 0.000005);
  REQUIRE_PYTHON();
  for (const bool window : {false, true}) {
    char range[64];
    std::snprintf(range, sizeof range, "%.17g %.17g", (0.468 - h) * 1e3, (0.733 + h) * 1e3);
    const auto py = independent("dektak", file, window ? range : "");
    const auto r = metrology::evaluate_profile(window ? metrology::crop(p, 0.468 - h, 0.733 + h) : p, how).parameters;
    EXPECT_EQ(r.points, py["points"].get<std::size_t>());
    const double um = 1e-3;  // the Python reading is in the file's um
    // Two implementations in double precision of the same formulae: agreement to 1e-9.
    EXPECT_NEAR(r.Ra_mm, py["Ra"].get<double>() * um, 1e-9 * r.Ra_mm) << window;
    EXPECT_NEAR(r.Rq_mm, py["Rq"].get<double>() * um, 1e-9 * r.Rq_mm) << window;
    EXPECT_NEAR(r.Rsk, py["Rsk"].get<double>(), 1e-9 * std::abs(r.Rsk)) << window;
    EXPECT_NEAR(r.Rku, py["Rku"].get<double>(), 1e-9 * r.Rku) << window;
    EXPECT_NEAR(r.Rp_mm, py["Rp"].get<double>() * um, 1e-9 * r.Rp_mm) << window;
    EXPECT_NEAR(r.Rv_mm, py["Rv"].get<double>() * um, 1e-9 * r.Rv_mm) << window;
    EXPECT_NEAR(r.Rz_mm, py["Rz"].get<double>() * um, 1e-9 * r.Rz_mm) << window;
    EXPECT_NEAR(r.Rt_mm, py["Rt"].get<double>() * um, 1e-9 * r.Rt_mm) << window;
  }
}
