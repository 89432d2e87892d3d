// The header fields of the formats other tools write, one at a time, on small files made here: Digital Surf .sur
// (units and ratios, Zmin, the Z offset, int16, inversion, special points, compressed and multi-object files),
// BCR-STM with an ASCII header (the "ASCII variant" of the binary format: bcrstm int16 and bcrf float32, byte
// order, void points), X3P zips laid out by other tools, gzip, the matrix header keys, and Dektak-style CSV.
// The reference is Gwyddion 2.62 where it reads the file (the comparison skips when it is not installed), and the
// values written into the file otherwise.
#include "core/error.hpp"
#include "metrology/bcr.hpp"
#include "metrology/dektak.hpp"
#include "metrology/sur.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"

#include <gtest/gtest.h>
#include <zip.h>
#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <algorithm>
#include <iterator>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <string>
#include <unistd.h>
#include <vector>

#include "tests/metrology/gwy_reader.hpp"

using namespace vmsim;
namespace fs = std::filesystem;

namespace {

fs::path scan_tmp(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("vmsim_scan_formats_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d / name;
}

void write_bytes(const fs::path& p, const std::string& b) {
  std::ofstream f(p, std::ios::binary);
  f.write(b.data(), static_cast<std::streamsize>(b.size()));
}

// A .sur object as the MountainsMap description lays it out (512-byte header, then the points).
struct SurSpec {
  std::vector<std::int32_t> points;
  int nx = 4, ny = 3, bits = 32, type = 2, special = 0, inversion = 0, objects = 1;
  std::int32_t zmin = 0;
  float dx = 0.5f, dy = 0.25f, dz = 1e-3f, xoff = 0, yoff = 0, zoff = 0, rx = 1, ry = 1, rz = 1;
  std::string xstep = "um", zstep = "um", xlen = "um", zlen = "um";
  bool compressed = false;
};

std::string sur_object(const SurSpec& s) {
  std::string h(512, '\0');
  const auto str = [&](std::size_t off, std::size_t len, const std::string& v) {
    std::string t = v.substr(0, len);
    t.resize(len, ' ');
    std::memcpy(&h[off], t.data(), len);
  };
  const auto i16 = [&](std::size_t off, int v) {
    const std::int16_t x = static_cast<std::int16_t>(v);
    std::memcpy(&h[off], &x, 2);
  };
  const auto i32 = [&](std::size_t off, std::int32_t v) { std::memcpy(&h[off], &v, 4); };
  const auto f32 = [&](std::size_t off, float v) { std::memcpy(&h[off], &v, 4); };
  str(0, 12, s.compressed ? "DSCOMPRESSED" : "DIGITAL SURF");
  i16(12, 0), i16(14, s.objects), i16(16, 1), i16(18, s.type);
  str(20, 30, "object"), str(50, 30, "operator");
  i16(86, s.special), i16(88, 1), i16(98, s.bits);
  i32(100, s.zmin), i32(104, *std::max_element(s.points.begin(), s.points.end()));
  i32(108, s.nx), i32(112, s.ny), i32(116, s.nx * s.ny);
  f32(120, s.dx), f32(124, s.dy), f32(128, s.dz);
  str(132, 16, "X"), str(148, 16, "Y"), str(164, 16, "Z");
  str(180, 16, s.xstep), str(196, 16, s.xstep), str(212, 16, s.zstep);
  str(228, 16, s.xlen), str(244, 16, s.xlen), str(260, 16, s.zlen);
  f32(276, s.rx), f32(280, s.ry), f32(284, s.rz);
  i16(290, s.inversion);
  f32(466, s.xoff), f32(470, s.yoff), f32(474, s.zoff);
  std::string raw;
  for (std::int32_t v : s.points) {
    if (s.bits == 16) {
      const std::int16_t x = static_cast<std::int16_t>(v);
      raw.append(reinterpret_cast<const char*>(&x), 2);
    } else {
      raw.append(reinterpret_cast<const char*>(&v), 4);
    }
  }
  if (!s.compressed) return h + raw;
  // RosettaSciIO's layout: a stream count, (raw size, zipped size) per stream, the zlib streams. Two streams here.
  std::string out = h;
  const std::size_t half = raw.size() / 2;
  const std::string parts[2] = {raw.substr(0, half), raw.substr(half)};
  std::string zipped[2];
  for (int k = 0; k < 2; ++k) {
    uLongf len = compressBound(parts[k].size());
    zipped[k].resize(len);
    compress(reinterpret_cast<Bytef*>(zipped[k].data()), &len, reinterpret_cast<const Bytef*>(parts[k].data()),
             parts[k].size());
    zipped[k].resize(len);
  }
  const auto u32 = [&](std::uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
  u32(2);
  for (int k = 0; k < 2; ++k)
    u32(static_cast<std::uint32_t>(parts[k].size())), u32(static_cast<std::uint32_t>(zipped[k].size()));
  for (int k = 0; k < 2; ++k) out += zipped[k];
  return out;
}

SurSpec base_spec() {
  SurSpec s;
  for (int k = 0; k < 12; ++k) s.points.push_back(10 * k + 5);
  return s;
}

double mean_of(const core::HeightGrid& g) {
  double s = 0;
  int n = 0;
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k)
    if (std::isfinite(g.z_mm.data()[k])) s += g.z_mm.data()[k], ++n;
  return s / n;
}

// vmsim and Gwyddion on one file: grid size and spacing; heights point by point (about their means when
// `about_mean`: Gwyddion inverts z about the mean where vmsim negates it).
void expect_like_gwyddion(const fs::path& p, const core::HeightGrid& g, bool about_mean = false) {
  if (!vmsim_test::gwyddion_available()) {
    std::printf("[  note    ] Gwyddion is not installed: %s not compared with it\n", p.filename().string().c_str());
    return;
  }
  std::string why;
  const auto gw = vmsim_test::gwyddion_read(p, scan_tmp("gwy"), &why);
  ASSERT_TRUE(gw) << why;
  ASSERT_EQ(gw->xres, g.nx());
  ASSERT_EQ(gw->yres, g.ny());
  EXPECT_NEAR(gw->xreal / gw->xres * 1e3, g.dx_mm, 1e-9 * g.dx_mm) << p;
  EXPECT_NEAR(gw->yreal / gw->yres * 1e3, g.dy_mm, 1e-9 * g.dy_mm) << p;
  double gm = 0;
  int n = 0;
  for (std::size_t k = 0; k < gw->data.size(); ++k)
    if (std::isfinite(g.z_mm.data()[k])) gm += gw->data[k], ++n;
  gm /= n;
  const double vm = mean_of(g);
  for (std::size_t k = 0; k < gw->data.size(); ++k) {
    const double z = g.z_mm.data()[k];
    if (!std::isfinite(z)) continue;
    const double a = about_mean ? z - vm : z, b = about_mean ? (gw->data[k] - gm) * 1e3 : gw->data[k] * 1e3;
    EXPECT_NEAR(a, b, 1e-9 * std::max(1.0, std::abs(b))) << p << " point " << k;
  }
}

}  // namespace

// ---- .sur ----

TEST(SurFields, StepUnitNotLengthUnitAndRatio) {
  // sur-3.sur's layout: step unit nm, length unit um, ratio 1000. The spacing is 0.5 nm, not 0.5 um or 500 um.
  SurSpec s = base_spec();
  s.xstep = "nm", s.xlen = "\xb5m", s.rx = s.ry = 1000;
  const fs::path p = scan_tmp("ratio.sur");
  write_bytes(p, sur_object(s));
  const auto d = metrology::read_sur_data(p);
  EXPECT_DOUBLE_EQ(d.grid.dx_mm, 0.5e-6);
  EXPECT_DOUBLE_EQ(d.grid.dy_mm, 0.25e-6);
  EXPECT_TRUE(d.note.empty()) << d.note;  // the ratio agrees with the units
  expect_like_gwyddion(p, d.grid);
  // A ratio that disagrees with the units is said, and the step unit still rules.
  s.rx = 3;
  write_bytes(p, sur_object(s));
  const auto e = metrology::read_sur_data(p);
  EXPECT_DOUBLE_EQ(e.grid.dx_mm, 0.5e-6);
  EXPECT_NE(e.note.find("ratio"), std::string::npos) << e.note;
}

TEST(SurFields, HeightsArePointTimesZSpacingPlusOffsetInTheZStepUnit) {
  SurSpec s = base_spec();
  s.zstep = "nm", s.zlen = "um", s.rz = 1000, s.zoff = 2.0f, s.zmin = 100;  // Zmin is not subtracted
  const fs::path p = scan_tmp("z.sur");
  write_bytes(p, sur_object(s));
  const auto d = metrology::read_sur_data(p);
  // Z spacing and offset are float32 in the header: the expected heights use the same floats.
  for (int k = 0; k < 12; ++k)
    EXPECT_NEAR(d.grid.z_mm.data()[k], ((10 * k + 5) * static_cast<double>(1e-3f) + 2.0) * 1e-6, 1e-18) << k;
  expect_like_gwyddion(p, d.grid);
}

TEST(SurFields, Int16IsSigned) {
  SurSpec s = base_spec();
  s.bits = 16;
  s.points = {-300, -2, -1, 0, 1, 2, 3, 4, 5, 6, 7, 32000};
  s.zmin = -300;
  const fs::path p = scan_tmp("i16.sur");
  write_bytes(p, sur_object(s));
  const auto d = metrology::read_sur_data(p);
  constexpr double dz = static_cast<double>(1e-3f) * 1e-3;  // float32 Z spacing in um, in mm
  EXPECT_DOUBLE_EQ(d.grid.z_mm(0, 0), -300 * dz);
  EXPECT_DOUBLE_EQ(d.grid.z_mm(2, 3), 32000 * dz);
  expect_like_gwyddion(p, d.grid);
}

TEST(SurFields, NonMeasuredOnlyWhereTheHeaderDeclaresThem) {
  SurSpec s = base_spec();
  s.points = {10, 8, 12, 13, 14, 15, 16, 17, 18, 19, 20, 8};
  s.zmin = 10;  // 8 = Zmin - 2
  s.special = 1;
  const fs::path p = scan_tmp("special.sur");
  write_bytes(p, sur_object(s));
  auto d = metrology::read_sur_data(p);
  EXPECT_TRUE(std::isnan(d.grid.z_mm(0, 1)));
  EXPECT_TRUE(std::isnan(d.grid.z_mm(2, 3)));
  constexpr double dz = static_cast<double>(1e-3f) * 1e-3;
  EXPECT_DOUBLE_EQ(d.grid.z_mm(0, 0), 10 * dz);
  s.special =
      0;  // the same values, no flag: every point is a height (SurfaceTopography's test_sur_special_points_flag)
  write_bytes(p, sur_object(s));
  d = metrology::read_sur_data(p);
  EXPECT_DOUBLE_EQ(d.grid.z_mm(0, 1), 8 * dz);
  expect_like_gwyddion(p, d.grid);
}

TEST(SurFields, InversionNegatesAndMirrors) {
  for (int inv : {1, 2, 3}) {
    SurSpec s = base_spec();
    s.inversion = inv;
    const fs::path p = scan_tmp("inv" + std::to_string(inv) + ".sur");
    write_bytes(p, sur_object(s));
    const auto d = metrology::read_sur_data(p);
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 4; ++i) {
        const int si = inv == 2 ? 3 - i : i, sj = inv == 3 ? 2 - j : j;  // 2: left-right, 3: upside down
        EXPECT_DOUBLE_EQ(d.grid.z_mm(j, i), -(10 * (4 * sj + si) + 5) * static_cast<double>(1e-3f) * 1e-3)
            << inv << " " << j << " " << i;
      }
    expect_like_gwyddion(p, d.grid, true);  // Gwyddion inverts about the mean: compare the shapes
  }
}

