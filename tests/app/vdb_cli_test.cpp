// Cross-validation of the two removal kernels through `vmsim run`, as a user runs them: the dexel kernel (exact
// along its rays) and the OpenVDB level-set kernel (removal.method = "vdb") on the plane-cylinder, corner and
// five-axis parts
// (parts/), each cut along its programmed path (motion = "program", so that the comparison is about the kernels, not
// the drives) at coarse resolutions. Reference: each kernel is the other's; they must agree within
// max(dexel spacing, voxel size) / 2 plus the tracks' stated sub-stepping bounds (report.json track_error_bound_mm of
// each run: each cut is within its bound of the programmed motion's swept volume).
// The metric is the level set's signed distance at the dexel kernel's surface points (a distance between the
// surfaces, insensitive to the slope of the plane-cylinder part), and the heights / needle offsets themselves.
#include "metrology/grid_io.hpp"
#include "removal/vdb_part.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_util.hpp"
#include "tests/test_paths.hpp"

using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace fs = std::filesystem;
using vmsim::removal::VdbPart;

namespace {

using vmsim::test::kSourceDir;

int run(const std::string& args, const TempDir& tmp, std::string& out, std::string& err) {
  const fs::path o = tmp.path() / "stdout.txt", e = tmp.path() / "stderr.txt";
  const std::string cmd = std::string("'") + VMSIM_EXE + "' " + args + " >'" + o.string() + "' 2>'" + e.string() + "'";
  const int status = std::system(cmd.c_str());
  out = slurp(o);
  err = slurp(e);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A job of a part with absolute paths, cut along its programmed path, no reference, and the given [removal] lines.
fs::path write_vdb_job(const TempDir& tmp, const std::string& name, const std::string& part, const std::string& program,
                       const std::string& tool, const std::string& stock_stl, const std::string& start,
                       const std::string& removal) {
  const std::string dir = kSourceDir + "/parts/" + part + "/";
  const fs::path p = tmp.path() / (name + ".toml");
  std::ofstream f(p);
  f << "[job]\nname = \"" << name << "\"\nmachine = \"" << kSourceDir << "/parts/machines/mikron_ucp710.toml\"\n"
    << "program = \"" << dir << program << "\"\ntool_table = \"" << dir << "tools.tbl\"\nstart_mm = " << start << "\n"
    << "[tool]\n"
    << tool << "\n[stock]\ntype = \"stl\"\nfile = \"" << dir << stock_stl << "\"\n"
    << "[removal]\nmotion = \"program\"\n"
    << removal << "\n[reference]\nkind = \"none\"\n";
  return p;
}

struct NormalNeedle {
  Eigen::Vector3d p, n;
  double offset;
};

std::vector<NormalNeedle> read_normal_needles(const fs::path& p) {
  std::ifstream in(p);
  std::string line;
  std::getline(in, line);
  std::vector<NormalNeedle> v;
  while (std::getline(in, line)) {
    std::vector<double> c;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) c.push_back(std::stod(cell));
    if (c.size() == 9) v.push_back({{c[0], c[1], c[2]}, {c[3], c[4], c[5]}, c[6]});
  }
  return v;
}

}  // namespace

