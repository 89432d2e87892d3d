// vmsim stats and vmsim compare on profiles and on the real scans, end to end as a user runs them:
//   - stats on a stylus profile gives its ISO 21920-2 parameters (a sine's closed forms; the real Dektak export's
//     own results between its cursors);
//   - compare holds a measured profile against a line across a predicted surface (the shift, offset and tilt it
//     was made with come back; the real Dektak trace against a surface carrying it);
//   - stats and compare run on every real file in ../shared/data/real/scans (each held against itself rewritten
//     by vmsim as X3P: the deviation must be zero where both are valid), skipping absent files with a message.
#include "metrology/dektak.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <functional>
#include <cstdio>
#include <filesystem>
#include <string>

#include "tests/app/cli_util.hpp"
#include "core/units.hpp"

using vmsim_test::CliRun;
using vmsim_test::quoted_arg;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;
using vmsim_test::write_file;

namespace fs = std::filesystem;
using namespace vmsim;

namespace {

using vmsim::core::units::kPi;

fs::path real() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "scans"; }

// A Dektak-style export of heights z(x) (um) every dx (um), lateral values printed to 0.1 um as Dektak does.
std::string dektak_csv(double dx_um, int n, const std::function<double(double)>& z_um) {
  std::string t =
      "Scan Parameters\r\r\nStylus,Radius: 2.5 \xb5m\r\n\r\r\nScan Data\r\r\nLateral um,Raw Micrometer,\r\n";
  char buf[96];
  for (int i = 0; i < n; ++i) {
    std::snprintf(buf, sizeof buf, "%.1f,%.6f,,\r\n", i * dx_um, z_um(i * dx_um));
    t += buf;
  }
  return t + "\r\r\n";
}

}  // namespace

TEST(ProfileCli, StatsOfASineProfileInClosedForm) {
  TempDir tmp;
  const double A = 1.0, lambda = 50.0;  // um
  write_file(tmp.path() / "sine.csv",
             dektak_csv(0.25, 8000, [&](double x) { return A * std::sin(2 * kPi * x / lambda); }));
  const CliRun r = run_vmsim("stats --level none " + quoted_arg(tmp.path() / "sine.csv"), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["file"]["format"], "dektak");
  EXPECT_EQ(j["profile"]["points"], 8000);
  EXPECT_NEAR(j["profile"]["dx_mm"].get<double>(), 0.25e-3, 1e-9);
  const auto& p = j["profile_parameters"];
  // 40 whole periods of N = 200 samples with a sample on each zero: the sampled mean of |sin| is (2/N) cot(pi/N)
  // (2/pi to 8e-5); heights printed to 1e-6 um.
  const double N = lambda / 0.25;
  EXPECT_NEAR(p["Ra_mm"].get<double>(), A * 2 / N / std::tan(kPi / N) * 1e-3, 1e-9);
  EXPECT_NEAR(p["Rq_mm"].get<double>(), A / std::sqrt(2.0) * 1e-3, 1e-9);
  EXPECT_NEAR(p["Rsk"].get<double>(), 0.0, 1e-5);
  EXPECT_NEAR(p["Rku"].get<double>(), 1.5, 1e-5);
  EXPECT_NEAR(p["Rz_mm"].get<double>(), 2 * A * 1e-3, 1e-8);
  EXPECT_EQ(p["sections"], 5);
  // With an L-filter (lambda_c 0.25 mm, five times the sine's wavelength): the sine passes, the ends are dropped.
  const CliRun f = run_vmsim("stats --filter L:0.25mm " + quoted_arg(tmp.path() / "sine.csv"), tmp);
  ASSERT_EQ(f.code, 0) << f.err;
  const auto pf = nlohmann::json::parse(f.out)["profile_parameters"];
  EXPECT_NEAR(pf["x_from_mm"].get<double>(), 0.125, 1e-6);
  EXPECT_NEAR(pf["section_length_mm"].get<double>(), 0.25, 1e-6);
  EXPECT_NEAR(pf["Rq_mm"].get<double>(), A / std::sqrt(2.0) * 1e-3, 0.01e-3);
  // --range cuts the trace; --outliers is for surfaces.
  const CliRun g = run_vmsim("stats --range 100um,300um " + quoted_arg(tmp.path() / "sine.csv"), tmp);
  ASSERT_EQ(g.code, 0) << g.err;
  EXPECT_NEAR(nlohmann::json::parse(g.out)["profile_parameters"]["evaluation_length_mm"].get<double>(), 0.2, 0.001);
  EXPECT_NE(run_vmsim("stats --outliers 6 " + quoted_arg(tmp.path() / "sine.csv"), tmp).code, 0);
}