TEST(SurFields, CompressedReadsAsUncompressed) {
  // Gwyddion 2.62 does not read DSCOMPRESSED files; the reference is the same object written uncompressed.
  SurSpec s = base_spec();
  s.nx = 40, s.ny = 30;
  s.points.clear();
  for (int k = 0; k < 1200; ++k) s.points.push_back((k * 7919) % 100003 - 50000);
  s.zmin = -50000;
  const fs::path a = scan_tmp("plain.sur"), b = scan_tmp("zipped.sur");
  write_bytes(a, sur_object(s));
  s.compressed = true;
  write_bytes(b, sur_object(s));
  const auto da = metrology::read_sur_data(a), db = metrology::read_sur_data(b);
  EXPECT_TRUE((da.grid.z_mm == db.grid.z_mm).all());
  EXPECT_EQ(da.grid.dx_mm, db.grid.dx_mm);
  expect_like_gwyddion(a, da.grid);
}

TEST(SurFields, MultiObjectFileReadsTheFirstAndSaysSo) {
  SurSpec s = base_spec();
  s.objects = 2;
  s.type = 5;  // a series of surfaces: the first header carries the series type
  std::string bytes = sur_object(s);
  SurSpec t = base_spec();
  t.objects = 2;
  for (auto& v : t.points) v += 1000;
  bytes += sur_object(t);
  const fs::path p = scan_tmp("multi.sur");
  write_bytes(p, bytes);
  const auto d = metrology::read_surface_file(p);
  EXPECT_DOUBLE_EQ(d.grid.z_mm(0, 0), 5 * static_cast<double>(1e-3f) * 1e-3);  // the first object's, not 1005
  EXPECT_NE(d.note.find("2 objects"), std::string::npos) << d.note;
}

