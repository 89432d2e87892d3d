// part.vtp (render/mesh_io.cpp write_vtp) read back bit for bit. References: VTK's own vtkXMLPolyDataReader (what
// ParaView opens it with), and the VTK XML file format as its documentation gives it ("VTK File Formats", appended
// data: encoding="raw", then per array a UInt32 header {blocks, block size, last block's size, each block's compressed
// size} and the zlib blocks), decoded here with zlib alone. Meshes: a part's height field with NaN holes in its
// deviation, one triangle, a mesh without point data, and a large grid (1.2 M triangles).
#include "render/mesh_io.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>
#include <vtkCellArray.h>
#include <vtkDataArray.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkXMLPolyDataReader.h>
#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <regex>
#include <string>

using namespace vmsim;
using vmsim::render::write_vtp;

namespace {

namespace fs = std::filesystem;

// A ny x nx grid's top as two triangles per cell (the part mesh's layout), heights with 17-digit fractions, and a
// deviation with NaN at every 7th node (a hole in the reference) and the sign bit of -0.0 at another.
core::TriangleMesh vtp_test_grid_mesh(int nx, int ny) {
  core::TriangleMesh m;
  m.vertices_mm.resize(nx * ny, 3);
  Eigen::VectorXd dev(nx * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int v = j * nx + i;
      m.vertices_mm.row(v) << 0.1 * i, 0.1 * j, -3.0 + std::sin(0.37 * i) * std::cos(0.11 * j) / 3.0;
      dev[v] = v % 7 == 3 ? std::numeric_limits<double>::quiet_NaN() : (v % 11 == 5 ? -0.0 : 1e-3 * std::sin(0.1 * v));
    }
  m.triangles.resize(2 * (nx - 1) * (ny - 1), 3);
  int t = 0;
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const int a = j * nx + i, b = a + 1, c = a + nx + 1, e = a + nx;
      m.triangles.row(t++) << a, b, c;
      m.triangles.row(t++) << a, c, e;
    }
  m.point_data.emplace_back("deviation_mm", dev);
  return m;
}

// $TMPDIR/vtp_io/<Suite.Test> (tests/test_paths.hpp's scheme; that header's vmsim::test would clash in this suite's
// unity batches with render's own test namespace).
fs::path vtp_scratch_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir =
      fs::temp_directory_path() / "vtp_io" / (std::string(info->test_suite_name()) + "." + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

bool vtp_same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Everything VTK's reader gives back must equal the mesh bit for bit (NaN's payload and -0.0's sign included).
void expect_vtk_reads_back(const fs::path& file, const core::TriangleMesh& m) {
  vtkNew<vtkXMLPolyDataReader> r;
  r->SetFileName(file.string().c_str());
  r->Update();
  ASSERT_EQ(r->GetErrorCode(), 0u) << file;
  vtkPolyData* pd = r->GetOutput();
  ASSERT_EQ(pd->GetNumberOfPoints(), m.vertices_mm.rows());
  ASSERT_EQ(pd->GetNumberOfPolys(), m.triangles.rows());
  ASSERT_EQ(pd->GetNumberOfCells(), m.triangles.rows());  // no verts, lines or strips
  vtkDataArray* xyz = pd->GetPoints()->GetData();
  ASSERT_EQ(xyz->GetDataType(), VTK_DOUBLE);
  long bad = 0;
  for (vtkIdType v = 0; v < pd->GetNumberOfPoints(); ++v)
    for (int a = 0; a < 3; ++a) bad += !vtp_same_bits(xyz->GetComponent(v, a), m.vertices_mm(v, a));
  EXPECT_EQ(bad, 0) << "coordinates that differ";
  vtkNew<vtkIdList> ids;
  vtkCellArray* polys = pd->GetPolys();
  bad = 0;
  for (vtkIdType t = 0; t < polys->GetNumberOfCells(); ++t) {
    polys->GetCellAtId(t, ids);
    bad += ids->GetNumberOfIds() != 3;
    for (int c = 0; c < 3 && c < ids->GetNumberOfIds(); ++c) bad += ids->GetId(c) != m.triangles(t, c);
  }
  EXPECT_EQ(bad, 0) << "triangle corners that differ";
  ASSERT_EQ(pd->GetPointData()->GetNumberOfArrays(), static_cast<int>(m.point_data.size()));
  for (const auto& [name, values] : m.point_data) {
    vtkDataArray* a = pd->GetPointData()->GetArray(name.c_str());
    ASSERT_NE(a, nullptr) << name;
    ASSERT_EQ(a->GetDataType(), VTK_DOUBLE);
    ASSERT_EQ(a->GetNumberOfTuples(), values.size());
    bad = 0;
    for (vtkIdType v = 0; v < a->GetNumberOfTuples(); ++v) bad += !vtp_same_bits(a->GetComponent(v, 0), values[v]);
    EXPECT_EQ(bad, 0) << name << ": values that differ";
  }
  if (!m.point_data.empty()) {  // the first array is the active scalars ParaView colours by
    ASSERT_NE(pd->GetPointData()->GetScalars(), nullptr);
    EXPECT_EQ(std::string(pd->GetPointData()->GetScalars()->GetName()), m.point_data.front().first);
  }
}

std::string vtp_file_bytes(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// The format documentation's reading of one appended array: the bytes after '_' at its offset, a UInt32 header
// (number of blocks, uncompressed block size, size of the last block when partial, then each block's compressed
// size), then the blocks, each a zlib stream.
std::string vtp_inflate_appended(const std::string& file, std::size_t offset) {
  const std::size_t base = file.find("<AppendedData encoding=\"raw\">");
  const std::size_t data = file.find('_', base) + 1 + offset;
  auto u32 = [&](std::size_t at) {
    std::uint32_t v;
    std::memcpy(&v, file.data() + at, 4);
    return v;
  };
  const std::uint32_t blocks = u32(data), block = u32(data + 4), last = u32(data + 8);
  std::size_t at = data + 12 + 4 * std::size_t{blocks};
  std::string out;
  for (std::uint32_t k = 0; k < blocks; ++k) {
    const std::uint32_t csize = u32(data + 12 + 4 * k);
    uLongf n = (k + 1 == blocks && last != 0) ? last : block;
    std::string raw(n, '\0');
    EXPECT_EQ(
        uncompress(reinterpret_cast<Bytef*>(raw.data()), &n, reinterpret_cast<const Bytef*>(file.data() + at), csize),
        Z_OK);
    out.append(raw.data(), n);
    at += csize;
  }
  return out;
}

}  // namespace

TEST(VtpRoundTrip, HeightFieldWithNaNHolesReadsBackBitForBitThroughVtk) {
  const fs::path dir = vtp_scratch_dir();
  const core::TriangleMesh m = vtp_test_grid_mesh(41, 29);
  for (int level : {1, 5, 9}) {
    write_vtp(dir / "part.vtp", m, level);
    expect_vtk_reads_back(dir / "part.vtp", m);
  }
  // Nothing but the finished file is left (written to a temporary name, then renamed).
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1);
}