// Plane-cylinder (41 ball-end passes over floor, fillet and 30-degree slope): z-map at 0.2 mm vs level set at 0.2 mm.
TEST(VdbCli, PlaneCylinderKernelsAgree) {
  TempDir tmp;
  const std::string tool = "type = \"ball\"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0";
  const double s = 0.2, h = 0.2;
  const fs::path jd =
      write_vdb_job(tmp, "pc_dexel", "plane_cylinder", "plane_cylinder_reference.ngc", tool, "plane_cylinder_stock.stl",
                    "[-8.0, 0.0, 40.0]", "field = \"zmap\"\nspacing_mm = 0.2");
  const fs::path jv =
      write_vdb_job(tmp, "pc_vdb", "plane_cylinder", "plane_cylinder_reference.ngc", tool, "plane_cylinder_stock.stl",
                    "[-8.0, 0.0, 40.0]", "method = \"vdb\"\nfield = \"zmap\"\nspacing_mm = 0.2\nvoxel_mm = 0.2");
  std::string out, err;
  ASSERT_EQ(
      run("run '" + jd.string() + "' --quiet --no-render --out '" + (tmp.path() / "d").string() + "'", tmp, out, err),
      0)
      << err;
  ASSERT_EQ(
      run("run '" + jv.string() + "' --quiet --no-render --out '" + (tmp.path() / "v").string() + "'", tmp, out, err),
      0)
      << err;
  // The memory estimate is stated before the run (stderr) and in report.json.
  EXPECT_NE(err.find("estimated memory"), std::string::npos) << err;
  const auto rd = nlohmann::json::parse(slurp(tmp.path() / "d" / "report.json"));
  const auto rv = nlohmann::json::parse(slurp(tmp.path() / "v" / "report.json"));
  EXPECT_EQ(rv["removal"]["method"], "vdb");
  EXPECT_GT(rv["removal"]["memory_estimate_bytes"].get<double>(), 0.5 * rv["removal"]["memory_bytes"].get<double>());
  // A 3-axis track: both kernels cut the same sweeps at the default track tolerance (the vdb default of voxel / 10
  // is for turning tools only).
  EXPECT_EQ(rd["removal"]["sweeps"], rv["removal"]["sweeps"]);
  EXPECT_EQ(rd["removal"]["track_tolerance_mm"], rv["removal"]["track_tolerance_mm"]);
  const double bound = std::max(s, h) / 2 + rd["removal"]["track_error_bound_mm"].get<double>() +
                       rv["removal"]["track_error_bound_mm"].get<double>();

  const vmsim::core::HeightGrid gd = vmsim::metrology::read_height_csv(tmp.path() / "d" / "surface.csv");
  const vmsim::core::HeightGrid gv = vmsim::metrology::read_height_csv(tmp.path() / "v" / "surface.csv");
  ASSERT_EQ(gd.nx(), gv.nx());
  ASSERT_EQ(gd.ny(), gv.ny());
  const VdbPart part = VdbPart::read_vdb(tmp.path() / "v" / "part.vdb");
  // Dexel surface points (away from the stock's outline, where a vertical ray grazes its side walls).
  std::vector<Eigen::Vector3d> pts;
  double worst_dz = 0;
  for (Eigen::Index j = 0; j < gd.ny(); ++j)
    for (Eigen::Index i = 0; i < gd.nx(); ++i) {
      if (i < 2 || j < 2 || i + 2 >= gd.nx() || j + 2 >= gd.ny() || std::isnan(gd.z_mm(j, i))) continue;
      pts.emplace_back(gd.x(i), gd.y(j), gd.z_mm(j, i));
      // Heights: the normal distance over the cosine of the steepest slope (30 degrees).
      worst_dz = std::max(worst_dz, std::abs(gd.z_mm(j, i) - gv.z_mm(j, i)));
    }
  ASSERT_GT(pts.size(), 10000u);
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> P(static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t k = 0; k < pts.size(); ++k) P.row(static_cast<Eigen::Index>(k)) = pts[k].transpose();
  const Eigen::VectorXd phi = part.signed_distance(P);
  double worst = 0;
  for (Eigen::Index k = 0; k < phi.size(); ++k) worst = std::max(worst, std::isnan(phi[k]) ? 1e9 : std::abs(phi[k]));
  std::printf("plane-cylinder: level set at the z-map's points within %.4f mm (bound %.4f), heights within %.4f mm\n",
              worst, bound, worst_dz);
  EXPECT_LT(worst, bound);
  EXPECT_LT(worst_dz, bound / std::cos(30 * 3.14159265358979 / 180));
  // The part files: a watertight STL (every edge used twice: 3 F = 2 E, closed) and the .vdb.
  EXPECT_TRUE(fs::exists(tmp.path() / "v" / "part.stl"));
  EXPECT_TRUE(fs::exists(tmp.path() / "v" / "part.vtp"));
}