TEST(SurFields, ProfileObjectIsAProfile) {
  SurSpec s = base_spec();
  s.type = 1, s.nx = 12, s.ny = 1;
  const fs::path p = scan_tmp("profile.sur");
  write_bytes(p, sur_object(s));
  const auto f = metrology::read_surface_file(p);
  ASSERT_TRUE(f.profile);
  EXPECT_EQ(f.profile->size(), 12);
  EXPECT_DOUBLE_EQ(f.profile->dx_mm, 0.5e-3);
  EXPECT_DOUBLE_EQ(f.profile->z_mm[11], 115 * static_cast<double>(1e-3f) * 1e-3);
}

TEST(SurFields, WriterAndReaderAgreeOnTheNewRules) {
  core::HeightGrid g;
  g.x0_mm = 0.5, g.y0_mm = -0.25, g.dx_mm = 0.004, g.dy_mm = 0.002;
  g.z_mm.resize(7, 9);
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k)
    g.z_mm.data()[k] = 0.01 * std::sin(0.37 * static_cast<double>(k)) - 3.0;
  g.z_mm(3, 4) = NAN;
  const fs::path p = scan_tmp("vmsim.sur");
  metrology::write_sur(p, g);
  const auto r = metrology::read_sur_data(p);
  EXPECT_TRUE(std::isnan(r.grid.z_mm(3, 4)));
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) {
    if (std::isfinite(g.z_mm.data()[k])) {
      EXPECT_NEAR(r.grid.z_mm.data()[k], g.z_mm.data()[k], 1e-6);
    }
  }
  EXPECT_FLOAT_EQ(static_cast<float>(r.grid.dx_mm), 0.004f);
}

