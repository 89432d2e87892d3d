// STL reader and writer: round trips (binary, ASCII), format detection (a binary header that starts with "solid"),
// welding, closedness diagnostics, and errors on broken or hostile files, each naming the file (and the line).
#include "core/error.hpp"
#include "core/stl.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>

namespace fs = std::filesystem;
using vmsim::core::Error;
using vmsim::core::TriangleMesh;

namespace {

fs::path work() {
  const fs::path d = fs::path(VMSIM_BINARY_DIR) / "tests" / "core" / "work" / "stl";
  fs::create_directories(d);
  return d;
}

void write_bytes(const fs::path& p, const std::string& s) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << s;
}

// An axis-aligned box: 8 corners, 12 triangles counter-clockwise seen from outside.
TriangleMesh box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  TriangleMesh m;
  m.vertices_mm.resize(8, 3);
  for (int k = 0; k < 8; ++k)
    m.vertices_mm.row(k) << ((k & 1) ? hi.x() : lo.x()), ((k & 2) ? hi.y() : lo.y()), ((k & 4) ? hi.z() : lo.z());
  m.triangles.resize(12, 3);
  m.triangles << 0, 2, 1, 1, 2, 3,  // z = lo (normal -z)
      4, 5, 6, 5, 7, 6,             // z = hi
      0, 1, 4, 1, 5, 4,             // y = lo
      2, 6, 3, 3, 6, 7,             // y = hi
      0, 4, 2, 2, 4, 6,             // x = lo
      1, 3, 5, 3, 7, 5;             // x = hi
  return m;
}

// Same geometry, triangle for triangle (vertex numbering may differ after welding).
void expect_same_triangles(const TriangleMesh& a, const TriangleMesh& b) {
  ASSERT_EQ(a.triangles.rows(), b.triangles.rows());
  for (Eigen::Index t = 0; t < a.triangles.rows(); ++t)
    for (int c = 0; c < 3; ++c)
      for (int x = 0; x < 3; ++x)
        EXPECT_EQ(a.vertices_mm(a.triangles(t, c), x), b.vertices_mm(b.triangles(t, c), x)) << "triangle " << t;
}

std::string stl_error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

std::string le32(std::uint32_t v) {
  std::string s;
  for (int k = 0; k < 4; ++k) s += static_cast<char>((v >> (8 * k)) & 0xff);
  return s;
}

}  // namespace

TEST(Stl, BinaryRoundTripWeldsCorners) {
  const TriangleMesh m = box({-2.5, 1.25, -10}, {37.5, 21.25, 0});
  const fs::path p = work() / "box.stl";
  vmsim::core::write_stl_binary(p, m);
  EXPECT_EQ(fs::file_size(p), 84u + 50u * 12u);
  const TriangleMesh r = vmsim::core::read_stl(p);
  EXPECT_EQ(r.vertices_mm.rows(), 8);  // 36 corners in the file, 8 points
  expect_same_triangles(m, r);
  EXPECT_NO_THROW(vmsim::core::check_closed(r, p.string()));
  // No temporary file left beside the result.
  for (const auto& e : fs::directory_iterator(work()))
    EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
}

TEST(Stl, AsciiRoundTripIsExactInDouble) {
  TriangleMesh m = box({0.1, 1.0 / 3, -7e-5}, {12345.678901234, 2.0 / 3 + 10, 1e-3});
  const fs::path p = work() / "box_ascii.stl";
  vmsim::core::write_stl_ascii(p, m, "part one");
  const TriangleMesh r = vmsim::core::read_stl(p);
  EXPECT_EQ(r.vertices_mm.rows(), 8);
  expect_same_triangles(m, r);  // shortest round-trip decimals: every double back bit for bit
}