// Corner (flank milling round an outside vertical edge, N-buffer needles on both walls): needles in the dexel kernel
// vs the level set at 0.2 mm.
TEST(VdbCli, CornerKernelsAgree) {
  TempDir tmp;
  const std::string tool = "type = \"flat\"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0";
  const std::string needles = "field = \"nbuffer\"\nneedles_file = \"" + kSourceDir +
                              "/parts/corner/corner_needles.csv\"\nneedle_half_length_mm = 0.5\n";
  const double h = 0.2;
  const fs::path jd = write_vdb_job(tmp, "c_dexel", "corner", "corner_reference.ngc", tool, "corner_stock.stl",
                                    "[5.0, -75.0, 20.0]", needles);
  const fs::path jv = write_vdb_job(tmp, "c_vdb", "corner", "corner_reference.ngc", tool, "corner_stock.stl",
                                    "[5.0, -75.0, 20.0]", needles + "method = \"vdb\"\nvoxel_mm = 0.2");
  std::string out, err;
  ASSERT_EQ(
      run("run '" + jd.string() + "' --quiet --no-render --out '" + (tmp.path() / "d").string() + "'", tmp, out, err),
      0)
      << err;
  ASSERT_EQ(
      run("run '" + jv.string() + "' --quiet --no-render --out '" + (tmp.path() / "v").string() + "'", tmp, out, err),
      0)
      << err;
  const auto rd = nlohmann::json::parse(slurp(tmp.path() / "d" / "report.json"));
  const auto rv = nlohmann::json::parse(slurp(tmp.path() / "v" / "report.json"));
  const double bound =
      h / 2 + rd["removal"]["track_error_bound_mm"].get<double>() + rv["removal"]["track_error_bound_mm"].get<double>();
  const std::vector<NormalNeedle> nd = read_normal_needles(tmp.path() / "d" / "needles.csv");
  const std::vector<NormalNeedle> nv = read_normal_needles(tmp.path() / "v" / "needles.csv");
  ASSERT_EQ(nd.size(), nv.size());
  ASSERT_GT(nd.size(), 10000u);
  const VdbPart part = VdbPart::read_vdb(tmp.path() / "v" / "part.vdb");
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> P(static_cast<Eigen::Index>(nd.size()), 3);
  double worst_offset = 0, worst_edge_offset = 0;
  int compared = 0;
  for (std::size_t k = 0; k < nd.size(); ++k) {
    P.row(static_cast<Eigen::Index>(k)) = (nd[k].p + nd[k].offset * nd[k].n).transpose();
    if (std::isnan(nd[k].offset) || std::isnan(nv[k].offset)) {
      EXPECT_EQ(std::isnan(nd[k].offset), std::isnan(nv[k].offset)) << k;
      continue;
    }
    // Along a needle within h of an edge of the part (the vertical corner x = y = 0, the block's ends 60 mm from it,
    // the top z = 0, the step at the tip z = -10) the level set's bevel (about h/3 across the edge) shows as a much
    // larger along-needle difference: the offsets are compared away from the edges, the distances (phi, below)
    // everywhere.
    const double lateral = std::abs(nd[k].n.x() != 0 ? nd[k].p.y() : nd[k].p.x());
    const double z = nd[k].p.z();
    const double edge = std::min({lateral, std::abs(lateral - 60), std::abs(z), std::abs(z + 10)});  // block 60 mm
    if (edge <= h) {
      worst_edge_offset = std::max(worst_edge_offset, std::abs(nd[k].offset - nv[k].offset));
      continue;
    }
    ++compared;
    worst_offset = std::max(worst_offset, std::abs(nd[k].offset - nv[k].offset));
  }
  const Eigen::VectorXd phi = part.signed_distance(P);
  double worst = 0;
  for (std::size_t k = 0; k < nd.size(); ++k)
    if (!std::isnan(nd[k].offset))
      worst = std::max(
          worst, std::isnan(phi[static_cast<Eigen::Index>(k)]) ? 1e9 : std::abs(phi[static_cast<Eigen::Index>(k)]));
  std::printf(
      "corner: level set at the needles' surface points within %.4f mm (bound %.4f), offsets within %.4f "
      "mm (%d needles more than h from an edge; %.4f mm within h of one)\n",
      worst, bound, worst_offset, compared, worst_edge_offset);
  EXPECT_GT(compared, 10000);
  EXPECT_LT(worst, bound);
  EXPECT_LT(worst_offset, bound);
}

