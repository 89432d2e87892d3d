// vmsim stats, measure and compare, end to end as a user runs them: a predicted surface written as X3P, a scan
// simulated from it and moved by a known rigid transform, compared back; the JSON and files they write; errors.
#include "core/stl.hpp"
#include "metrology/mesh_distance.hpp"
#include "metrology/register.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "tests/app/cli_util.hpp"
#include "core/units.hpp"

using vmsim_test::CliRun;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace fs = std::filesystem;
using namespace vmsim;

namespace {

using vmsim::core::units::kPi;

// A predicted surface: scallops of a 0.25 mm stepover along x, a wave along x, and an 8 um overcut mark.
core::HeightGrid predicted(bool with_mark) {
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = 0.01;
  g.z_mm.resize(501, 601);
  for (int j = 0; j < 501; ++j)
    for (int i = 0; i < 601; ++i) {
      const double x = g.x(i), y = g.y(j);
      double z = 0.004 * std::cos(2 * kPi * y / 0.25) + 0.01 * std::sin(2 * kPi * x / 2.0) + 0.002 * x;
      if (with_mark) z -= 0.008 * std::exp(-std::pow((y - 2.6) / 0.15, 2) - std::pow((x - 3.0) / 1.2, 2));
      g.z_mm(j, i) = z;
    }
  return g;
}

}  // namespace

TEST(MetrologyCli, StatsPrintsTheGridAndClosedFormParameters) {
  TempDir tmp;
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = 0.001;
  g.z_mm.resize(5, 2000);
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 2000; ++i) g.z_mm(j, i) = 0.5 + 0.003 * std::sin(2 * kPi * g.x(i) / 1.0);  // 2 periods
  g.z_mm(2, 7) = NAN;
  metrology::write_x3p(tmp.path() / "sine.x3p", g);
  const CliRun r = run_vmsim("stats --level none '" + (tmp.path() / "sine.x3p").string() + "'", tmp);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["file"]["format"], "x3p");
  EXPECT_EQ(j["grid"]["nx"], 2000);
  EXPECT_EQ(j["grid"]["invalid_points"], 1);
  EXPECT_DOUBLE_EQ(j["grid"]["dx_mm"].get<double>(), 0.001);
  EXPECT_NEAR(j["areal"]["mean_mm"].get<double>(), 0.5, 1e-6);
  // Closed forms, to within the one invalid point of 10000 (and 1000 nodes per period).
  EXPECT_NEAR(j["areal"]["Sq_mm"].get<double>(), 0.003 / std::sqrt(2.0), 3e-7);
  EXPECT_NEAR(j["areal"]["Sa_mm"].get<double>(), 0.006 / kPi, 3e-7);
  EXPECT_NEAR(j["areal"]["Sku"].get<double>(), 1.5, 3e-4);
  // A filter and a level are applied and said.
  const CliRun f =
      run_vmsim("stats --level poly:2 --filter L:0.25mm '" + (tmp.path() / "sine.x3p").string() + "'", tmp);
  ASSERT_EQ(f.code, 0) << f.err;
  const auto jf = nlohmann::json::parse(f.out);
  EXPECT_EQ(jf["processing"]["level"]["form"], "poly:2");
  EXPECT_DOUBLE_EQ(jf["processing"]["filters"][0]["cutoff_mm"].get<double>(), 0.25);
  // The 1 mm wave is 4 times the cut-off: the L-filter leaves 1 - exp(-pi (alpha / 4)^2) = 4.2 % of it (more at
  // the edges, where the mean surface is one-sided).
  EXPECT_LT(jf["areal"]["Sq_mm"].get<double>(), 0.1 * 0.003 / std::sqrt(2.0));
}

