// The writers' number and record encodings made cheaper in issue 21, against references written elsewhere:
//  - core::append_general(v, 7) against fmt's "{:.7g}" (fmt's own float formatter, which signals.csv used before) and
//    against the value read back (7 significant digits: within half a unit of the 7th digit);
//  - write_stl_binary's bytes against the format as the STL specification gives it (80-byte header, little-endian
//    uint32 count, per facet 12 little-endian float32 and a zero uint16), encoded here byte by byte.
#include "core/csv.hpp"
#include "core/stl.hpp"
#include "tests/test_paths.hpp"

#include <fmt/format.h>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace vmsim::core {
namespace {

std::vector<double> writer_bytes_values() {
  std::vector<double> v = {0.0,
                           -0.0,
                           1.0,
                           -1.0,
                           0.1,
                           1e-5,
                           1e-4,
                           9.9999995e-5,
                           123456.75,
                           1234567.5,
                           9999999.5,
                           99999995.0,
                           1e7,
                           1e16,
                           1e-300,
                           5e-324,
                           std::numeric_limits<double>::min(),
                           std::numeric_limits<double>::max(),
                           std::numeric_limits<double>::lowest(),
                           0.5,
                           2.5e-7,
                           1.0 / 3.0};
  std::mt19937_64 rng(2127);
  std::uniform_real_distribution<double> mant(-10.0, 10.0);
  std::uniform_int_distribution<int> ex(-320, 300);
  for (int k = 0; k < 200000; ++k) v.push_back(mant(rng) * std::pow(10.0, ex(rng)));
  // Signals' own range: positions, speeds, currents, with a few digits and halves that round at the 7th digit.
  std::uniform_real_distribution<double> sig(-5000.0, 5000.0);
  for (int k = 0; k < 200000; ++k) v.push_back(sig(rng));
  for (int k = 0; k < 20000; ++k) v.push_back(std::round(sig(rng) * 1e4) / 1e4 + 5e-8);
  // Random bit patterns (finite ones): every exponent and mantissa.
  std::uniform_int_distribution<std::uint64_t> bits;
  for (int k = 0; k < 200000; ++k) {
    const double d = std::bit_cast<double>(bits(rng));
    if (std::isfinite(d)) v.push_back(d);
  }
  return v;
}

TEST(WriterBytes, GeneralSevenDigitsAreFmtsBytes) {
  std::string line;
  for (const double v : writer_bytes_values()) {
    line.clear();
    append_general(line, v, 7);
    ASSERT_EQ(line, fmt::format("{:.7g}", v)) << "value bits " << std::bit_cast<std::uint64_t>(v);
    double back = 0.0;
    const auto r = std::from_chars(line.data(), line.data() + line.size(), back);
    ASSERT_EQ(r.ec, std::errc()) << line;
    if (v != 0.0 && std::isfinite(v) && std::abs(v) >= std::numeric_limits<double>::min()) {
      ASSERT_LE(std::abs(back - v), 5.0000001e-7 * std::abs(v)) << line;
    }
  }
  // Appended: what was there stays.
  line = "a,";
  append_general(line, 0.25, 7);
  EXPECT_EQ(line, "a,0.25");
}

void writer_bytes_le32(std::string& out, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<char>((v >> (8 * k)) & 0xffu));
}

TEST(WriterBytes, BinaryStlIsTheSpecifiedRecordLayout) {
  // A closed mesh: a tetrahedron, then an octahedron-like fan with random vertices (welded, closed: 8 faces).
  std::mt19937_64 rng(2128);
  std::uniform_real_distribution<double> c(-30.0, 30.0);
  TriangleMesh m;
  m.vertices_mm.resize(6, 3);
  for (int i = 0; i < 6; ++i)
    for (int a = 0; a < 3; ++a) m.vertices_mm(i, a) = (a == i % 3 ? (i < 3 ? 40.0 : -40.0) : 0.0) + 0.1 * c(rng);
  // Octahedron: +x=0, +y=1, +z=2, -x=3, -y=4, -z=5.
  m.triangles.resize(8, 3);
  m.triangles << 0, 1, 2, 1, 3, 2, 3, 4, 2, 4, 0, 2, 1, 0, 5, 3, 1, 5, 4, 3, 5, 0, 4, 5;
  const std::filesystem::path p = test::test_scratch_dir("core") / "octa.stl";
  write_stl_binary(p, m);
  std::ifstream in(p, std::ios::binary);
  const std::string got((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());

  std::string want = "vmsim binary STL, units mm";
  want.resize(80, ' ');
  writer_bytes_le32(want, 8);
  for (int t = 0; t < 8; ++t) {
    const Eigen::Vector3d a = m.vertices_mm.row(m.triangles(t, 0)).transpose();
    const Eigen::Vector3d b = m.vertices_mm.row(m.triangles(t, 1)).transpose();
    const Eigen::Vector3d d = m.vertices_mm.row(m.triangles(t, 2)).transpose();
    const Eigen::Vector3d n = (b - a).cross(d - a).normalized();
    for (int k = 0; k < 3; ++k) writer_bytes_le32(want, std::bit_cast<std::uint32_t>(static_cast<float>(n[k])));
    for (int v = 0; v < 3; ++v)
      for (int k = 0; k < 3; ++k)
        writer_bytes_le32(want, std::bit_cast<std::uint32_t>(static_cast<float>(m.vertices_mm(m.triangles(t, v), k))));
    want.push_back('\0');
    want.push_back('\0');
  }
  ASSERT_EQ(got.size(), 84u + 50u * 8u);
  // Byte for byte (the normal may differ in its last float bit from a differently rounded normalisation: compared
  // as floats within 1e-6, everything else exactly).
  for (int t = 0; t < 8; ++t) {
    const std::size_t r = 84 + 50 * static_cast<std::size_t>(t);
    for (int k = 0; k < 3; ++k) {
      float fg, fw;
      std::memcpy(&fg, got.data() + r + 4 * k, 4);
      std::memcpy(&fw, want.data() + r + 4 * k, 4);
      EXPECT_NEAR(fg, fw, 1e-6f) << "facet " << t;
    }
    EXPECT_EQ(got.substr(r + 12, 38), want.substr(r + 12, 38)) << "facet " << t;
  }
  EXPECT_EQ(got.substr(0, 84), want.substr(0, 84));
  // And it reads back as the same mesh (float corners).
  const TriangleMesh back = read_stl(p);
  EXPECT_EQ(back.triangles.rows(), 8);
}

}  // namespace
}  // namespace vmsim::core