// The five-axis part (parts/five_axis: dome RS 30 from its STL stock, ball-end D10 along the normal on the Mikron UCP
// 710's A/C chain): the part's own program shortened by the test to its first two turns of the spiral (polar angle
// 10 -> 16 deg, 721 GOTOs, then a retract 20 mm along the last normal), cut along the programmed poses (tool axis
// on the great circle between GOTOs, through the chain's inverse), tri-dexel at 0.2 mm vs level set at 0.2 mm.
// The two jobs sub-step the turning axis differently: the dexel job at the part's own 2 um track tolerance, the vdb
// job at its default for a turning tool, voxel / 10 (core/job.hpp); each cut is within its own track_error_bound_mm of
// the motion's swept volume (removal/track.hpp: e_orient = 2 reach sin(phi / 4) plus the tip terms), so the two
// surfaces agree within max(spacing, voxel) / 2 plus both bounds. Compared along the Z dexel rays: the level set's
// signed distance at the tri-dexel's surface points, and the heights themselves times the sphere's normal's z (a height
// difference on a surface sloping by theta is the normal distance over cos theta).
TEST(VdbCli, FiveAxisKernelsAgree) {
  TempDir tmp;
  const std::string dir = kSourceDir + "/parts/five_axis/";
  // The trimmed program: header up to FEDRAT, the first 721 feed GOTOs (two turns at 1 deg of azimuth), a retract.
  {
    std::ifstream in(dir + "dome_spiral.cl");
    std::ofstream out(tmp.path() / "spiral.cl");
    std::string line, last;
    bool feed = false;
    int gotos = 0;
    while (std::getline(in, line) && gotos < 721) {
      if (feed && line.rfind("GOTO/", 0) == 0) ++gotos, last = line;
      if (line.rfind("FEDRAT", 0) == 0) feed = true;
      out << line << "\n";
    }
    ASSERT_EQ(gotos, 721);
    double v[6];
    ASSERT_EQ(std::sscanf(last.c_str(), "GOTO/%lf,%lf,%lf,%lf,%lf,%lf", v, v + 1, v + 2, v + 3, v + 4, v + 5), 6);
    char buf[200];
    std::snprintf(buf, sizeof buf, "GOTO/%.6f,%.6f,%.6f,%.6f,%.6f,%.6f\nFINI\n", v[0] + 20 * v[3], v[1] + 20 * v[4],
                  v[2] + 20 * v[5], v[3], v[4], v[5]);
    out << buf;
  }
  const double s = 0.2, h = 0.2;
  auto job = [&](const std::string& name, const std::string& removal) {
    const fs::path p = tmp.path() / (name + ".toml");
    std::ofstream f(p);
    f << "[job]\nname = \"" << name << "\"\nmachine = \"" << kSourceDir << "/parts/machines/mikron_ucp710.toml\"\n"
      << "program = \"" << (tmp.path() / "spiral.cl").string() << "\"\n"
      << "[tool]\ntype = \"ball\"\ndiameter_mm = 10.0\nflute_length_mm = 6.0\nlength_mm = 6.0\n"
      << "[stock]\ntype = \"stl\"\nfile = \"" << dir << "dome_stock.stl\"\n"
      << "[interpolation]\nperiod_ms = 1.0\ntolerance_mm = 0.020\n"
      << "[removal]\nmotion = \"program\"\nfield = \"tridexel\"\nspacing_mm = 0.2\n"
      << removal << "\n[reference]\nkind = \"none\"\n";
    return p;
  };
  const fs::path jd = job("fa_dexel", "track_tolerance_mm = 0.002");
  const fs::path jv = job("fa_vdb", "method = \"vdb\"\nvoxel_mm = 0.2");
  std::string out, err;
  ASSERT_EQ(
      run("run '" + jd.string() + "' --quiet --no-render --out '" + (tmp.path() / "d").string() + "'", tmp, out, err),
      0)
      << err;
  ASSERT_EQ(
      run("run '" + jv.string() + "' --quiet --no-render --out '" + (tmp.path() / "v").string() + "'", tmp, out, err),
      0)
      << err;
  const auto rd = nlohmann::json::parse(slurp(tmp.path() / "d" / "report.json"));
  const auto rv = nlohmann::json::parse(slurp(tmp.path() / "v" / "report.json"));
  // The vdb job's track tolerance defaults to voxel / 10, and its orientation term is part of its bound.
  EXPECT_DOUBLE_EQ(rv["removal"]["track_tolerance_mm"].get<double>(), h / 10);
  const double bd = rd["removal"]["track_error_bound_mm"].get<double>(),
               bv = rv["removal"]["track_error_bound_mm"].get<double>();
  EXPECT_LE(bv, h / 10 + 1e-12);
  EXPECT_GT(rv["removal"]["orientation_error_mm"].get<double>(), 0.0);
  EXPECT_LT(rv["removal"]["sweeps"].get<double>(), rd["removal"]["sweeps"].get<double>());
  const double bound = std::max(s, h) / 2 + bd + bv;

  const vmsim::core::HeightGrid gd = vmsim::metrology::read_height_csv(tmp.path() / "d" / "surface.csv");
  const vmsim::core::HeightGrid gv = vmsim::metrology::read_height_csv(tmp.path() / "v" / "surface.csv");
  ASSERT_EQ(gd.nx(), gv.nx());
  ASSERT_EQ(gd.ny(), gv.ny());
  ASSERT_NEAR(gd.x(0), gv.x(0), 1e-9);
  ASSERT_NEAR(gd.y(0), gv.y(0), 1e-9);
  const VdbPart part = VdbPart::read_vdb(tmp.path() / "v" / "part.vdb");
  std::vector<Eigen::Vector3d> pts;
  double worst_dn = 0, worst_dn_cut = 0;
  int cut_points = 0;
  for (Eigen::Index j = 0; j < gd.ny(); ++j)
    for (Eigen::Index i = 0; i < gd.nx(); ++i) {
      const double x = gd.x(i), y = gd.y(j), z = gd.z_mm(j, i);
      // The dome up to 45 deg from its pole (the stock's rim at z = 18 is 53 deg, where vertical rays graze it).
      if (std::hypot(x, y) > 30.0 * std::sin(45 * 3.14159265358979 / 180) || std::isnan(z)) continue;
      pts.emplace_back(x, y, z);
      const double nz = z / std::sqrt(x * x + y * y + z * z), dn = std::abs(z - gv.z_mm(j, i)) * nz;
      worst_dn = std::max(worst_dn, dn);
      // Points the spiral cut (below the stock's 0.05 mm allowance by more than a quarter of it).
      if (std::sqrt(x * x + y * y + z * z) < 30.0 + 0.0375) ++cut_points, worst_dn_cut = std::max(worst_dn_cut, dn);
    }
  ASSERT_GT(pts.size(), 10000u);
  // The two turns' band on the sphere (polar angle 10 to 16 deg) is about 130 mm^2, 3250 nodes at 0.2 mm, less its
  // rims where the cut is shallower.
  EXPECT_GT(cut_points, 2000);
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> P(static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t k = 0; k < pts.size(); ++k) P.row(static_cast<Eigen::Index>(k)) = pts[k].transpose();
  const Eigen::VectorXd phi = part.signed_distance(P);
  double worst = 0;
  for (Eigen::Index k = 0; k < phi.size(); ++k) worst = std::max(worst, std::isnan(phi[k]) ? 1e9 : std::abs(phi[k]));
  std::printf(
      "five-axis: level set at the tri-dexel's points within %.4f mm, heights x n_z within %.4f mm (%.4f on "
      "the %d cut points); bound %.4f (tracks %.4f + %.4f, %d vs %d sweeps)\n",
      worst, worst_dn, worst_dn_cut, cut_points, bound, bd, bv, rd["removal"]["sweeps"].get<int>(),
      rv["removal"]["sweeps"].get<int>());
  EXPECT_LT(worst, bound);
  EXPECT_LT(worst_dn, bound);
}