// The Dektak export's own analytical results between its cursors (468 and 733 um; --range takes the samples nearest
// to them, as cursors do): Ra 0.00525 um, Rq 0.01143 um, Skew 6.96, RzDin 0.04917 um (see
// tests/metrology/real_scans_test.cpp).
TEST(ProfileCli, StatsOfTheRealDektakExport) {
  if (!fs::exists(real() / "SurfaceTopography/dektak-1.csv"))
    GTEST_SKIP() << real() << " is absent; the real Dektak file is not checked";
  TempDir tmp;
  const CliRun r = run_vmsim("stats --range 468um,733um " + quoted_arg(real() / "SurfaceTopography/dektak-1.csv"), tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto p = nlohmann::json::parse(r.out)["profile_parameters"];
  EXPECT_EQ(p["form_removed"], "least-squares line");
  EXPECT_NEAR(p["Ra_mm"].get<double>() * 1e3, 0.00525, 0.000005);
  EXPECT_NEAR(p["Rq_mm"].get<double>() * 1e3, 0.01143, 0.000005);
  EXPECT_NEAR(p["Rsk"].get<double>(), 6.96, 0.005);
  EXPECT_NEAR(p["Rz_mm"].get<double>() * 1e3, 0.04917, 0.000005);  // RzDin
}

// A predicted surface (scallops along x, a slower wave, a mark); the stylus ran along y = 1 mm from 0.4123 mm in x,
// with its own datum (+20 um) and a tilt of 1e-4. compare finds them and the deviation is the printing's rounding.
TEST(ProfileCli, CompareAProfileAlongALine) {
  TempDir tmp;
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = 0.005;
  g.z_mm.resize(301, 801);
  const auto surf = [](double x) {
    return 0.004 * std::cos(2 * kPi * x / 0.25) + 0.01 * std::sin(2 * kPi * x / 1.7) -
           0.006 * std::exp(-std::pow((x - 2.2) / 0.1, 2));
  };
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i) g.z_mm(j, i) = surf(g.x(i)) + 0.0005 * g.y(j);
  metrology::write_x3p(tmp.path() / "pred.x3p", g);
  const double start = 0.4123;
  write_file(tmp.path() / "trace.csv", dektak_csv(0.5, 5000, [&](double x_um) {
               const double s = start + x_um * 1e-3;
               return (surf(s) + 0.0005 * 1.0 + 0.020 + 1e-4 * s) * 1e3;
             }));
  const fs::path out = tmp.path() / "cmp";
  const CliRun r =
      run_vmsim("compare -m " + quoted_arg(tmp.path() / "trace.csv") + " -p " + quoted_arg(tmp.path() / "pred.x3p") +
                    " --profile-line 0,1,4,1 --no-render --out " + quoted_arg(out),
                tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(j["mode"], "profile along a line");
  EXPECT_NEAR(j["registration"]["shift_mm"].get<double>(), start, 0.001);
  EXPECT_NEAR(j["registration"]["tilt"].get<double>(), 1e-4, 2e-6);
  EXPECT_LT(j["deviation"]["rms_mm"].get<double>(), 0.2e-3);  // heights printed to 1e-6 um; interpolation on 5 um nodes
  EXPECT_EQ(j["deviation"]["points"], 5000);
  EXPECT_NEAR(j["profile_parameters"]["measured"]["Rq_mm"].get<double>(),
              j["profile_parameters"]["predicted"]["Rq_mm"].get<double>(), 2e-5);
  EXPECT_TRUE(fs::exists(out / "profile_compare.csv"));
  EXPECT_NE(r.out.find("registration along the line"), std::string::npos) << r.out;
  // A profile without its line is an error that says what to give.
  const CliRun e = run_vmsim("compare -m " + quoted_arg(tmp.path() / "trace.csv") + " -p " +
                                 quoted_arg(tmp.path() / "pred.x3p") + " --no-render --out " + quoted_arg(out),
                             tmp);
  EXPECT_NE(e.code, 0);
  EXPECT_NE(e.err.find("--profile-line"), std::string::npos) << e.err;
}

// The real Dektak trace against a surface that carries it along x (extruded in y, written by vmsim as X3P): the
// line from (0, 0.01) to (1.5, 0.01) mm; the registration puts the trace at the line's start and the deviation is
// zero to the interpolation of the rounded lateral values.
TEST(ProfileCli, CompareTheRealDektakTraceEndToEnd) {
  if (!fs::exists(real() / "SurfaceTopography/dektak-1.csv"))
    GTEST_SKIP() << real() << " is absent; the real Dektak file is not checked";
  TempDir tmp;
  const auto d = metrology::read_dektak_csv(real() / "SurfaceTopography/dektak-1.csv");
  core::HeightGrid g;
  g.x0_mm = d.profile.x0_mm, g.dx_mm = g.dy_mm = d.profile.dx_mm;
  g.z_mm.resize(160, d.profile.size());
  for (Eigen::Index j = 0; j < g.ny(); ++j) g.z_mm.row(j) = d.profile.z_mm.transpose();
  metrology::write_x3p(tmp.path() / "pred.x3p", g);
  const fs::path out = tmp.path() / "cmp";
  const double x1 = g.x(g.nx() - 1);
  const CliRun r = run_vmsim("compare -m " + quoted_arg(real() / "SurfaceTopography/dektak-1.csv") + " -p " +
                                 quoted_arg(tmp.path() / "pred.x3p") + " --profile-line " + std::to_string(g.x0_mm) +
                                 ",0.01," + std::to_string(x1) + ",0.01 --out " + quoted_arg(out),
                             tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_NEAR(j["registration"]["shift_mm"].get<double>(), 0.0, d.profile.dx_mm / 2);
  EXPECT_LT(j["deviation"]["rms_mm"].get<double>(), 1e-6);
  EXPECT_GT(j["deviation"]["points"].get<std::size_t>(), 9500u);
  if (!j.contains("pictures") || !j["pictures"].contains("error")) {
    EXPECT_TRUE(fs::exists(out / "images" / "profile_compare.png"));
  }
}

// Every real surface file through vmsim stats (--level none, exit 0, the grid it should have) and vmsim compare
// against itself rewritten as X3P (--align none: the deviation is zero to rounding wherever both are valid; it is
// taken on the prediction's grid through the bilinear resampling of the scan, which leaves out the far edge and the
// cells with an invalid corner, so at least 95 % of the valid points). matrix-4 also goes through the registration
// (--align auto), which must come back to the identity.
TEST(ProfileCli, StatsAndCompareOnEveryRealSurface) {
  struct Case {
    const char* file;
    long nx, ny;
  };
  const Case cases[] = {{"SurfaceTopography/sur-3.sur", 512, 512},
                        {"SurfaceTopography/bcrf-1.bcrf", 960, 600},
                        {"SurfaceTopography/x3p-2.x3p", 650, 650},
                        {"KautschukInfiniteFocus.x3p", 860, 634},
                        {"sample-land.x3p", 918, 256},
                        {"SurfaceTopography/matrix-3.txt", 256, 256},
                        {"SurfaceTopography/matrix-4.txt.gz", 75, 305}};
  int ran = 0;
  for (const Case& c : cases) {
    const fs::path file = real() / c.file;
    if (!fs::exists(file)) {
      std::printf("[  skip    ] %s is absent\n", file.string().c_str());
      continue;
    }
    ++ran;
    SCOPED_TRACE(c.file);
    TempDir tmp;
    const CliRun s = run_vmsim("stats --level none " + quoted_arg(file), tmp);
    ASSERT_EQ(s.code, 0) << s.err;
    const auto j = nlohmann::json::parse(s.out);
    EXPECT_EQ(j["grid"]["nx"], c.nx);
    EXPECT_EQ(j["grid"]["ny"], c.ny);
    if (std::string(c.file) == "sample-land.x3p") {
      EXPECT_NE(s.err.find("warning"), std::string::npos) << s.err;
    }
    const std::size_t valid = j["grid"]["points"].get<std::size_t>() - j["grid"]["invalid_points"].get<std::size_t>();
    metrology::write_x3p(tmp.path() / "self.x3p", metrology::read_surface(file));
    const CliRun cmp = run_vmsim("compare -m " + quoted_arg(file) + " -p " + quoted_arg(tmp.path() / "self.x3p") +
                                     " --align none --outliers 0 --no-render --out " + quoted_arg(tmp.path() / "cmp"),
                                 tmp);
    ASSERT_EQ(cmp.code, 0) << cmp.err;
    const auto r = nlohmann::json::parse(slurp(tmp.path() / "cmp" / "report.json"));
    EXPECT_LE(r["deviation"]["points"].get<std::size_t>(), valid);
    EXPECT_GE(r["deviation"]["points"].get<std::size_t>(), 0.95 * static_cast<double>(valid));
    EXPECT_LT(r["deviation"]["rms_mm"].get<double>(), 1e-12);
    EXPECT_LT(std::max(-r["deviation"]["min_mm"].get<double>(), r["deviation"]["max_mm"].get<double>()), 1e-12);
    if (std::string(c.file) == "SurfaceTopography/matrix-4.txt.gz") {
      const CliRun a = run_vmsim("compare -m " + quoted_arg(file) + " -p " + quoted_arg(tmp.path() / "self.x3p") +
                                     " --no-render --out " + quoted_arg(tmp.path() / "auto"),
                                 tmp);
      ASSERT_EQ(a.code, 0) << a.err;
      const auto ra = nlohmann::json::parse(slurp(tmp.path() / "auto" / "report.json"));
      const double h = metrology::read_surface(file).dx_mm;
      for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(ra["registration"]["transform"]["t_mm"][k].get<double>(), 0.0, h / 10) << k;
      EXPECT_LT(ra["registration"]["transform"]["angle_rad"].get<double>(), 1e-4);
    }
  }
  if (ran == 0)
    GTEST_SKIP() << real() << " is absent (a fresh clone has no ../shared/data/real); the real files are not run";
}
