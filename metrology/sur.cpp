#include "metrology/sur.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "metrology/units.hpp"

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace vmsim::metrology {

namespace {

constexpr std::size_t kHeader = 512;
constexpr std::uint64_t kMaxPoints = std::uint64_t{1} << 28;

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what) {
  throw core::Error(file.string() + ": " + what);
}

template <typename T>
T at(const std::string& b, std::size_t off) {  // little-endian, as the format (and x86-64)
  T v;
  std::memcpy(&v, b.data() + off, sizeof v);
  return v;
}

std::string field(const std::string& b, std::size_t off, std::size_t len) {
  std::string s(b.data() + off, len);
  const auto z = s.find('\0');
  if (z != std::string::npos) s.erase(z);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.pop_back();
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.erase(0, 1);
  return s;
}

// Header offsets (bytes). Names as in the MountainsMap description.
enum : std::size_t {
  kSignature = 0, kFormat = 12, kObjects = 14, kVersion = 16, kType = 18, kObjectName = 20, kOperator = 50,
  kPSize = 80, kAcquisition = 82, kRange = 84, kSpecialPoints = 86, kAbsolute = 88, kGaugeResolution = 90,
  kWSize = 94, kPointBits = 98, kZmin = 100, kZmax = 104, kPointsPerLine = 108, kLines = 112, kTotalPoints = 116,
  kXSpacing = 120, kYSpacing = 124, kZSpacing = 128, kXName = 132, kYName = 148, kZName = 164, kXStepUnit = 180,
  kYStepUnit = 196, kZStepUnit = 212, kXLengthUnit = 228, kYLengthUnit = 244, kZLengthUnit = 260, kXRatio = 276,
  kYRatio = 280, kZRatio = 284, kImprint = 288, kInverted = 290, kLevelled = 292, kObsolete = 294, kSeconds = 306,
  kMinutes = 308, kHours = 310, kDay = 312, kMonth = 314, kYear = 316, kDayOfWeek = 318, kDuration = 320,
  kCompressedSize = 324, kObsolete2 = 328, kCommentSize = 334, kPrivateSize = 336, kClientZone = 338,
  kXOffset = 466, kYOffset = 470, kZOffset = 474, kTSpacing = 478, kTOffset = 482, kTName = 486, kTStepUnit = 499
};

int unit_or_fail(const std::filesystem::path& file, const std::string& u, const char* what) {
  const auto p = length_unit_pow10(u);
  if (!p) fail(file, fmt::format("header {}: unknown length unit \"{}\" (m, mm, um, nm expected)", what, u));
  return *p;
}

}  // namespace

