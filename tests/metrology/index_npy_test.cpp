// Index grids as NumPy .npy files (tool_map.npy: which tool last cut each node). Reference: the bytes numpy.save
// (numpy 1.24, Debian 12's python3-numpy) writes for the same small int8 / uint8 / float64 arrays, spelled out below
// from its output: vmsim writes them byte for byte and reads what numpy writes, in C and Fortran order.
#include "core/error.hpp"
#include "metrology/grid_io.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace {

namespace fs = std::filesystem;

bool same_index(const vmsim::metrology::IndexGrid& a, const vmsim::metrology::IndexGrid& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && (a == b).all();
}

// numpy.save's file: the magic, version 1.0, the header's length (118 = 0x76 for these small shapes), the dict padded
// with spaces to 117 characters and a newline (so the data start at byte 128), then the values.
std::string npy_as_numpy_writes(const std::string& dict, const std::string& data) {
  std::string header = dict;
  header += std::string(117 - dict.size(), ' ');
  header += '\n';
  return std::string("\x93NUMPY\x01\x00\x76\x00", 10) + header + data;
}

fs::path index_npy_tmp(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("vmsim_index_npy_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d / name;
}

void write_npy_bytes(const fs::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary) << bytes;
}

std::string read_npy_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// np.array([[0, 1, -1], [2, -1, 0]], dtype=np.int8)
const char kIndexDictC[] = "{'descr': '|i1', 'fortran_order': False, 'shape': (2, 3), }";
const std::string kIndexDataC("\x00\x01\xff\x02\xff\x00", 6);

}  // namespace

TEST(IndexNpy, WritesTheBytesNumpyWrites) {
  vmsim::metrology::IndexGrid index(2, 3);
  index << 0, 1, -1, 2, -1, 0;
  vmsim::core::HeightGrid on;
  on.x0_mm = -1.5, on.y0_mm = 2.0, on.dx_mm = 0.25, on.dy_mm = 0.5;
  on.z_mm = vmsim::core::HeightArray::Zero(2, 3);
  const fs::path f = index_npy_tmp("w.npy");
  vmsim::metrology::write_index_npy(f, index, on, "index of the tool; -1: uncut \"none\"");
  EXPECT_EQ(read_npy_bytes(f), npy_as_numpy_writes(kIndexDictC, kIndexDataC));
  // The sidecar: the grid's geometry as the height .npy files give it, and what the values mean (a JSON string).
  const std::string side = read_npy_bytes(fs::path(f.string() + ".json"));
  EXPECT_NE(side.find("\"x0_mm\": -1.5, \"y0_mm\": 2, \"dx_mm\": 0.25, \"dy_mm\": 0.5, \"nx\": 3, \"ny\": 2"),
            std::string::npos)
      << side;
  EXPECT_NE(side.find("\"values\": \"index of the tool; -1: uncut \\\"none\\\"\""), std::string::npos) << side;
  EXPECT_TRUE(same_index(vmsim::metrology::read_index_npy(f), index));
  // An index whose shape is not its grid's is refused.
  on.z_mm = vmsim::core::HeightArray::Zero(3, 2);
  EXPECT_THROW(vmsim::metrology::write_index_npy(f, index, on, ""), vmsim::core::Error);
}

TEST(IndexNpy, ReadsWhatNumpyWritesInBothOrders) {
  vmsim::metrology::IndexGrid want(2, 3);
  want << 0, 1, -1, 2, -1, 0;
  const fs::path c = index_npy_tmp("c.npy"), f = index_npy_tmp("f.npy"), u = index_npy_tmp("u.npy");
  write_npy_bytes(c, npy_as_numpy_writes(kIndexDictC, kIndexDataC));
  // np.asfortranarray of the same array: column by column.
  write_npy_bytes(f, npy_as_numpy_writes("{'descr': '|i1', 'fortran_order': True, 'shape': (2, 3), }",
                                     std::string("\x00\x02\x01\xff\xff\x00", 6)));
  EXPECT_TRUE(same_index(vmsim::metrology::read_index_npy(c), want));
  EXPECT_TRUE(same_index(vmsim::metrology::read_index_npy(f), want));
  // uint8 values up to 127 read as they are; np.array([[3, 100]], dtype=np.uint8).
  write_npy_bytes(u, npy_as_numpy_writes("{'descr': '|u1', 'fortran_order': False, 'shape': (1, 2), }", "\x03\x64"));
  const vmsim::metrology::IndexGrid small = vmsim::metrology::read_index_npy(u);
  ASSERT_EQ(small.rows(), 1);
  ASSERT_EQ(small.cols(), 2);
  EXPECT_EQ(small(0, 0), 3);
  EXPECT_EQ(small(0, 1), 100);
}

TEST(IndexNpy, RefusalsNameTheFileAndWhatWasExpected) {
  const fs::path p = index_npy_tmp("bad.npy");
  auto message = [&](const std::string& bytes) {
    write_npy_bytes(p, bytes);
    try {
      vmsim::metrology::read_index_npy(p);
    } catch (const vmsim::core::Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  // np.array([[1.5]]): float64, not an index.
  std::string m = message(npy_as_numpy_writes("{'descr': '<f8', 'fortran_order': False, 'shape': (1, 1), }",
                                              std::string("\x00\x00\x00\x00\x00\x00\xf8\x3f", 8)));
  EXPECT_NE(m.find(p.string()), std::string::npos) << m;
  EXPECT_NE(m.find("'<f8'"), std::string::npos) << m;
  m = message(npy_as_numpy_writes("{'descr': '|u1', 'fortran_order': False, 'shape': (1, 2), }", "\x03\xc8"));
  EXPECT_NE(m.find("200"), std::string::npos) << m;  // np.uint8 200 does not fit an index
  m = message(npy_as_numpy_writes("{'descr': '|i1', 'fortran_order': False, 'shape': (6,), }", kIndexDataC));
  EXPECT_NE(m.find("not 2-D"), std::string::npos) << m;
  m = message(npy_as_numpy_writes(kIndexDictC, std::string("\x00\x01", 2)));
  EXPECT_NE(m.find("cut short"), std::string::npos) << m;
  m = message("PK\x03\x04 not numpy");
  EXPECT_NE(m.find("not a NumPy .npy file"), std::string::npos) << m;
}