// ---- BCR-STM, ASCII header ----

namespace {

std::string bcr_file(const std::string& kind, int nx, int ny, const std::vector<double>& values,
                     const std::vector<std::string>& keys, bool big_endian = false) {
  std::string h = "fileformat = " + kind + "\nheadersize = 2048\nxpixels = " + std::to_string(nx) +
                  "\nypixels = " + std::to_string(ny) + "\n";
  for (const auto& k : keys) h += k + "\n";
  h += std::string("intelmode = ") + (big_endian ? "0" : "1") + "\n";
  h.resize(2048, ' ');
  for (double v : values) {
    char b[4];
    std::size_t n = 2;
    if (kind == "bcrf") {
      const float f = static_cast<float>(v);
      std::memcpy(b, &f, 4), n = 4;
    } else {
      const std::int16_t s = static_cast<std::int16_t>(v);
      std::memcpy(b, &s, 2);
    }
    if (big_endian) std::reverse(b, b + n);
    h.append(b, n);
  }
  return h;
}

}  // namespace

TEST(BcrAscii, Int16WithScaleUnitsOffsetsAndVoidPoints) {
  std::vector<double> v;
  for (int k = 1; k <= 11; ++k) v.push_back(k);
  v.push_back(32767);  // the bcrstm void value
  const fs::path p = scan_tmp("stm.bcr");
  write_bytes(p, bcr_file("bcrstm", 4, 3, v,
                          {"xlength = 400", "ylength = 600", "xunit = nm", "yunit = nm", "zunit = um", "bit2nm = 2",
                           "voidpixels = 1", "xoffset = 1000", "yoffset = 2000"}));
  const auto f = metrology::read_surface_file(p);
  EXPECT_EQ(f.format, "bcr");
  EXPECT_DOUBLE_EQ(f.grid.dx_mm, 1e-4);
  EXPECT_DOUBLE_EQ(f.grid.dy_mm, 2e-4);
  EXPECT_DOUBLE_EQ(f.grid.x0_mm, 1e-3);
  EXPECT_DOUBLE_EQ(f.grid.y0_mm, 2e-3);
  EXPECT_DOUBLE_EQ(f.grid.z_mm(0, 0), 2e-3);  // 1 x bit2nm 2, in um
  EXPECT_TRUE(std::isnan(f.grid.z_mm(2, 3)));
  expect_like_gwyddion(p, f.grid);
  // Without voidpixels, 32767 is a height (Gwyddion 2.62 masks it anyway; the SPIP description counts void pixels).
  write_bytes(p, bcr_file("bcrstm", 4, 3, v, {"xlength = 400", "ylength = 600"}));
  EXPECT_DOUBLE_EQ(metrology::read_surface(p).z_mm(2, 3), 32767e-6);
}