// Bad [removal] keys name the file and the key: a voxel for the dexel kernel, an adaptivity beyond [0, 1], an
// unknown method; exit code 2.
TEST(VdbCli, BadRemovalKeysAreErrors) {
  TempDir tmp;
  const std::string tool = "type = \"ball\"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0";
  const std::pair<std::string, std::string> cases[] = {{"voxel_mm = 0.1", "voxel_mm"},
                                                       {"method = \"vdb\"\nmesh_adaptivity = 1.5", "mesh_adaptivity"},
                                                       {"method = \"voxels\"", "method"},
                                                       {"method = \"vdb\"\nvoxel_mm = 0.0001", "voxel_mm"}};
  int n = 0;
  for (const auto& [removal, key] : cases) {
    const fs::path j = write_vdb_job(tmp, "bad" + std::to_string(n++), "plane_cylinder", "plane_cylinder_fast.ngc",
                                     tool, "plane_cylinder_stock.stl", "[-8.0, 0.0, 40.0]", removal);
    std::string out, err;
    EXPECT_EQ(
        run("run '" + j.string() + "' --quiet --no-render --out '" + (tmp.path() / "o").string() + "'", tmp, out, err),
        2)
        << removal;
    EXPECT_NE(err.find(j.filename().string()), std::string::npos) << err;
    EXPECT_NE(err.find(key), std::string::npos) << err;
  }
}