TEST(VtpRoundTrip, OneTriangleAndNoPointData) {
  const fs::path dir = vtp_scratch_dir();
  core::TriangleMesh m;
  m.vertices_mm.resize(3, 3);
  m.vertices_mm << 0, 0, 0, 1, 0, 0.1, 0, 1, std::nextafter(0.2, 1.0);
  m.triangles.resize(1, 3);
  m.triangles << 0, 1, 2;
  write_vtp(dir / "one.vtp", m);
  expect_vtk_reads_back(dir / "one.vtp", m);
  m.point_data.emplace_back("deviation_mm", Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), -0.0, 5e-324));
  m.point_data.emplace_back("second", Eigen::Vector3d(1, 2, 3));
  write_vtp(dir / "one.vtp", m, 1);
  expect_vtk_reads_back(dir / "one.vtp", m);
}

TEST(VtpRoundTrip, LargeGridReadsBackAndItsRawAppendedDataDecodesByTheFormatDocumentation) {
  const fs::path dir = vtp_scratch_dir();
  const core::TriangleMesh m = vtp_test_grid_mesh(780, 780);  // 1.21 M triangles: many 32 KiB zlib blocks per array
  write_vtp(dir / "big.vtp", m, 1);
  expect_vtk_reads_back(dir / "big.vtp", m);
  // The encoding chosen in issue 21 (raw appended binary, 32-bit cell arrays), and the points and the deviation as the
  // format documentation reads them: the same bytes as the mesh's doubles.
  const std::string f = vtp_file_bytes(dir / "big.vtp");
  EXPECT_NE(f.find("<AppendedData encoding=\"raw\">"), std::string::npos);
  EXPECT_EQ(f.find("format=\"binary\""), std::string::npos);  // nothing base64-encoded inside the XML
  EXPECT_EQ(f.find("header_type=\"UInt32\""), f.find("header_type="));
  const auto offset_of = [&](const std::string& array) {
    std::smatch s;
    const std::string head = f.substr(0, f.find("<AppendedData"));
    EXPECT_TRUE(std::regex_search(head, s, std::regex("Name=\"" + array + "\"[^>]*offset=\"([0-9]+)\"")));
    return static_cast<std::size_t>(std::stoull(s[1].str()));
  };
  EXPECT_TRUE(std::regex_search(f.substr(0, f.find("<AppendedData")),
                                std::regex("<Polys>\\s*<DataArray type=\"Int32\" Name=\"connectivity\"")));
  const std::string xyz = vtp_inflate_appended(f, offset_of("Points"));
  ASSERT_EQ(xyz.size(), sizeof(double) * 3 * m.vertices_mm.rows());
  EXPECT_EQ(std::memcmp(xyz.data(), m.vertices_mm.data(), xyz.size()), 0);
  const std::string dev = vtp_inflate_appended(f, offset_of("deviation_mm"));
  ASSERT_EQ(dev.size(), sizeof(double) * m.vertices_mm.rows());
  EXPECT_EQ(std::memcmp(dev.data(), m.point_data[0].second.data(), dev.size()), 0);
}

TEST(VtpRoundTrip, RefusesABadLevelAndPointDataOfTheWrongLength) {
  const fs::path dir = vtp_scratch_dir();
  core::TriangleMesh m = vtp_test_grid_mesh(3, 3);
  EXPECT_THROW(write_vtp(dir / "x.vtp", m, 0), core::Error);
  EXPECT_THROW(write_vtp(dir / "x.vtp", m, 10), core::Error);
  m.point_data.emplace_back("short", Eigen::VectorXd::Zero(2));
  try {
    write_vtp(dir / "x.vtp", m, 1);
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("\"short\" does not have one value per vertex"), std::string::npos);
  }
  EXPECT_FALSE(fs::exists(dir / "x.vtp"));
}
