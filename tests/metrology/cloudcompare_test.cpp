// The deviation of a point grid from a predicted mesh against CloudCompare's cloud-to-mesh distance
// (../shared/peers/README.md section 2: `CloudCompare -SILENT ... -C2M_DIST`, signed along the facet normal).
// Skips when CloudCompare is not installed: it is a peer, not a dependency.
#include "core/stl.hpp"
#include "metrology/mesh_distance.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <unistd.h>

using namespace vmsim;
namespace fs = std::filesystem;

namespace {
using vmsim::core::units::kPi;
double part(double x, double y) {  // a machined-looking top: waves, a ball-end groove along y, a tilt
  const double r = 1.5, gx = 6.0, depth = 0.4;
  double z = 5.0 + 0.05 * std::sin(2 * kPi * x / 2.0) * std::cos(2 * kPi * y / 3.0) + 0.002 * x;
  const double dx = x - gx;
  if (std::abs(dx) < std::sqrt(r * r - (r - depth) * (r - depth)))
    z = std::min(z, 5.0 - depth + r - std::sqrt(r * r - dx * dx));
  return z;
}
}  // namespace

TEST(CloudCompare, GridDeviationFromAMeshAgreesWithC2MWithin1um) {
  if (std::system("command -v CloudCompare > /dev/null 2>&1") != 0)
    GTEST_SKIP() << "CloudCompare is not installed (apt-get install cloudcompare); the peer comparison is skipped";
  const fs::path dir = fs::temp_directory_path() / ("vmsim_cc_" + std::to_string(::getpid()));
  fs::create_directories(dir);

  // The predicted part: its top surface on a 0.05 mm grid, as an STL (float vertices; vmsim uses the same floats).
  core::HeightGrid pred;
  pred.dx_mm = pred.dy_mm = 0.05;
  pred.z_mm.resize(201, 201);
  for (int j = 0; j < 201; ++j)
    for (int i = 0; i < 201; ++i) pred.z_mm(j, i) = part(pred.x(i), pred.y(j));
  core::TriangleMesh mesh = metrology::grid_surface_mesh(pred);
  mesh.vertices_mm = mesh.vertices_mm.cast<float>().cast<double>();
  core::write_stl_binary(dir / "predicted.stl", mesh);

  // The measured point grid: another lattice, heights off the prediction by up to 30 um, noise, a few dropouts.
  core::HeightGrid scan;
  scan.x0_mm = 0.31, scan.y0_mm = 0.27, scan.dx_mm = scan.dy_mm = 0.07;
  scan.z_mm.resize(134, 134);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0, 0.002);
  for (int j = 0; j < 134; ++j)
    for (int i = 0; i < 134; ++i) {
      const double x = scan.x(i), y = scan.y(j);
      scan.z_mm(j, i) = static_cast<float>(part(x, y) + 0.03 * std::sin(x) * std::cos(0.7 * y) + noise(rng));
    }
  scan.z_mm(10, 10) = NAN;
  {
    std::ofstream f(dir / "measured.xyz");
    char buf[96];
    for (int j = 0; j < 134; ++j)
      for (int i = 0; i < 134; ++i)
        if (scan.valid(j, i)) {
          // CloudCompare stores float coordinates: give it the floats vmsim uses too.
          std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g\n", static_cast<double>(static_cast<float>(scan.x(i))),
                        static_cast<double>(static_cast<float>(scan.y(j))), scan.z_mm(j, i));
          f << buf;
        }
  }
  const std::string cmd =
      "cd '" + dir.string() +
      "' && QT_QPA_PLATFORM=offscreen timeout 300 CloudCompare -SILENT -NO_TIMESTAMP -C_EXPORT_FMT ASC "
      "-PREC 9 -SEP SPACE -ADD_HEADER -AUTO_SAVE OFF -O measured.xyz -O predicted.stl -C2M_DIST "
      "-SAVE_CLOUDS FILE c2m.asc > cc.log 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "CloudCompare failed; see " << (dir / "cc.log");

  // vmsim: the same points (float x, y as written) against the same mesh.
  std::vector<double> mine;
  {
    Eigen::Matrix<double, Eigen::Dynamic, 3> pts(134 * 134 - 1, 3);
    Eigen::Index k = 0;
    for (int j = 0; j < 134; ++j)
      for (int i = 0; i < 134; ++i)
        if (scan.valid(j, i))
          pts.row(k++) << static_cast<float>(scan.x(i)), static_cast<float>(scan.y(j)), scan.z_mm(j, i);
    const Eigen::VectorXd d = metrology::signed_distances(pts, mesh);
    mine.assign(d.data(), d.data() + d.size());
  }
  std::ifstream in(dir / "c2m.asc");
  ASSERT_TRUE(in) << "no c2m.asc from CloudCompare";
  std::string line;
  std::getline(in, line);  // "//X Y Z C2M_signed_distances"
  std::size_t n = 0;
  double worst = 0, sum = 0;
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    double x, y, z, d;
    if (!(ss >> x >> y >> z >> d)) continue;
    ASSERT_LT(n, mine.size());
    worst = std::max(worst, std::abs(d - mine[n]));
    sum += d;
    ++n;
  }
  EXPECT_EQ(n, mine.size());
  EXPECT_LT(worst, 1e-3);  // the 1 um
  std::printf("CloudCompare C2M vs vmsim on %zu points: largest difference %.3g um (mean distance %.2f um)\n", n,
              worst * 1e3, sum / static_cast<double>(n) * 1e3);
  fs::remove_all(dir);
}

TEST(MeshDistance, PlaneAgainstClosedForms) {
  // Distance to a plane z = 1 (two triangles) is z - 1, signed; beyond the edge it is the distance to the edge.
  core::TriangleMesh m;
  m.vertices_mm.resize(4, 3);
  m.vertices_mm << 0, 0, 1, 10, 0, 1, 0, 10, 1, 10, 10, 1;
  m.triangles.resize(2, 3);
  m.triangles << 0, 1, 3, 0, 3, 2;
  Eigen::Matrix<double, Eigen::Dynamic, 3> p(4, 3);
  p << 5, 5, 1.25, 2, 3, 0.5, 13, 5, 5, -3, -4, 1;
  const Eigen::VectorXd d = metrology::signed_distances(p, m);
  EXPECT_DOUBLE_EQ(d[0], 0.25);
  EXPECT_DOUBLE_EQ(d[1], -0.5);
  EXPECT_DOUBLE_EQ(d[2], 5.0);  // (3, 4) from the edge x = 10: hypot(3, 4), above the plane
  EXPECT_DOUBLE_EQ(d[3], 5.0);
}