core::HeightGrid read_sur(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string b = std::move(ss).str();
  if (b.size() < kHeader) fail(file, fmt::format("{} bytes: shorter than the 512-byte .sur header", b.size()));
  const std::string sig = b.substr(0, 12);
  const bool compressed = sig == "DSCOMPRESSED";
  if (sig != "DIGITAL SURF" && !compressed)
    fail(file, "not a Digital Surf file: it starts neither with \"DIGITAL SURF\" nor \"DSCOMPRESSED\"");
  const int type = at<std::int16_t>(b, kType);
  if (type != 1 && type != 2)
    fail(file, fmt::format("header byte {}: object type {}; vmsim reads surfaces (2) and profiles (1)", kType, type));
  const int bits = at<std::int16_t>(b, kPointBits);
  if (bits != 16 && bits != 32) fail(file, fmt::format("header byte {}: {} bits per point, expected 16 or 32", kPointBits, bits));
  const std::int32_t nx = at<std::int32_t>(b, kPointsPerLine), ny = at<std::int32_t>(b, kLines);
  if (nx < 1 || ny < 1) fail(file, fmt::format("header: {} points per line, {} lines: both must be at least 1", nx, ny));
  if (static_cast<std::uint64_t>(nx) * static_cast<std::uint64_t>(ny) > kMaxPoints)
    fail(file, fmt::format("header: {} x {} points is more than vmsim accepts", nx, ny));
  const std::uint64_t n = static_cast<std::uint64_t>(nx) * static_cast<std::uint64_t>(ny);
  const std::uint32_t total = at<std::uint32_t>(b, kTotalPoints);
  if (total != n) fail(file, fmt::format("header byte {}: total points {}, but {} x {} = {}", kTotalPoints, total, nx, ny, n));
  const std::int32_t zmin = at<std::int32_t>(b, kZmin);
  const float dx = at<float>(b, kXSpacing), dy = at<float>(b, kYSpacing), dz = at<float>(b, kZSpacing);
  float rx = at<float>(b, kXRatio), ry = at<float>(b, kYRatio), rz = at<float>(b, kZRatio);
  // A ratio of 0 in older files means "no scaling".
  if (rx == 0) rx = 1;
  if (ry == 0) ry = 1;
  if (rz == 0) rz = 1;
  const int px = unit_or_fail(file, field(b, kXStepUnit, 16), "x step unit");
  const int py = unit_or_fail(file, field(b, kYStepUnit, 16), "y step unit");
  const int pz = unit_or_fail(file, field(b, kZStepUnit, 16), "z step unit");
  const double to_mm_x = std::pow(10.0, px + 3), to_mm_y = std::pow(10.0, py + 3), to_mm_z = std::pow(10.0, pz + 3);
  core::HeightGrid g;
  g.dx_mm = static_cast<double>(dx) * rx * to_mm_x;
  g.dy_mm = type == 1 ? g.dx_mm : static_cast<double>(dy) * ry * to_mm_y;
  if (!(g.dx_mm > 0) || !(g.dy_mm > 0) || !std::isfinite(g.dx_mm) || !std::isfinite(g.dy_mm))
    fail(file, fmt::format("header bytes {}-{}: x and y spacing must be positive", kXSpacing, kYSpacing + 3));
  if (!std::isfinite(dz) || dz == 0) fail(file, fmt::format("header byte {}: z spacing must be a non-zero number", kZSpacing));
  g.x0_mm = static_cast<double>(at<float>(b, kXOffset)) * to_mm_x;
  g.y0_mm = static_cast<double>(at<float>(b, kYOffset)) * to_mm_y;
  if (!std::isfinite(g.x0_mm) || !std::isfinite(g.y0_mm)) g.x0_mm = g.y0_mm = 0;
  const double zoff_mm = static_cast<double>(at<float>(b, kZOffset)) * to_mm_z;

  const std::size_t comment = static_cast<std::uint16_t>(at<std::int16_t>(b, kCommentSize));
  const std::size_t priv = static_cast<std::uint16_t>(at<std::int16_t>(b, kPrivateSize));
  const std::size_t start = kHeader + comment + priv;
  const std::size_t psize = static_cast<std::size_t>(bits / 8);
  const std::size_t need = static_cast<std::size_t>(n) * psize;
  std::string raw;
  if (!compressed) {
    if (b.size() < start + need)
      fail(file, fmt::format("{} bytes after the header and zones (from byte {}), {} x {} points of {} bits need {}",
                             b.size() < start ? 0 : b.size() - start, start, nx, ny, bits, need));
    raw.assign(b.data() + start, need);
  } else {
    // Compressed: a count of streams, then (raw size, zipped size) per stream, then the zlib streams.
    std::size_t p = start;
    const auto u32 = [&](const char* what) {
      if (p + 4 > b.size()) fail(file, fmt::format("byte {}: file ends inside the compressed data's {}", p, what));
      const std::uint32_t v = at<std::uint32_t>(b, p);
      p += 4;
      return v;
    };
    const std::uint32_t streams = u32("stream count");
    if (streams < 1 || streams > 64) fail(file, fmt::format("byte {}: {} compressed streams, expected 1 to 64", p - 4, streams));
    std::vector<std::uint32_t> rawlen(streams), ziplen(streams);
    std::uint64_t sum = 0;
    for (std::uint32_t s = 0; s < streams; ++s) rawlen[s] = u32("stream sizes"), ziplen[s] = u32("stream sizes"), sum += rawlen[s];
    if (sum != need) fail(file, fmt::format("compressed streams hold {} bytes, {} x {} points need {}", sum, nx, ny, need));
    std::uint64_t zipped = 0;
    for (std::uint32_t s = 0; s < streams; ++s) zipped += ziplen[s];
    // Deflate expands at most ~1032:1: streams that claim more are corrupt (and would make vmsim allocate for them).
    if (zipped > b.size() || need > 1032 * zipped + 1024)
      fail(file, fmt::format("compressed streams of {} bytes cannot hold the {} bytes they declare", zipped, need));
    raw.resize(need);
    std::size_t out = 0;
    for (std::uint32_t s = 0; s < streams; ++s) {
      if (p + ziplen[s] > b.size()) fail(file, fmt::format("byte {}: compressed stream {} runs past the end of the file", p, s + 1));
      uLongf len = rawlen[s];
      if (uncompress(reinterpret_cast<Bytef*>(raw.data() + out), &len, reinterpret_cast<const Bytef*>(b.data() + p), ziplen[s]) != Z_OK ||
          len != rawlen[s])
        fail(file, fmt::format("byte {}: compressed stream {} is corrupt", p, s + 1));
      p += ziplen[s];
      out += rawlen[s];
    }
  }
  const bool special = at<std::int16_t>(b, kSpecialPoints) == 1;
  const std::int64_t nonmeasured = static_cast<std::int64_t>(zmin) - 2;
  const double scale = static_cast<double>(dz) * rz * to_mm_z;
  g.z_mm.resize(ny, nx);
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::int64_t v = bits == 16 ? at<std::int16_t>(raw, i * 2) : at<std::int32_t>(raw, i * 4);
    const double z = static_cast<double>(v - zmin) * scale + zoff_mm;
    g.z_mm.data()[i] = (special && v == nonmeasured) || !std::isfinite(z) ? std::numeric_limits<double>::quiet_NaN() : z;
  }
  if (at<std::int16_t>(b, kInverted) == 1) g.z_mm = -g.z_mm;  // "inverted" surfaces store -z
  return g;
}