TEST(Stl, BinaryWhoseHeaderStartsWithSolidIsBinary) {
  const TriangleMesh m = box({0, 0, 0}, {1, 2, 3});
  const fs::path p = work() / "solid_header.stl";
  vmsim::core::write_stl_binary(p, m);
  std::string bytes;
  {
    std::ifstream in(p, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  bytes.replace(0, 20, "solid exported by X ");  // as SolidWorks and others write it
  write_bytes(p, bytes);
  const TriangleMesh r = vmsim::core::read_stl(p);
  expect_same_triangles(m, r);
}

TEST(Stl, AsciiVariantsRead) {
  // Upper case, CRLF, tabs, a leading '+', exponents, two solids in one file, a name with spaces.
  const std::string text =
      "solid first body\r\n"
      "FACET NORMAL 0 0 -1\r\n OUTER LOOP\r\n  VERTEX 0 0 0\r\n  VERTEX +0 1 0\r\n  VERTEX 1e0 0 0\r\n ENDLOOP\r\n"
      "ENDFACET\r\nENDSOLID first body\r\n"
      "solid second\n\tfacet normal 0 0 0\n\t\touter loop\n\t\t\tvertex 0 0 0\n\t\t\tvertex 1 0 0\n"
      "\t\t\tvertex 0 0 1.0E+00\n\t\tendloop\n\tendfacet\nendsolid\n";
  const fs::path p = work() / "variants.stl";
  write_bytes(p, text);
  const TriangleMesh r = vmsim::core::read_stl(p);
  EXPECT_EQ(r.triangles.rows(), 2);
  EXPECT_EQ(r.vertices_mm.rows(), 4);  // (0,0,0) and (1,0,0) shared by the two solids' facets
}

TEST(Stl, WeldTolerance) {
  // Corners printed with different rounding: exact welding leaves holes, a tolerance closes them.
  TriangleMesh m = box({0, 0, 0}, {10, 10, 10});
  TriangleMesh unwelded;
  unwelded.vertices_mm.resize(36, 3);
  unwelded.triangles.resize(12, 3);
  for (int t = 0; t < 12; ++t)
    for (int c = 0; c < 3; ++c) {
      unwelded.vertices_mm.row(3 * t + c) = m.vertices_mm.row(m.triangles(t, c)).array() + 1e-7 * ((t * 3 + c) % 5);
      unwelded.triangles(t, c) = 3 * t + c;
    }
  const fs::path p = work() / "sloppy.stl";
  vmsim::core::write_stl_ascii(p, unwelded);
  const TriangleMesh exact = vmsim::core::read_stl(p);
  const std::string e = stl_error_of([&] { vmsim::core::check_closed(exact, p.string()); });
  EXPECT_EQ(e.rfind(p.string() + ": the mesh is not closed", 0), 0u) << e;
  vmsim::core::StlReadOptions o;
  o.weld_tolerance_mm = 1e-5;
  const TriangleMesh welded = vmsim::core::read_stl(p, o);
  EXPECT_EQ(welded.vertices_mm.rows(), 8);
  EXPECT_NO_THROW(vmsim::core::check_closed(welded, p.string()));
  o.weld_tolerance_mm = -1;
  EXPECT_NE(stl_error_of([&] { (void)vmsim::core::read_stl(p, o); }).find("weld tolerance"), std::string::npos);
}

TEST(Stl, ClosednessProblemsNameTheFileAndTheFacet) {
  const fs::path p = work() / "problems.stl";
  const TriangleMesh good = box({0, 0, 0}, {1, 1, 1});
  EXPECT_FALSE(vmsim::core::closed_mesh_problem(good));

  TriangleMesh hole = good;  // last facet removed
  hole.triangles.conservativeResize(11, 3);
  std::string e = stl_error_of([&] { vmsim::core::check_closed(hole, p.string()); });
  EXPECT_EQ(e.rfind(p.string() + ": the mesh is not closed", 0), 0u) << e;
  EXPECT_NE(e.find("facet #"), std::string::npos) << e;

  TriangleMesh flipped = good;  // facet #6 reversed
  std::swap(flipped.triangles(5, 1), flipped.triangles(5, 2));
  e = stl_error_of([&] { vmsim::core::check_closed(flipped, p.string()); });
  EXPECT_EQ(e.rfind(p.string() + ": inconsistent orientation", 0), 0u) << e;
  EXPECT_NE(e.find("#6"), std::string::npos) << e;

  TriangleMesh fin = good;  // a 13th facet hanging off the edge (0,0,0)-(1,0,0)
  fin.vertices_mm.conservativeResize(9, 3);
  fin.vertices_mm.row(8) << 0.5, -1, -1;
  fin.triangles.conservativeResize(13, 3);
  fin.triangles.row(12) << 0, 1, 8;
  e = stl_error_of([&] { vmsim::core::check_closed(fin, p.string()); });
  EXPECT_EQ(e.rfind(p.string() + ": the mesh is not manifold", 0), 0u) << e;
  EXPECT_NE(e.find("3 facets"), std::string::npos) << e;

  // A facet with a repeated corner bounds no area: ignored, the box stays closed.
  TriangleMesh sliver = good;
  sliver.triangles.conservativeResize(13, 3);
  sliver.triangles.row(12) << 0, 0, 1;
  EXPECT_FALSE(vmsim::core::closed_mesh_problem(sliver));
  // ... but mentioned when the mesh is open anyway.
  sliver.triangles.row(11) = sliver.triangles.row(12);
  e = stl_error_of([&] { vmsim::core::check_closed(sliver, p.string()); });
  EXPECT_NE(e.find("repeated vertex"), std::string::npos) << e;

  TriangleMesh empty;
  EXPECT_NE(stl_error_of([&] { vmsim::core::check_closed(empty, p.string()); }).find("no triangles"),
            std::string::npos);
  TriangleMesh bad_index = good;
  bad_index.triangles(3, 2) = 99;
  EXPECT_NE(stl_error_of([&] { vmsim::core::check_closed(bad_index, p.string()); }).find("index 99"),
            std::string::npos);
}

TEST(Stl, BrokenAndHostileFilesGiveErrorsNamingTheFile) {
  const fs::path p = work() / "bad.stl";
  const auto err = [&](const std::string& bytes) {
    write_bytes(p, bytes);
    return stl_error_of([&] { (void)vmsim::core::read_stl(p); });
  };
  const std::string name = p.string() + ":";

  // A binary header declaring 4 billion triangles in a 100-byte file: an error, not a 200 GB allocation.
  std::string huge(80, 'x');
  huge += le32(4000000000u);
  huge += std::string(16, '\0');
  std::string e = err(huge);
  EXPECT_EQ(e.rfind(name, 0), 0u) << e;
  EXPECT_NE(e.find("4000000000 triangles"), std::string::npos) << e;
  EXPECT_NE(e.find("100 bytes"), std::string::npos) << e;

  // The same with a "solid" header (binary bytes after it): both readings explained.
  huge.replace(0, 6, "solid ");
  e = err(huge);
  EXPECT_EQ(e.rfind(name, 0), 0u) << e;
  EXPECT_NE(e.find("binary"), std::string::npos) << e;

  e = err("");
  EXPECT_EQ(e.rfind(name, 0), 0u) << e;
  e = err("hello");
  EXPECT_NE(e.find("not an STL file"), std::string::npos) << e;

  // Binary with a NaN corner.
  {
    std::string b(80, ' ');
    b += le32(1);
    b += std::string(12, '\0');
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int k = 0; k < 9; ++k) b += le32(std::bit_cast<std::uint32_t>(k == 4 ? nan : 1.0f * k));
    b += std::string(2, '\0');
    e = err(b);
    EXPECT_EQ(e.rfind(name, 0), 0u) << e;
    EXPECT_NE(e.find("triangle #1"), std::string::npos) << e;
  }

  const std::string facet =
      "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
  e = err("solid t\n" + facet);  // truncated: no endsolid
  EXPECT_EQ(e.rfind(name + "9:", 0), 0u) << e;
  e = err("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nvertex 1 1 0\n");
  EXPECT_EQ(e.rfind(name + "7: a facet with more than three vertices", 0), 0u) << e;
  e = err("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 zero 0\n");
  EXPECT_EQ(e.rfind(name + "5: expected a number, found \"zero\"", 0), 0u) << e;
  e = err("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 1e400 0\n");
  EXPECT_EQ(e.rfind(name + "5:", 0), 0u) << e;
  e = err("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 inf 0\n");
  EXPECT_EQ(e.rfind(name + "5: vertex coordinate", 0), 0u) << e;
  e = err("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 2e9 0\n");
  EXPECT_EQ(e.rfind(name + "5: vertex coordinate", 0), 0u) << e;
  e = err("solid t\n" + facet + "endsolid t\ngarbage\n");
  EXPECT_EQ(e.rfind(name + "10: expected the end of the file or another \"solid\"", 0), 0u) << e;
  e = err("solid t\n" + facet + "\x01\x02" + "endsolid t\n");
  EXPECT_EQ(e.rfind(name + "9: binary byte", 0), 0u) << e;
  e = err("solid t\nfacet\n");
  EXPECT_EQ(e.rfind(name + "3: expected \"normal\", found \"end of file\"", 0), 0u) << e;

  e = stl_error_of([&] { (void)vmsim::core::read_stl(work() / "does-not-exist.stl"); });
  EXPECT_EQ(e.rfind((work() / "does-not-exist.stl").string() + ":", 0), 0u) << e;
  e = stl_error_of([&] { (void)vmsim::core::read_stl(work()); });
  EXPECT_NE(e.find("not a regular file"), std::string::npos) << e;
}

TEST(Stl, WriterRefusesWhatItCannotWrite) {
  TriangleMesh m = box({0, 0, 0}, {1, 1, 1});
  m.vertices_mm(3, 1) = std::numeric_limits<double>::infinity();
  const fs::path p = work() / "refused.stl";
  const std::string e = stl_error_of([&] { vmsim::core::write_stl_binary(p, m); });
  EXPECT_EQ(e.rfind(p.string() + ":", 0), 0u) << e;
  EXPECT_FALSE(fs::exists(p));
}
