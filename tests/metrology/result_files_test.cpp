// The height grids' result files as `vmsim run` writes them (surface.csv, surface.npy, surface.x3p; issue 21 made
// their writers cheaper), on a 1 x 1 grid, a grid with NaN holes and a large one (every double's bit patterns):
//  - the CSV's bytes against the file as written before issue 21 (fmt's "{}" per number, built here), read back bit
//    for bit by vmsim's reader;
//  - an independent reading in Python (its own float parser, the NPY format as NumPy's documentation specifies it,
//    the zip and MD5 of the X3P through Python's zipfile and hashlib, the heights in metres as IEEE division gives
//    them): the CSV, the NPY and the X3P hold the same doubles, bit for bit; skipped without python3;
//  - Info-ZIP's `unzip -t` tests every X3P entry's CRC (skipped without unzip).
#include "metrology/grid_io.hpp"
#include "metrology/x3p.hpp"

#include "tests/test_paths.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>

namespace vmsim::metrology {
namespace {

namespace fs = std::filesystem;

// Heights of a scalloped part, NaN holes (every 13th node and a whole row), -0.0, and in `random_bits` grids any
// finite double (subnormals, huge values) at a quarter of the nodes.
core::HeightGrid result_files_grid(int nx, int ny, bool random_bits) {
  core::HeightGrid g;
  g.x0_mm = 0.05, g.y0_mm = -1.0 / 3.0, g.dx_mm = 0.1, g.dy_mm = 0.025;
  g.z_mm.resize(ny, nx);
  std::mt19937_64 rng(2132);
  std::uniform_int_distribution<std::uint64_t> bits;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      double z = -3.0 + std::sin(0.3 * i) * std::cos(0.17 * j) + 0.004 * std::cos(j / 0.4);
      if (random_bits && (i + j) % 4 == 1) {
        z = std::bit_cast<double>(bits(rng));
        if (!std::isfinite(z)) z = 1e300;
      }
      if ((j * nx + i) % 13 == 7 || (ny > 3 && j == ny / 2)) z = std::numeric_limits<double>::quiet_NaN();
      if ((j * nx + i) % 29 == 3) z = -0.0;
      g.z_mm(j, i) = z;
    }
  return g;
}

// surface.csv as vmsim wrote it before issue 21: the header, then each row's numbers through fmt's "{}", "nan" where
// invalid.
std::string result_files_csv_reference(const core::HeightGrid& g) {
  std::string s = "# vmsim height grid, mm; row j is y = y0 + j dy, column i is x = x0 + i dx\n";
  s += fmt::format("# x0_mm={} y0_mm={} dx_mm={} dy_mm={} nx={} ny={}\n", g.x0_mm, g.y0_mm, g.dx_mm, g.dy_mm, g.nx(),
                   g.ny());
  for (Eigen::Index j = 0; j < g.ny(); ++j) {
    for (Eigen::Index i = 0; i < g.nx(); ++i) {
      const double z = g.z_mm(j, i);
      s += (i ? "," : "") + (std::isfinite(z) ? fmt::format("{}", z) : std::string("nan"));
    }
    s += '\n';
  }
  return s;
}

std::string result_files_bytes(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void result_files_expect_same_bits(const core::HeightGrid& a, const core::HeightGrid& b) {
  ASSERT_EQ(a.nx(), b.nx());
  ASSERT_EQ(a.ny(), b.ny());
  EXPECT_EQ(std::bit_cast<std::uint64_t>(a.dx_mm), std::bit_cast<std::uint64_t>(b.dx_mm));
  EXPECT_EQ(std::bit_cast<std::uint64_t>(a.y0_mm), std::bit_cast<std::uint64_t>(b.y0_mm));
  long differ = 0;
  for (Eigen::Index k = 0; k < a.z_mm.size(); ++k) {
    const double x = a.z_mm.data()[k], y = b.z_mm.data()[k];
    differ += std::isnan(x) ? !std::isnan(y) : std::bit_cast<std::uint64_t>(x) != std::bit_cast<std::uint64_t>(y);
  }
  EXPECT_EQ(differ, 0) << "heights that differ";
}

// Reads surface.csv, surface.npy and surface.x3p of one grid without vmsim and checks that they hold the same doubles.
constexpr const char* kResultFilesPython = R"PY(
import ast, hashlib, re, struct, sys, zipfile
d = sys.argv[1]
# NPY (NumPy's format documentation): magic, version 1.0, little-endian header length, a dict literal, C-order data.
b = open(d + '/surface.npy', 'rb').read()
assert b[:8] == b'\x93NUMPY\x01\x00', 'npy magic'
hl = struct.unpack('<H', b[8:10])[0]
h = ast.literal_eval(b[10:10 + hl].decode('latin1'))
assert h['descr'] == '<f8' and h['fortran_order'] is False, h
ny, nx = h['shape']
assert (10 + hl) % 64 == 0, 'npy data not 64-byte aligned'
npy = struct.unpack('<%dd' % (nx * ny), b[10 + hl:])
# CSV: '#' lines, then ny rows of nx numbers parsed by Python's float().
rows = [l for l in open(d + '/surface.csv').read().split('\n') if l and not l.startswith('#')]
assert len(rows) == ny, (len(rows), ny)
csv = [float(c) for r in rows for c in r.split(',')]
assert all(len(r.split(',')) == nx for r in rows)
bits = lambda v: struct.pack('<d', v)
nan = lambda v: v != v
bad = sum(1 for a, c in zip(npy, csv) if (nan(a) != nan(c)) or (not nan(a) and bits(a) != bits(c)))
assert bad == 0, '%d CSV values differ from the NPY' % bad
# X3P: the zip's CRCs, main.xml's MD5 in md5checksum.hex, data.bin's MD5 in main.xml, heights in metres.
z = zipfile.ZipFile(d + '/surface.x3p')
assert z.testzip() is None, 'bad CRC'
xml = z.read('main.xml')
assert z.read('md5checksum.hex').decode().split()[0] == hashlib.md5(xml).hexdigest(), 'main.xml MD5'
data = z.read('bindata/data.bin')
m = re.search(rb'<MD5ChecksumPointData>([0-9a-f]+)<', xml)
assert m and m.group(1).decode() == hashlib.md5(data).hexdigest(), 'data.bin MD5'
assert z.getinfo('bindata/data.bin').compress_type == zipfile.ZIP_STORED
assert int(re.search(rb'<SizeX>(\d+)<', xml).group(1)) == nx and int(re.search(rb'<SizeY>(\d+)<', xml).group(1)) == ny
metres = struct.unpack('<%dd' % (nx * ny), data)
invalid = sum(1 for a in npy if nan(a))
if invalid:
    valid = z.read('bindata/valid.bin')
    for k, a in enumerate(npy):
        assert ((valid[k // 8] >> (k % 8)) & 1) == (0 if nan(a) else 1), 'valid.bin bit %d' % k
else:
    assert 'bindata/valid.bin' not in z.namelist()
bad = sum(1 for a, mm in zip(npy, metres) if (nan(a) != nan(mm)) or (not nan(a) and bits(a / 1000.0) != bits(mm)))
assert bad == 0, '%d data.bin values are not the heights / 1000' % bad
print('ok', nx, ny, invalid)
)PY";

void result_files_write_all(const fs::path& dir, const core::HeightGrid& g) {
  write_height_csv(dir / "surface.csv", g);
  write_height_npy(dir / "surface.npy", g);
  X3pWriteOptions o;
  o.date = "2026-11-27T10:00:00+00:00";
  write_x3p(dir / "surface.x3p", g, o);
}

void result_files_check(const std::string& name, const core::HeightGrid& g) {
  SCOPED_TRACE(name);
  const fs::path dir = test::test_scratch_dir("metrology") / name;
  fs::create_directories(dir);
  result_files_write_all(dir, g);
  EXPECT_EQ(result_files_bytes(dir / "surface.csv"), result_files_csv_reference(g));
  {
    SCOPED_TRACE("surface.csv through read_height_csv");
    result_files_expect_same_bits(g, read_height_csv(dir / "surface.csv"));
  }
  // X3P keeps metres and a correction of up to 4 ulps per point: exact for heights whose metre value is a normal double
  // (|z| above ~2.2e-305 mm), the bits of smaller ones are lost in z / 1000 (a limit of the format's metres, not of
  // the writer).
  SCOPED_TRACE("surface.x3p through read_x3p");
  core::HeightGrid back = read_x3p(dir / "surface.x3p").grid, normal = g;
  for (Eigen::Index k = 0; k < normal.z_mm.size(); ++k)
    if (const double z = g.z_mm.data()[k]; z != 0 && std::abs(z) < 1e3 * std::numeric_limits<double>::min())
      normal.z_mm.data()[k] = back.z_mm.data()[k];
  result_files_expect_same_bits(normal, back);
  if (std::system("command -v python3 > /dev/null 2>&1") == 0) {
    const fs::path script = dir / "independent.py";
    std::ofstream(script) << kResultFilesPython;
    const std::string cmd =
        "python3 '" + script.string() + "' '" + dir.string() + "' > '" + (dir / "py.txt").string() + "' 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << result_files_bytes(dir / "py.txt");
  } else {
    std::printf("python3 is not installed: the independent reading is skipped\n");
  }
  if (std::system("command -v unzip > /dev/null 2>&1") == 0) {
    const std::string cmd = "unzip -tq '" + (dir / "surface.x3p").string() + "' > /dev/null";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << "unzip -t found a bad entry";
  }
}

TEST(ResultFiles, OneByOneGrid) {
  core::HeightGrid g;
  g.z_mm.resize(1, 1);
  g.z_mm(0, 0) = -2.404;
  result_files_check("one", g);
}

TEST(ResultFiles, GridWithNaNHoles) { result_files_check("holes", result_files_grid(57, 31, false)); }

TEST(ResultFiles, LargeGridOfAnyDoubles) { result_files_check("large", result_files_grid(640, 480, true)); }

}  // namespace
}  // namespace vmsim::metrology