void write_sur(const std::filesystem::path& file, const core::HeightGrid& g) {
  const Eigen::Index nx = g.nx(), ny = g.ny();
  if (nx < 1 || ny < 1 || nx > INT32_MAX / std::max<Eigen::Index>(ny, 1)) fail(file, "cannot write an empty or huge grid as .sur");
  double lo = HUGE_VAL, hi = -HUGE_VAL;
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) {
    const double z = g.z_mm.data()[k];
    if (std::isfinite(z)) lo = std::min(lo, z), hi = std::max(hi, z);
  }
  const bool any = lo <= hi;
  if (!any) lo = hi = 0;
  const double range = hi - lo;
  constexpr double kSteps = 1073741824.0;  // 2^30 steps, as Gwyddion writes, well inside int32
  const float dz = static_cast<float>(range > 0 ? range / kSteps : 1e-9);
  const float zoff = static_cast<float>(lo);
  std::string h(kHeader, '\0');
  const auto put_str = [&](std::size_t off, std::size_t len, const std::string& s) {
    std::string v = s.substr(0, len);
    v.resize(len, ' ');
    std::memcpy(&h[off], v.data(), len);
  };
  const auto put16 = [&](std::size_t off, std::int16_t v) { std::memcpy(&h[off], &v, 2); };
  const auto put32 = [&](std::size_t off, std::int32_t v) { std::memcpy(&h[off], &v, 4); };
  const auto putf = [&](std::size_t off, float v) { std::memcpy(&h[off], &v, 4); };
  put_str(kSignature, 12, "DIGITAL SURF");
  put16(kFormat, 0);  // PC
  put16(kObjects, 1);
  put16(kVersion, 1);
  put16(kType, 2);    // surface
  put_str(kObjectName, 30, "vmsim");
  put_str(kOperator, 30, "vmsim");
  put16(kSpecialPoints, 1);  // there may be non-measured points (Zmin - 2)
  put16(kAbsolute, 1);
  put16(kPointBits, 32);
  put32(kZmin, 0);
  put32(kZmax, static_cast<std::int32_t>(kSteps));
  put32(kPointsPerLine, static_cast<std::int32_t>(nx));
  put32(kLines, static_cast<std::int32_t>(ny));
  put32(kTotalPoints, static_cast<std::int32_t>(nx * ny));
  putf(kXSpacing, static_cast<float>(g.dx_mm));
  putf(kYSpacing, static_cast<float>(g.dy_mm));
  putf(kZSpacing, dz);
  put_str(kXName, 16, "X"), put_str(kYName, 16, "Y"), put_str(kZName, 16, "Z");
  for (std::size_t off : {kXStepUnit, kYStepUnit, kZStepUnit, kXLengthUnit, kYLengthUnit, kZLengthUnit}) put_str(off, 16, "mm");
  putf(kXRatio, 1), putf(kYRatio, 1), putf(kZRatio, 1);
  putf(kXOffset, static_cast<float>(g.x0_mm));
  putf(kYOffset, static_cast<float>(g.y0_mm));
  putf(kZOffset, zoff);
  std::string data(static_cast<std::size_t>(nx * ny) * 4, '\0');
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) {
    const double z = g.z_mm.data()[k];
    std::int32_t v = -2;  // Zmin - 2: non-measured
    if (std::isfinite(z)) v = static_cast<std::int32_t>(std::clamp(std::llround((z - static_cast<double>(zoff)) / static_cast<double>(dz)), 0LL, static_cast<long long>(kSteps)));
    std::memcpy(&data[static_cast<std::size_t>(k) * 4], &v, 4);
  }
  core::AtomicFile out(file);
  out.stream().write(h.data(), static_cast<std::streamsize>(h.size()));
  out.stream().write(data.data(), static_cast<std::streamsize>(data.size()));
  out.commit();
}

}  // namespace vmsim::metrology