TEST(BcrAscii, Float32AndBigEndian) {
  std::vector<double> v;
  for (int k = 1; k <= 11; ++k) v.push_back(0.5 * k);
  v.push_back(3.402823e38);
  const fs::path p = scan_tmp("f.bcrf");
  write_bytes(p, bcr_file("bcrf", 4, 3, v,
                          {"xlength = 4", "ylength = 6", "xunit = um", "yunit = um", "zunit = nm", "voidpixels = 1"}));
  const auto g = metrology::read_surface(p);
  EXPECT_DOUBLE_EQ(g.dx_mm, 1e-3);
  EXPECT_DOUBLE_EQ(g.z_mm(0, 1), 1e-6);
  EXPECT_TRUE(std::isnan(g.z_mm(2, 3)));
  expect_like_gwyddion(p, g);
  const fs::path q = scan_tmp("big.bcr");
  std::vector<double> w = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  write_bytes(q, bcr_file("bcrstm", 4, 3, w, {"xlength = 400", "ylength = 600", "bit2nm = 1"}, true));
  const auto b = metrology::read_surface(q);
  for (int k = 0; k < 12; ++k) EXPECT_DOUBLE_EQ(b.z_mm.data()[k], (k + 1) * 1e-6);
}

TEST(BcrAscii, ShortFileIsAClearError) {
  const fs::path p = scan_tmp("short.bcr");
  std::string b = bcr_file("bcrstm", 4, 3, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}, {"xlength = 400", "ylength = 600"});
  b.resize(b.size() - 4);
  write_bytes(p, b);
  try {
    metrology::read_surface(p);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(p.string(), 0), 0u) << e.what();
  }
}

// ---- X3P laid out by other tools ----

