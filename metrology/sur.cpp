#include "metrology/sur.hpp"
#include "metrology/reader_common.hpp"
#include "core/regular_file.hpp"

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
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace vmsim::metrology {

namespace {

constexpr std::size_t kHeader = 512;

[[noreturn]] void fail(const std::string& name, const std::string& what) { throw core::Error(name + ": " + what); }

template <typename T>
T at(std::string_view b, std::size_t off) {  // little-endian, as the format (and x86-64)
  T v;
  std::memcpy(&v, b.data() + off, sizeof v);
  return v;
}

std::string field(std::string_view b, std::size_t off, std::size_t len) {
  std::string s(b.data() + off, len);
  const auto z = s.find('\0');
  if (z != std::string::npos) s.erase(z);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.pop_back();
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.erase(0, 1);
  return s;
}

// Header offsets (bytes). Names as in the MountainsMap description.
enum : std::size_t {
  kSignature = 0,
  kFormat = 12,
  kObjects = 14,
  kVersion = 16,
  kType = 18,
  kObjectName = 20,
  kOperator = 50,
  kPSize = 80,
  kAcquisition = 82,
  kRange = 84,
  kSpecialPoints = 86,
  kAbsolute = 88,
  kGaugeResolution = 90,
  kWSize = 94,
  kPointBits = 98,
  kZmin = 100,
  kZmax = 104,
  kPointsPerLine = 108,
  kLines = 112,
  kTotalPoints = 116,
  kXSpacing = 120,
  kYSpacing = 124,
  kZSpacing = 128,
  kXName = 132,
  kYName = 148,
  kZName = 164,
  kXStepUnit = 180,
  kYStepUnit = 196,
  kZStepUnit = 212,
  kXLengthUnit = 228,
  kYLengthUnit = 244,
  kZLengthUnit = 260,
  kXRatio = 276,
  kYRatio = 280,
  kZRatio = 284,
  kImprint = 288,
  kInverted = 290,
  kLevelled = 292,
  kObsolete = 294,
  kSeconds = 306,
  kMinutes = 308,
  kHours = 310,
  kDay = 312,
  kMonth = 314,
  kYear = 316,
  kDayOfWeek = 318,
  kDuration = 320,
  kCompressedSize = 324,
  kObsolete2 = 328,
  kCommentSize = 334,
  kPrivateSize = 336,
  kClientZone = 338,
  kXOffset = 466,
  kYOffset = 470,
  kZOffset = 474,
  kTSpacing = 478,
  kTOffset = 482,
  kTName = 486,
  kTStepUnit = 499
};

// One object's header, as read from the bytes at `base`.
struct Object {
  bool compressed = false;
  int objects = 1, type = 0, bits = 0, special = 0, inverted = 0, format = 0;
  std::int32_t zmin = 0, nx = 0, ny = 0, wsize = 0;
  std::uint32_t total = 0;
  float dx = 0, dy = 0, dz = 0, xoff = 0, yoff = 0, zoff = 0, rx = 0, ry = 0, rz = 0;
  std::string xstep, ystep, zstep, xlen, ylen, zlen;
  std::size_t comment = 0, priv = 0;
};

Object parse_header(std::string_view b, std::size_t base, const std::string& name) {
  const auto fail_at = [&](std::size_t off, const std::string& what) {
    fail(name, fmt::format("object at byte {}: header byte {}: {}", base, off, what));
  };
  if (b.size() < base + kHeader)
    fail(name, fmt::format("{} bytes: the object at byte {} needs a 512-byte .sur header", b.size(), base));
  Object o;
  const std::string_view sig = b.substr(base, 12);
  o.compressed = sig == "DSCOMPRESSED";
  if (sig != "DIGITAL SURF" && !o.compressed)
    fail(name,
         base == 0
             ? std::string("not a Digital Surf file: it starts neither with \"DIGITAL SURF\" nor \"DSCOMPRESSED\"")
             : fmt::format("byte {}: the next object does not start with \"DIGITAL SURF\" or \"DSCOMPRESSED\"", base));
  const std::string_view h = b.substr(base, kHeader);
  o.format = at<std::int16_t>(h, kFormat);
  if (o.format != 0)
    fail_at(kFormat, fmt::format("format {}: vmsim reads PC (little-endian, 0) files; 257 is the Macintosh byte order",
                                 o.format));
  o.objects = at<std::uint16_t>(h, kObjects);
  o.type = at<std::int16_t>(h, kType);
  o.special = at<std::int16_t>(h, kSpecialPoints);
  o.wsize = at<std::int32_t>(h, kWSize);
  o.bits = at<std::int16_t>(h, kPointBits);
  if (o.bits != 16 && o.bits != 32) fail_at(kPointBits, fmt::format("{} bits per point, expected 16 or 32", o.bits));
  o.zmin = at<std::int32_t>(h, kZmin);
  o.nx = at<std::int32_t>(h, kPointsPerLine);
  o.ny = at<std::int32_t>(h, kLines);
  if (o.nx < 1 || o.ny < 1)
    fail_at(kPointsPerLine, fmt::format("{} points per line, {} lines: both must be at least 1", o.nx, o.ny));
  if (static_cast<std::uint64_t>(o.nx) * static_cast<std::uint64_t>(o.ny) > kMaxGridPoints)
    fail_at(kPointsPerLine, fmt::format("{} x {} points is more than vmsim accepts", o.nx, o.ny));
  o.total = at<std::uint32_t>(h, kTotalPoints);
  if (o.total != static_cast<std::uint64_t>(o.nx) * static_cast<std::uint64_t>(o.ny))
    fail_at(kTotalPoints, fmt::format("total points {}, but {} x {} = {}", o.total, o.nx, o.ny,
                                      static_cast<std::uint64_t>(o.nx) * static_cast<std::uint64_t>(o.ny)));
  o.dx = at<float>(h, kXSpacing), o.dy = at<float>(h, kYSpacing), o.dz = at<float>(h, kZSpacing);
  o.rx = at<float>(h, kXRatio), o.ry = at<float>(h, kYRatio), o.rz = at<float>(h, kZRatio);
  o.xstep = field(h, kXStepUnit, 16), o.ystep = field(h, kYStepUnit, 16), o.zstep = field(h, kZStepUnit, 16);
  o.xlen = field(h, kXLengthUnit, 16), o.ylen = field(h, kYLengthUnit, 16), o.zlen = field(h, kZLengthUnit, 16);
  o.inverted = at<std::int16_t>(h, kInverted);
  o.comment = at<std::uint16_t>(h, kCommentSize);
  o.priv = at<std::uint16_t>(h, kPrivateSize);
  o.xoff = at<float>(h, kXOffset), o.yoff = at<float>(h, kYOffset), o.zoff = at<float>(h, kZOffset);
  return o;
}

// The object's points as raw bytes (inflated when compressed), and the offset of the next object.
std::string object_points(std::string_view b, std::size_t base, const Object& o, const std::string& name,
                          std::size_t& next) {
  const std::size_t start = base + kHeader + o.comment + o.priv;
  const std::size_t psize = static_cast<std::size_t>(o.bits / 8);
  const std::size_t n = static_cast<std::size_t>(o.total);
  const std::size_t need = n * psize;
  if (!o.compressed) {
    // Series and spectra carry W values per point; the first W-layer is the height object read here.
    const std::size_t w = static_cast<std::size_t>(std::max<std::int32_t>(o.wsize, 1));
    if (b.size() < start + need)
      fail(name, fmt::format("{} bytes after the header and zones (from byte {}), {} x {} points of {} bits need {}",
                             b.size() < start ? 0 : b.size() - start, start, o.nx, o.ny, o.bits, need));
    next = start + std::min(need * w, b.size() - start);
    return std::string(b.substr(start, need));
  }
  // Compressed: a count of streams, then (raw size, zipped size) per stream, then the zlib streams.
  std::size_t p = start;
  const auto u32 = [&](const char* what) {
    if (p + 4 > b.size()) fail(name, fmt::format("byte {}: file ends inside the compressed data's {}", p, what));
    const std::uint32_t v = at<std::uint32_t>(b, p);
    p += 4;
    return v;
  };
  const std::uint32_t streams = u32("stream count");
  if (streams < 1 || streams > 64)
    fail(name, fmt::format("byte {}: {} compressed streams, expected 1 to 64", p - 4, streams));
  std::vector<std::uint32_t> rawlen(streams), ziplen(streams);
  std::uint64_t sum = 0, zipped = 0;
  for (std::uint32_t s = 0; s < streams; ++s) {
    rawlen[s] = u32("stream sizes"), ziplen[s] = u32("stream sizes");
    sum += rawlen[s], zipped += ziplen[s];
  }
  if (sum < need)
    fail(name, fmt::format("compressed streams hold {} bytes, {} x {} points need {}", sum, o.nx, o.ny, need));
  // Deflate expands at most ~1032:1: streams that claim more are corrupt (and would make vmsim allocate for them).
  if (zipped > b.size() || sum > 1032 * zipped + 1024)
    fail(name, fmt::format("compressed streams of {} bytes cannot hold the {} bytes they declare", zipped, sum));
  std::string raw(static_cast<std::size_t>(sum), '\0');
  std::size_t out = 0;
  for (std::uint32_t s = 0; s < streams; ++s) {
    if (p + ziplen[s] > b.size())
      fail(name, fmt::format("byte {}: compressed stream {} runs past the end of the file", p, s + 1));
    uLongf len = rawlen[s];
    if (uncompress(reinterpret_cast<Bytef*>(raw.data() + out), &len, reinterpret_cast<const Bytef*>(b.data() + p),
                   ziplen[s]) != Z_OK ||
        len != rawlen[s])
      fail(name, fmt::format("byte {}: compressed stream {} is corrupt", p, s + 1));
    p += ziplen[s];
    out += rawlen[s];
  }
  next = p;
  raw.resize(need);
  return raw;
}

const char* type_name(int t) {
  switch (t) {
    case 1:
      return "profile";
    case 2:
      return "surface";
    case 3:
      return "binary image";
    case 4:
      return "series of profiles";
    case 5:
      return "series of surfaces";
    case 7:
      return "multilayer profile";
    case 8:
      return "multilayer surface";
    case 10:
      return "intensity image";
    case 12:
      return "RGB image";
    case 20:
      return "spectrum";
    case 21:
      return "hyperspectral map";
    default:
      return "object";
  }
}

// 10^p (m) of a unit field, or nullopt; the MS-DOS code page's micro sign (0xE6) as in SurfaceTopography's tests.
std::optional<int> sur_unit(const std::string& u) {
  if (u.size() == 2 && static_cast<unsigned char>(u[0]) == 0xE6 && u[1] == 'm') return -6;
  return length_unit_pow10(u);
}

}  // namespace

SurData read_sur_bytes(std::string_view b, const std::string& name) {
  const Object o = parse_header(b, 0, name);
  const bool profile = o.type == 1 || o.type == 4 || o.type == 7;
  const bool surface = o.type == 2 || o.type == 5 || o.type == 8;
  if (!profile && !surface)
    fail(name,
         fmt::format("header byte {}: object type {} ({}); vmsim reads heights: surfaces (2), profiles (1), their "
                     "series (5, 4) and multilayers (8, 7)",
                     kType, o.type, type_name(o.type)));
  SurData out;
  out.profile = profile;
  std::vector<std::string> notes;
  // Lengths: the step unit (see sur.hpp). A step unit that is not a length falls back on the length unit and ratio.
  const auto axis_pow = [&](const std::string& step, const std::string& len, float ratio, std::size_t off,
                            const char* axis, double& scale) {
    if (const auto p = sur_unit(step)) {
      scale = std::pow(10.0, *p + 3);
      if (const auto q = sur_unit(len); q && ratio != 0 && std::isfinite(ratio)) {
        const double expect = std::pow(10.0, *q - *p);
        if (std::abs(static_cast<double>(ratio) - expect) > 1e-4 * expect)
          notes.push_back(
              fmt::format("the {} unit ratio is {:g}, but 1 {} = {:g} {}; vmsim used the step unit {} (as "
                          "Gwyddion and SurfaceTopography do)",
                          axis, ratio, len, expect, step, step));
      }
      return;
    }
    const auto q = sur_unit(len);
    if (!q || ratio == 0 || !std::isfinite(ratio))
      fail(name,
           fmt::format("header byte {}: {} step unit \"{}\" is not a length (m, mm, um, nm expected), and the length "
                       "unit \"{}\" with ratio {:g} cannot stand in",
                       off, axis, step, len, ratio));
    scale = std::pow(10.0, *q + 3) / static_cast<double>(ratio);
    notes.push_back(
        fmt::format("the {} step unit \"{}\" is not a length; vmsim took the length unit {} and the ratio {:g}", axis,
                    step, len, ratio));
  };
  double sx = 1, sy = 1, sz = 1;
  axis_pow(o.xstep, o.xlen, o.rx, kXStepUnit, "x", sx);
  if (!profile) axis_pow(o.ystep, o.ylen, o.ry, kYStepUnit, "y", sy);
  axis_pow(o.zstep, o.zlen, o.rz, kZStepUnit, "z", sz);
  core::HeightGrid& g = out.grid;
  g.dx_mm = static_cast<double>(o.dx) * sx;
  g.dy_mm = profile ? g.dx_mm : static_cast<double>(o.dy) * sy;
  if (!(g.dx_mm > 0) || !(g.dy_mm > 0) || !std::isfinite(g.dx_mm) || !std::isfinite(g.dy_mm))
    fail(name, fmt::format("header bytes {}-{}: x and y spacing must be positive", kXSpacing, kYSpacing + 3));
  if (!std::isfinite(o.dz) || o.dz == 0)
    fail(name, fmt::format("header byte {}: z spacing must be a non-zero number", kZSpacing));
  g.x0_mm = static_cast<double>(o.xoff) * sx;
  g.y0_mm = profile ? 0.0 : static_cast<double>(o.yoff) * sy;
  if (!std::isfinite(g.x0_mm) || !std::isfinite(g.y0_mm)) g.x0_mm = g.y0_mm = 0;
  const double zoff_mm = std::isfinite(o.zoff) ? static_cast<double>(o.zoff) * sz : 0.0;

  std::size_t next = 0;
  const std::string raw = object_points(b, 0, o, name, next);
  const bool special = o.special == 1;
  const std::int64_t nonmeasured = static_cast<std::int64_t>(o.zmin) - 2;
  const double scale = static_cast<double>(o.dz) * sz;
  g.z_mm.resize(o.ny, o.nx);
  const std::size_t n = o.total;
  for (std::size_t i = 0; i < n; ++i) {
    const std::int64_t v = o.bits == 16 ? at<std::int16_t>(raw, i * 2) : at<std::int32_t>(raw, i * 4);
    const double z = static_cast<double>(v) * scale + zoff_mm;
    g.z_mm.data()[i] =
        (special && v == nonmeasured) || !std::isfinite(z) ? std::numeric_limits<double>::quiet_NaN() : z;
  }
  if (o.inverted >= 1 && o.inverted <= 3) {
    g.z_mm = -g.z_mm;
    if (o.inverted == 2) g.z_mm = g.z_mm.rowwise().reverse().eval();
    if (o.inverted == 3) g.z_mm = g.z_mm.colwise().reverse().eval();
  }
  // Further objects: say what they are; only the first is read.
  if (o.objects > 1 || next < b.size()) {
    int count = 1;
    std::vector<std::string> kinds;
    std::size_t base = next;
    while (base + kHeader <= b.size() && count < 4096) {
      try {
        const Object k = parse_header(b, base, name);
        std::size_t after = 0;
        (void)object_points(b, base, k, name, after);
        kinds.push_back(type_name(k.type));
        ++count;
        if (after <= base) break;
        base = after;
      } catch (const core::Error&) {
        break;
      }
    }
    if (count > 1 || o.objects > 1)
      notes.push_back(fmt::format("the file holds {} objects (header: {}); vmsim read the first, a {}", count,
                                  o.objects, type_name(o.type)));
  }
  for (const std::string& s : notes) out.note += (out.note.empty() ? "" : "; ") + s;
  return out;
}

SurData read_sur_data(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file.string(), "cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string b = std::move(ss).str();
  return read_sur_bytes(b, file.string());
}

void write_sur(const std::filesystem::path& file, const core::HeightGrid& g) {
  const Eigen::Index nx = g.nx(), ny = g.ny();
  if (nx < 1 || ny < 1 || nx > INT32_MAX / std::max<Eigen::Index>(ny, 1))
    fail(file.string(), "cannot write an empty or huge grid as .sur");
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
  put16(kType, 2);  // surface
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
  for (std::size_t off : {kXStepUnit, kYStepUnit, kZStepUnit, kXLengthUnit, kYLengthUnit, kZLengthUnit})
    put_str(off, 16, "mm");
  putf(kXRatio, 1), putf(kYRatio, 1), putf(kZRatio, 1);
  putf(kXOffset, static_cast<float>(g.x0_mm));
  putf(kYOffset, static_cast<float>(g.y0_mm));
  putf(kZOffset, zoff);
  std::string data(static_cast<std::size_t>(nx * ny) * 4, '\0');
  for (Eigen::Index k = 0; k < g.z_mm.size(); ++k) {
    const double z = g.z_mm.data()[k];
    std::int32_t v = -2;  // Zmin - 2: non-measured
    if (std::isfinite(z))
      v = static_cast<std::int32_t>(std::clamp(std::llround((z - static_cast<double>(zoff)) / static_cast<double>(dz)),
                                               0LL, static_cast<long long>(kSteps)));
    std::memcpy(&data[static_cast<std::size_t>(k) * 4], &v, 4);
  }
  core::AtomicFile out(file);
  out.stream().write(h.data(), static_cast<std::streamsize>(h.size()));
  out.stream().write(data.data(), static_cast<std::streamsize>(data.size()));
  out.commit();
}

}  // namespace vmsim::metrology