TEST(MetrologyCli, MeasureThenCompareRecoversTheTransformAndTheMark) {
  TempDir tmp;
  const fs::path pred = tmp.path() / "surface.x3p", ref = tmp.path() / "reference.x3p";
  metrology::write_x3p(pred, predicted(true));
  metrology::write_x3p(ref, predicted(false));
  // The sensor's view of the part.
  const CliRun m = run_vmsim("measure '" + pred.string() + "' --reference '" + ref.string() +
                                 "' --step 10um --spot 4um "
                                 "--noise 0.1um --out '" +
                                 (tmp.path() / "meas").string() + "'",
                             tmp);
  ASSERT_EQ(m.code, 0) << m.err;
  EXPECT_NE(m.out.find("resolved"), std::string::npos) << m.out;
  const auto mr = nlohmann::json::parse(slurp(tmp.path() / "meas" / "report.json"));
  ASSERT_EQ(mr["marks"]["list"].size(), 1u);
  EXPECT_TRUE(mr["marks"]["list"][0]["resolved"].get<bool>());
  // The scan as the instrument would give it: in its own frame, moved by a known transform.
  core::HeightGrid scan = metrology::read_surface(tmp.path() / "meas" / "scan.x3p");
  const auto truth = metrology::RigidTransform::from_xyz_rxyz(0.03, -0.02, 0.1, 1e-3, -2e-3, 3e-3);
  const core::HeightGrid moved = metrology::resample_scan(scan, truth.inverse(), scan);
  metrology::write_x3p(tmp.path() / "scan.x3p", moved);
  // Compared against the reference (no mark): the mark must show, the transform must come back.
  const CliRun c = run_vmsim("compare -m '" + (tmp.path() / "scan.x3p").string() + "' -p '" + ref.string() +
                                 "' --out '" + (tmp.path() / "cmp").string() + "'",
                             tmp);
  ASSERT_EQ(c.code, 0) << c.err;
  const auto r = nlohmann::json::parse(slurp(tmp.path() / "cmp" / "report.json"));
  EXPECT_EQ(r["command"], "compare");
  EXPECT_EQ(r["inputs"]["measured"]["format"], "x3p");
  EXPECT_EQ(r["inputs"]["measured"]["sha256"].get<std::string>().size(), 64u);
  const auto& t = r["registration"]["transform"]["t_mm"];
  EXPECT_NEAR(t[0].get<double>(), truth.t.x(), 0.002);
  EXPECT_NEAR(t[1].get<double>(), truth.t.y(), 0.002);
  EXPECT_NEAR(t[2].get<double>(), truth.t.z(), 0.002);
  EXPECT_NEAR(r["registration"]["transform"]["angle_rad"].get<double>(), truth.rotation_vector().norm(), 2e-4);
  const auto& marks = r["marks"]["list"];
  ASSERT_GE(marks.size(), 1u);
  EXPECT_EQ(marks[0]["kind"], "overcut");
  EXPECT_NEAR(marks[0]["depth_mm"].get<double>(), 0.008, 0.001);
  EXPECT_NEAR(marks[0]["y_mm"].get<double>(), 2.6, 0.05);
  EXPECT_NEAR(marks[0]["width_mm"].get<double>(), 2 * 0.15 * std::sqrt(std::log(2.0)), 0.03);  // across the lay (x)
  EXPECT_GT(marks[0]["along_path_mm"].get<double>(), 1.5);
  EXPECT_NEAR(r["marks"]["path_direction_deg"].get<double>(), 0.0, 1.0);
  for (const char* k : {"Sa_mm", "Sq_mm", "Sdq", "Sdr_percent"}) {
    EXPECT_TRUE(r["areal"]["measured"][k].is_number()) << k;
    EXPECT_TRUE(r["areal"]["measured_minus_predicted"][k].is_number()) << k;
  }
  // The deviation grid opens as X3P, with the mark in it.
  const core::HeightGrid dev = metrology::read_surface(tmp.path() / "cmp" / "deviation.x3p");
  EXPECT_LT(dev.z_mm.isNaN().select(0, dev.z_mm).minCoeff(), -0.007);
  EXPECT_TRUE(fs::exists(tmp.path() / "cmp" / "profiles.csv"));
  // Pictures, or the reason there are none (no EGL on the machine): never a failed comparison.
  if (!r["pictures"].contains("error")) {
    EXPECT_TRUE(fs::exists(tmp.path() / "cmp" / "images" / "deviation_map.png"));
    EXPECT_TRUE(fs::exists(tmp.path() / "cmp" / "images" / "profile_mark_1.png"));
    vmsim_test::expect_report_html(tmp.path() / "cmp", "--pictures yes");
  } else {
    vmsim_test::expect_report_html(tmp.path() / "cmp", "--pictures no --note 'The pictures could not be drawn'");
  }
}

TEST(MetrologyCli, ErrorsNameTheFileAndExit2) {
  TempDir tmp;
  const fs::path bad = tmp.path() / "bad.x3p";
  std::ofstream(bad) << "PK\x03\x04 this is not a zip";
  const CliRun r = run_vmsim("stats '" + bad.string() + "'", tmp);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("vmsim: error: " + bad.string() + ":"), std::string::npos) << r.err;
  const CliRun l = run_vmsim("stats --level curvy '" + bad.string() + "'", tmp);
  EXPECT_EQ(l.code, 2);
  EXPECT_NE(l.err.find("--level"), std::string::npos) << l.err;
  metrology::write_x3p(tmp.path() / "ok.x3p", predicted(false));
  const CliRun u = run_vmsim(
      "measure '" + (tmp.path() / "ok.x3p").string() + "' --step 5furlongs --out '" + tmp.path().string() + "'", tmp);
  EXPECT_EQ(u.code, 2);
  EXPECT_NE(u.err.find("--step"), std::string::npos) << u.err;
}

// A prediction given as a part mesh (vmsim run's part.stl): the scan is registered to the mesh's top and its
// deviation is the signed distance along the mesh normal, on the scan's own grid.
TEST(MetrologyCli, CompareAgainstAMesh) {
  TempDir tmp;
  const core::HeightGrid pred = predicted(false);
  core::write_stl_binary(tmp.path() / "part.stl", metrology::grid_surface_mesh(pred));
  core::HeightGrid scan = predicted(true);  // the mark is in the scan only
  metrology::write_x3p(tmp.path() / "scan.x3p", scan);
  const CliRun c =
      run_vmsim("compare -m '" + (tmp.path() / "scan.x3p").string() + "' -p '" + (tmp.path() / "part.stl").string() +
                    "' --no-render --out '" + (tmp.path() / "cmp").string() + "'",
                tmp);
  ASSERT_EQ(c.code, 0) << c.err;
  const auto r = nlohmann::json::parse(slurp(tmp.path() / "cmp" / "report.json"));
  EXPECT_EQ(r["inputs"]["predicted"]["format"], "stl");
  EXPECT_GT(r["predicted"]["mesh_triangles"].get<int>(), 500000);
  EXPECT_NE(r["deviation"]["definition"].get<std::string>().find("normal"), std::string::npos);
  const auto& marks = r["marks"]["list"];
  ASSERT_GE(marks.size(), 1u);
  // Along the normal of a surface sloping by up to 0.03 rad the 8 um dip reads a little less.
  EXPECT_NEAR(marks[0]["depth_mm"].get<double>(), 0.008, 0.0003);
  EXPECT_NEAR(marks[0]["part_y_mm"].get<double>(), 2.6, 0.05);
  EXPECT_LT(std::abs(r["registration"]["transform"]["t_mm"][2].get<double>()), 0.001);
}