namespace {

// A zip of the given (name, bytes) entries, stored.
void write_zip(const fs::path& p, const std::vector<std::pair<std::string, std::string>>& entries) {
  int err = 0;
  fs::remove(p);
  zip_t* z = zip_open(p.string().c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  ASSERT_TRUE(z);
  for (const auto& [name, data] : entries) {
    zip_source_t* s = zip_source_buffer(z, data.data(), data.size(), 0);
    ASSERT_GE(zip_file_add(z, name.c_str(), s, ZIP_FL_ENC_UTF_8), 0);
  }
  ASSERT_EQ(zip_close(z), 0);
}

std::vector<std::pair<std::string, std::string>> zip_entries(const fs::path& p) {
  std::vector<std::pair<std::string, std::string>> out;
  int err = 0;
  zip_t* z = zip_open(p.string().c_str(), ZIP_RDONLY, &err);
  for (zip_int64_t i = 0; i < zip_get_num_entries(z, 0); ++i) {
    zip_stat_t st;
    zip_stat_index(z, static_cast<zip_uint64_t>(i), 0, &st);
    std::string data(st.size, '\0');
    zip_file_t* f = zip_fopen_index(z, static_cast<zip_uint64_t>(i), 0);
    if (st.size) zip_fread(f, data.data(), st.size);
    zip_fclose(f);
    out.emplace_back(st.name, data);
  }
  zip_discard(z);
  return out;
}

core::HeightGrid small_grid() {
  core::HeightGrid g;
  g.dx_mm = 0.002, g.dy_mm = 0.003;
  g.z_mm.resize(5, 6);
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) g.z_mm.data()[k] = 0.001 * static_cast<double>(k);
  g.z_mm(1, 1) = NAN;
  return g;
}

}  // namespace

TEST(X3pOtherTools, MainXmlUnderAFolderNextToMacJunk) {
  const core::HeightGrid g = small_grid();
  const fs::path std_file = scan_tmp("std.x3p");
  metrology::write_x3p(std_file, g);
  std::vector<std::pair<std::string, std::string>> e = {{"__MACOSX/._scan", "junk"}, {"scan/.DS_Store", "junk"}};
  for (const auto& [n, d] : zip_entries(std_file))
    if (n.back() != '/') e.emplace_back("scan/" + n, d);
  const fs::path p = scan_tmp("folder.x3p");
  write_zip(p, e);
  const auto f = metrology::read_surface_file(p);
  EXPECT_TRUE(((f.grid.z_mm == g.z_mm) || (f.grid.z_mm.isNaN() && g.z_mm.isNaN())).all());
  EXPECT_NE(f.note.find("\"scan/\""), std::string::npos) << f.note;
  EXPECT_NE(f.note.find("__MACOSX/._scan"), std::string::npos) << f.note;
  // The same file at the root of the zip: no note.
  EXPECT_TRUE(metrology::read_surface_file(std_file).note.empty());
}

TEST(X3pOtherTools, TwoMainXmlAreAnErrorNamingBoth) {
  const fs::path std_file = scan_tmp("std2.x3p");
  metrology::write_x3p(std_file, small_grid());
  std::vector<std::pair<std::string, std::string>> e;
  for (const auto& [n, d] : zip_entries(std_file))
    if (n.back() != '/') e.emplace_back("a/" + n, d), e.emplace_back("b/" + n, d);
  const fs::path p = scan_tmp("two.x3p");
  write_zip(p, e);
  try {
    metrology::read_surface_file(p);
    FAIL();
  } catch (const core::Error& err) {
    const std::string m = err.what();
    EXPECT_NE(m.find("a/main.xml"), std::string::npos) << m;
    EXPECT_NE(m.find("b/main.xml"), std::string::npos) << m;
  }
}

// ---- gzip and matrix headers ----

TEST(GzipText, MatrixReadsAsTheUncompressedFile) {
  const std::string text =
      "h=2 w=3\npixel size=2 um\ndata unit=rad\nheight conversion factor (-> nm)=10\n1 2 3\n4 nan 6\n";
  const fs::path plain = scan_tmp("m.txt"), zipped = scan_tmp("m.txt.gz");
  write_bytes(plain, text);
  gzFile z = gzopen(zipped.string().c_str(), "wb");
  gzwrite(z, text.data(), static_cast<unsigned>(text.size()));
  gzclose(z);
  const auto a = metrology::read_surface_file(plain), b = metrology::read_surface_file(zipped);
  EXPECT_EQ(a.format, "matrix");
  EXPECT_EQ(b.format, "matrix+gzip");
  ASSERT_EQ(b.grid.nx(), 3);
  ASSERT_EQ(b.grid.ny(), 2);
  EXPECT_DOUBLE_EQ(b.grid.dx_mm, 2e-3);
  EXPECT_DOUBLE_EQ(b.grid.dy_mm, 2e-3);
  EXPECT_DOUBLE_EQ(b.grid.z_mm(1, 2), 6 * 10 * 1e-6);
  EXPECT_TRUE(std::isnan(b.grid.z_mm(1, 1)));
  EXPECT_TRUE((a.grid.z_mm.isNaN() == b.grid.z_mm.isNaN()).all());
  // A truncated gzip file is an error naming it.
  std::ifstream in(zipped, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  write_bytes(zipped, bytes.substr(0, bytes.size() / 2));
  try {
    metrology::read_surface_file(zipped);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(zipped.string(), 0), 0u) << e.what();
  }
}

