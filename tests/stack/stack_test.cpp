// Each dependency of STACK.md does one real thing here; the expected values are the libraries' own
// documented behaviour (a unit sphere's level set, a ray hitting a triangle at t = 1, an LP's optimum).
#include <gtest/gtest.h>

#include <ClpSimplex.hpp>
#include <embree3/rtcore.h>
#include <mpi.h>
#include <omp.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <pugixml.hpp>
#include <tbb/parallel_reduce.h>
#include <tbb/blocked_range.h>
#include <vtkNew.h>
#include <vtkPolyData.h>
#include <vtkSphereSource.h>
#include <zip.h>

#include <Eigen/Dense>
#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <toml++/toml.h>

#include <cmath>
#include <string>

TEST(Stack, TomlAndJson) {
  auto tbl = toml::parse("a = 1.5\n[b]\nc = \"x\"\n");
  EXPECT_DOUBLE_EQ(tbl["a"].value_or(0.0), 1.5);
  auto j = nlohmann::json::parse(R"({"k": [1, 2, 3]})");
  EXPECT_EQ(j["k"].size(), 3u);
  EXPECT_EQ(fmt::format("{:.3f}", 1.23456), "1.235");
}

TEST(Stack, PugixmlParses) {
  pugi::xml_document doc;
  ASSERT_TRUE(doc.load_string("<r><x>4</x></r>"));
  EXPECT_EQ(doc.child("r").child("x").text().as_int(), 4);
}

TEST(Stack, LibzipRoundTripInMemory) {
  zip_error_t err;
  zip_error_init(&err);
  zip_source_t* src = zip_source_buffer_create(nullptr, 0, 0, &err);
  ASSERT_NE(src, nullptr);
  zip_source_keep(src);
  zip_t* za = zip_open_from_source(src, ZIP_TRUNCATE, &err);
  ASSERT_NE(za, nullptr);
  static const char payload[] = "hello";
  zip_source_t* file = zip_source_buffer(za, payload, 5, 0);
  ASSERT_GE(zip_file_add(za, "a.txt", file, ZIP_FL_OVERWRITE), 0);
  ASSERT_EQ(zip_close(za), 0);
  zip_t* zr = zip_open_from_source(src, ZIP_RDONLY, &err);
  ASSERT_NE(zr, nullptr);
  zip_file_t* f = zip_fopen(zr, "a.txt", 0);
  ASSERT_NE(f, nullptr);
  char buf[8] = {};
  EXPECT_EQ(zip_fread(f, buf, sizeof buf), 5);
  EXPECT_EQ(std::string(buf), "hello");
  zip_fclose(f);
  zip_discard(zr);
  zip_error_fini(&err);
}

TEST(Stack, ClpSolvesSmallLp) {
  // max 3x + 2y  s.t.  x + y <= 4, x + 3y <= 6, x, y >= 0  ->  optimum 12 at (4, 0)
  ClpSimplex model;
  model.setLogLevel(0);
  const int starts[] = {0, 2, 4};
  const int rows[] = {0, 1, 0, 1};
  const double els[] = {1, 1, 1, 3};
  const double colLo[] = {0, 0}, colUp[] = {COIN_DBL_MAX, COIN_DBL_MAX};
  const double obj[] = {-3, -2};
  const double rowLo[] = {-COIN_DBL_MAX, -COIN_DBL_MAX}, rowUp[] = {4, 6};
  model.loadProblem(2, 2, starts, rows, els, colLo, colUp, obj, rowLo, rowUp);
  model.dual();
  EXPECT_TRUE(model.isProvenOptimal());
  EXPECT_NEAR(-model.objectiveValue(), 12.0, 1e-9);
}

TEST(Stack, EmbreeRayHitsTriangle) {
  RTCDevice dev = rtcNewDevice(nullptr);
  ASSERT_NE(dev, nullptr);
  RTCScene scene = rtcNewScene(dev);
  RTCGeometry geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3));
  auto* idx = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), 1));
  const float verts[] = {-1, -1, 0, 1, -1, 0, 0, 1, 0};
  std::copy(verts, verts + 9, v);
  idx[0] = 0;
  idx[1] = 1;
  idx[2] = 2;
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh{};
  rh.ray.org_x = 0;
  rh.ray.org_y = 0;
  rh.ray.org_z = -1;
  rh.ray.dir_x = 0;
  rh.ray.dir_y = 0;
  rh.ray.dir_z = 1;
  rh.ray.tnear = 0;
  rh.ray.tfar = 1e30f;
  rh.ray.mask = 0xFFFFFFFF;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene, &ctx, &rh);
  EXPECT_NE(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID);
  EXPECT_NEAR(rh.ray.tfar, 1.0f, 1e-6f);
  rtcReleaseScene(scene);
  rtcReleaseDevice(dev);
}

TEST(Stack, OpenVdbLevelSetSphere) {
  openvdb::initialize();
  auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0), 0.05f);
  ASSERT_TRUE(grid);
  auto acc = grid->getConstAccessor();
  // Inside the narrow band the value is the signed distance in world units: 0.5 at radius 1.5 ... here at the centre
  // of a voxel on the surface the distance is ~0.
  const float on_surface = acc.getValue(openvdb::Coord(20, 0, 0));
  EXPECT_NEAR(on_surface, 0.0f, 1e-3f);
  EXPECT_GT(grid->activeVoxelCount(), 10000u);
}

TEST(Stack, VtkSphereSource) {
  vtkNew<vtkSphereSource> s;
  s->SetThetaResolution(16);
  s->SetPhiResolution(8);
  s->Update();
  EXPECT_GT(s->GetOutput()->GetNumberOfPoints(), 50);
}

TEST(Stack, OpenMpAndTbbReduce) {
  double sum = 0;
#pragma omp parallel for reduction(+ : sum)
  for (int i = 1; i <= 1000; ++i) sum += i;
  EXPECT_EQ(sum, 500500.0);
  const double tbb_sum = tbb::parallel_reduce(
      tbb::blocked_range<int>(1, 1001), 0.0,
      [](const tbb::blocked_range<int>& r, double acc) {
        for (int i = r.begin(); i != r.end(); ++i) acc += i;
        return acc;
      },
      [](double a, double b) { return a + b; });
  EXPECT_EQ(tbb_sum, 500500.0);
}

TEST(Stack, MpiLinks) {
  int initialized = 1;
  MPI_Initialized(&initialized);
  EXPECT_EQ(initialized, 0);  // nothing here calls MPI_Init; the call itself proves the library links and loads
}

TEST(Stack, EigenSolves) {
  Eigen::Matrix3d a;
  a << 4, 1, 0, 1, 3, 1, 0, 1, 2;
  Eigen::Vector3d b(1, 2, 3);
  Eigen::Vector3d x = a.ldlt().solve(b);
  EXPECT_LT((a * x - b).norm(), 1e-12);
}
