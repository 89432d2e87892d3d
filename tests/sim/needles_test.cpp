// The N-buffer needles file ([removal] needles_file) as sim::initial_field reads it (core/csv): the corner part's own
// file (parts/corner/corner_needles.csv) against an independent line-by-line parse (std::stod), header-less files,
// columns by name in any order with extra columns ignored, and errors that name the file, line and column.
#include "sim/pipeline.hpp"

#include "core/error.hpp"
#include "core/job.hpp"
#include "core/progress.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cctype>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace vmsim {
namespace {

core::Job needle_job(const std::filesystem::path& file) {
  core::Job job;
  job.name = "needles";
  job.file = "needles_job.toml";
  job.stock.kind = core::StockSpec::Kind::Box;
  job.stock.min_mm = Eigen::Vector3d(-100, -100, -100);
  job.stock.max_mm = Eigen::Vector3d(100, 100, 100);
  job.removal.field = core::RemovalSpec::Field::NBuffer;
  job.removal.needles_file = file;
  job.removal.needle_half_length_mm = 0.5;
  return job;
}

sim::Field field_of(const std::filesystem::path& file) {
  core::Progress quiet;
  std::set<std::string> chain;
  return sim::initial_field(needle_job(file), quiet, chain);
}

std::filesystem::path write(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / ("vmsim_needles_" + std::to_string(::getpid()) + "_" + name);
  std::ofstream(p) << text;
  return p;
}

std::string error_of(const std::string& name, const std::string& text) {
  const auto p = write(name, text);
  try {
    (void)field_of(p);
  } catch (const core::Error& e) {
    std::filesystem::remove(p);
    return std::string(e.what()).substr(std::string(e.what()).rfind('/') + 1);
  }
  std::filesystem::remove(p);
  return "no error";
}

}  // namespace

TEST(Needles, CornerPartFileAsAPlainParseReadsIt) {
  const std::filesystem::path file = std::string(VMSIM_SOURCE_DIR) + "/parts/corner/corner_needles.csv";
  // The reference: every line starting with a digit or '-' is x,y,z,nx,ny,nz.
  std::vector<std::vector<double>> rows;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || !(std::isdigit(static_cast<unsigned char>(line[0])) || line[0] == '-')) continue;
    std::stringstream ss(line);
    std::string cell;
    std::vector<double> r;
    while (std::getline(ss, cell, ',')) r.push_back(std::stod(cell));
    ASSERT_EQ(r.size(), 6u) << line;
    rows.push_back(r);
  }
  ASSERT_GT(rows.size(), 100u);
  const sim::Field f = field_of(file);
  ASSERT_EQ(f.needle_point.size(), rows.size());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    EXPECT_EQ(f.needle_point[k], Eigen::Vector3d(rows[k][0], rows[k][1], rows[k][2])) << k;
    EXPECT_EQ(f.needle_normal[k], Eigen::Vector3d(rows[k][3], rows[k][4], rows[k][5]).normalized()) << k;
  }
  EXPECT_EQ(f.needles.size(), rows.size());
}

TEST(Needles, HeaderOptionalColumnsByName) {
  const auto bare = write("bare.csv", "# no header\n1,2,3,0,0,2\n\n4,5,6,0,3,0\n");
  const sim::Field a = field_of(bare);
  ASSERT_EQ(a.needle_point.size(), 2u);
  EXPECT_EQ(a.needle_point[1], Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(a.needle_normal[0], Eigen::Vector3d(0, 0, 1));
  const auto named = write("named.csv", "nz,id,x,y,z,nx,ny\n2,7,1,2,3,0,0\n0,8,4,5,6,0,3\n");
  const sim::Field b = field_of(named);
  ASSERT_EQ(b.needle_point.size(), 2u);
  EXPECT_EQ(b.needle_point[0], Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(b.needle_normal[0], Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(b.needle_normal[1], Eigen::Vector3d(0, 1, 0));
  std::filesystem::remove(bare);
  std::filesystem::remove(named);
}

TEST(Needles, ErrorsNameTheLine) {
  EXPECT_EQ(error_of("a.csv", "x,y,z,nx,ny,nz\n1,2,3,0,0,1\n1,2,3x,0,0,1\n"),
            "vmsim_needles_" + std::to_string(::getpid()) + "_a.csv:3: column 3 'z': '3x' is not a finite number");
  EXPECT_NE(error_of("b.csv", "1,2,3,0,0,1\n1,2,3,0,0\n").find("b.csv:2: 5 values, expected 6: x,y,z,nx,ny,nz (mm)"),
            std::string::npos);
  EXPECT_NE(error_of("c.csv", "x,y,z,nx,ny\n1,2,3,0,0\n").find("c.csv:1: no column 'nz' (found: x, y, z, nx, ny)"),
            std::string::npos);
  EXPECT_NE(error_of("d.csv", "1,2,3,0,0,0\n").find("d.csv:1: the normal has zero length"), std::string::npos);
  EXPECT_NE(error_of("e.csv", "# nothing\n").find("no needles"), std::string::npos);
}

}  // namespace vmsim