TEST(MatrixHeader, CountsAndUnitsAreChecked) {
  const fs::path p = scan_tmp("bad.txt");
  write_bytes(p, "h=3 w=3\npixel size=2 um\n1 2 3\n4 5 6\n");
  EXPECT_THROW(metrology::read_surface(p), core::Error);  // h=3 rows declared, 2 present
  write_bytes(p, "pixel size=2 um\ndata unit=rad\n1 2 3\n4 5 6\n");
  try {
    metrology::read_surface(p);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("rad"), std::string::npos) << e.what();  // phase without a conversion factor
  }
}

// ---- Dektak-style CSV ----

namespace {

std::string dektak_text(const std::vector<double>& x_um, const std::vector<double>& z_um) {
  // The layout of a Dektak export: CR CR LF after section titles, latin-1 micro sign, trailing empty columns.
  std::string t =
      "Scan Parameters\r\r\nStylus,Radius: 2.5 \xb5m\r\nLength,10.0 um\r\n\r\r\nScan Data\r\r\nLateral um,Raw "
      "Micrometer,\r\n";
  char buf[96];
  for (std::size_t i = 0; i < x_um.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%.1f,%.5f,,\r\n", x_um[i], z_um[i]);
    t += buf;
  }
  return t + "\r\r\n";
}

}  // namespace

TEST(DektakCsv, RoundedLateralValuesAreTheUniformGrid) {
  std::vector<double> x, z;
  for (int i = 0; i < 640; ++i) x.push_back(0.15625 * i), z.push_back(0.002 * std::sin(0.05 * i));
  const fs::path p = scan_tmp("dektak.csv");
  write_bytes(p, dektak_text(x, z));
  const auto f = metrology::read_surface_file(p);
  EXPECT_EQ(f.format, "dektak");
  ASSERT_TRUE(f.profile);
  EXPECT_TRUE(f.note.empty()) << f.note;
  EXPECT_NEAR(f.profile->dx_mm, 0.15625e-3, 1e-4 * 0.15625e-3);
  EXPECT_NEAR(f.profile->x0_mm, 0.0, 0.05e-3);
  EXPECT_NEAR(f.profile->z_mm[100], 0.002 * std::sin(5.0) * 1e-3, 5e-9);  // printed to 1e-5 um
}

TEST(DektakCsv, IrregularLateralValuesAreResampledAndSaid) {
  std::vector<double> x, z;
  for (int i = 0; i < 200; ++i) x.push_back(i + (i % 2 ? 0.4 : 0.0)), z.push_back(0.01 * i);
  const fs::path p = scan_tmp("irregular.csv");
  write_bytes(p, dektak_text(x, z));
  const auto f = metrology::read_surface_file(p);
  ASSERT_TRUE(f.profile);
  EXPECT_NE(f.note.find("resampled"), std::string::npos) << f.note;
  EXPECT_NEAR(f.profile->dx_mm, 1e-3 * 199.4 / 199, 1e-12);
  // Linear heights stay linear under linear resampling: z = 0.01 um per sample index, x alternating.
  EXPECT_NEAR(f.profile->z_mm[0], 0.0, 1e-12);
  EXPECT_NEAR(f.profile->z_mm[199], 1.99e-3, 1e-12);
}

TEST(DektakCsv, DecreasingLateralIsAnErrorWithTheLine) {
  const fs::path p = scan_tmp("bad.csv");
  write_bytes(p, dektak_text({0.0, 0.2, 0.1}, {1, 2, 3}));
  try {
    metrology::read_surface_file(p);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find(p.string() + ":9:"), std::string::npos) << e.what();
  }
}
