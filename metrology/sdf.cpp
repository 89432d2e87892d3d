#include "metrology/sdf.hpp"
#include "metrology/reader_common.hpp"
#include "core/units.hpp"
#include "core/regular_file.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "metrology/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace vmsim::metrology {

namespace {

using core::units::kNaN;
constexpr std::size_t kBinaryHeader = 8 + 10 + 12 + 12 + 2 + 2 + 4 * 8 + 3;  // 81 bytes
constexpr std::size_t kTypeSize[8] = {1, 2, 4, 4, 1, 2, 4, 8};

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what) {
  throw core::Error(file.string() + ": " + what);
}

template <typename T>
T load_le(const char* p) {  // SDF binary data are little-endian (PC origin); so is x86-64
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

struct Header {
  long nx = 0, ny = 0;
  double dx_mm = 0, dy_mm = 0;
  double zscale_mm = 0;  // mm per stored unit
  int compression = 0, data_type = -1, check_type = 0;
};

void check_header(const std::filesystem::path& file, const Header& h, const std::string& where) {
  if (h.nx < 1 || h.ny < 1)
    fail(file, where + fmt::format("NumPoints {} x NumProfiles {}: both must be at least 1", h.nx, h.ny));
  if (!(h.dx_mm > 0) || !(h.dy_mm > 0) || !std::isfinite(h.dx_mm) || !std::isfinite(h.dy_mm))
    fail(file, where + "Xscale and Yscale must be positive lengths in metres");
  if (!std::isfinite(h.zscale_mm) || h.zscale_mm == 0) fail(file, where + "Zscale must be a non-zero number");
  if (h.data_type < 0 || h.data_type > 7) fail(file, where + fmt::format("DataType {}: expected 0 to 7", h.data_type));
  if (h.compression != 0) fail(file, where + "compressed SDF data (Compression != 0) is not supported");
}

core::HeightGrid read_binary(const std::filesystem::path& file, const std::string& bytes) {
  if (bytes.size() < kBinaryHeader)
    fail(file, fmt::format("{} bytes: shorter than the 81-byte binary SDF header", bytes.size()));
  Header h;
  const char* p = bytes.data() + 8 + 10 + 12 + 12;
  h.nx = load_le<std::uint16_t>(p);
  h.ny = load_le<std::uint16_t>(p + 2);
  const double xs = load_le<double>(p + 4), ys = load_le<double>(p + 12), zs = load_le<double>(p + 20);
  h.dx_mm = xs * 1000.0, h.dy_mm = ys * 1000.0, h.zscale_mm = zs * 1000.0;
  h.compression = static_cast<unsigned char>(p[36]);
  h.data_type = static_cast<unsigned char>(p[37]);
  h.check_type = static_cast<unsigned char>(p[38]);
  check_header(file, h, "binary header: ");
  const std::size_t n = static_cast<std::size_t>(h.nx) * static_cast<std::size_t>(h.ny);
  const std::size_t need = n * kTypeSize[h.data_type];
  std::size_t start = kBinaryHeader;
  // Olympus writes 8 more header bytes (as Gwyddion notes); recognise them by the exact file size.
  if (bytes.size() == kBinaryHeader + need + 8) start += 8;
  if (bytes.size() < start + need)
    fail(file, fmt::format("{} bytes of data after the header, {} x {} points of type {} need {}", bytes.size() - start,
                           h.nx, h.ny, h.data_type, need));
  core::HeightGrid g;
  g.dx_mm = h.dx_mm, g.dy_mm = h.dy_mm;
  g.z_mm.resize(h.ny, h.nx);
  const char* d = bytes.data() + start;
  for (std::size_t i = 0; i < n; ++i) {
    const char* q = d + i * kTypeSize[h.data_type];
    double v = 0;
    bool bad = false;
    switch (h.data_type) {
      case 0:
        v = static_cast<unsigned char>(*q);
        break;
      case 1: {
        const auto u = load_le<std::uint16_t>(q);
        bad = u == 0xffff;
        v = u;
        break;
      }
      case 2: {
        const auto u = load_le<std::uint32_t>(q);
        bad = u == 0xffffffffu;
        v = u;
        break;
      }
      case 3:
        v = load_le<float>(q);
        break;
      case 4:
        v = static_cast<signed char>(*q);
        break;
      case 5: {
        const auto s = load_le<std::int16_t>(q);
        bad = s == INT16_MIN;
        v = s;
        break;
      }
      case 6: {
        const auto s = load_le<std::int32_t>(q);
        bad = s == INT32_MIN;
        v = s;
        break;
      }
      default:
        v = load_le<double>(q);
        break;
    }
    const double z = v * h.zscale_mm;
    g.z_mm.data()[i] = bad || !std::isfinite(z) ? kNaN : z;
  }
  return g;
}

core::HeightGrid read_ascii(const std::filesystem::path& file, const std::string& text) {
  std::istringstream in(text);
  std::string line;
  int lineno = 0;
  std::getline(in, line);
  ++lineno;
  Header h;
  std::map<std::string, bool> seen;
  std::string zscale_text;
  // Header: "Key = value" lines up to the first "*".
  bool star = false;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = trim_blanks(line);
    if (t.empty() || t[0] == ';') continue;
    if (t == "*") {
      star = true;
      break;
    }
    const std::size_t eq = t.find('=');
    if (eq == std::string::npos)
      fail(file, fmt::format("line {}: expected \"Key = value\" before the \"*\" that starts the data", lineno));
    const std::string key = trim_blanks(std::string_view(t).substr(0, eq)), val = trim_blanks(std::string_view(t).substr(eq + 1));
    seen[key] = true;
    const auto integer = [&](long lo, long hi) {
      const auto v = parse_decimal_scaled(val);
      if (!v || *v != std::floor(*v) || *v < static_cast<double>(lo) || *v > static_cast<double>(hi))
        fail(file, fmt::format("line {}: {}: expected an integer from {} to {}, found \"{}\"", lineno, key, lo, hi,
                               val.substr(0, 40)));
      return static_cast<long>(*v);
    };
    const auto metres_as_mm = [&]() {
      const auto v = parse_decimal_scaled(val, 3);
      if (!v || !std::isfinite(*v))
        fail(file,
             fmt::format("line {}: {}: expected a number of metres, found \"{}\"", lineno, key, val.substr(0, 40)));
      return *v;
    };
    if (key == "NumPoints")
      h.nx = integer(1, 1 << 20);
    else if (key == "NumProfiles")
      h.ny = integer(1, 1 << 20);
    else if (key == "Xscale")
      h.dx_mm = metres_as_mm();
    else if (key == "Yscale")
      h.dy_mm = metres_as_mm();
    else if (key == "Zscale")
      h.zscale_mm = metres_as_mm();
    else if (key == "Compression")
      h.compression = static_cast<int>(integer(0, 255));
    else if (key == "DataType")
      h.data_type = static_cast<int>(integer(0, 255));
    else if (key == "CheckType")
      h.check_type = static_cast<int>(integer(0, 255));
  }
  if (!star) fail(file, "no \"*\" line ending the header");
  for (const char* k : {"NumPoints", "NumProfiles", "Xscale", "Yscale", "Zscale", "DataType"})
    if (!seen.count(k)) fail(file, std::string("header: ") + k + " is missing");
  check_header(file, h, "header: ");
  if (static_cast<double>(h.nx) * static_cast<double>(h.ny) > static_cast<double>(1LL << 28))
    fail(file, fmt::format("header: {} x {} points is more than vmsim accepts", h.nx, h.ny));
  const std::size_t n = static_cast<std::size_t>(h.nx) * static_cast<std::size_t>(h.ny);
  // The stored values are x Zscale; Zscale 1E-3 (vmsim's) means mm, read with one rounding.
  const bool mm_values = h.zscale_mm == 1.0;
  std::vector<double> z;
  z.reserve(std::min<std::size_t>(n, 1 << 20));
  bool end_star = false;
  while (std::getline(in, line)) {
    ++lineno;
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
      const std::size_t b = i;
      while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
      if (i == b) continue;
      const std::string_view tok(line.data() + b, i - b);
      if (tok == "*") {
        end_star = true;
        break;
      }
      if (z.size() >= n)
        fail(file, fmt::format("line {}: more than the {} x {} values the header declares", lineno, h.nx, h.ny));
      std::string low(tok);
      for (char& c : low) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      if (low == "nan" || low == "bad") {
        z.push_back(kNaN);
        continue;
      }
      const auto v = mm_values ? parse_decimal_scaled(tok) : parse_decimal_scaled(tok);
      if (!v) fail(file, fmt::format("line {}: \"{}\" is not a number", lineno, std::string(tok).substr(0, 40)));
      const double zz = mm_values ? *v : *v * h.zscale_mm;
      z.push_back(std::isfinite(zz) ? zz : kNaN);
    }
    if (end_star) break;
  }
  if (z.size() != n) fail(file, fmt::format("{} values, the header declares {} x {} = {}", z.size(), h.nx, h.ny, n));
  core::HeightGrid g;
  g.dx_mm = h.dx_mm, g.dy_mm = h.dy_mm;
  // Trailer: "key = value" lines; vmsim's XOffset and YOffset give the origin.
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = trim_blanks(line);
    const std::size_t eq = t.find('=');
    if (t == "*" || eq == std::string::npos) continue;
    const std::string key = trim_blanks(std::string_view(t).substr(0, eq)), val = trim_blanks(std::string_view(t).substr(eq + 1));
    if (key == "XOffset" || key == "YOffset") {
      const auto v = parse_decimal_scaled(val, 3);
      if (!v || !std::isfinite(*v)) fail(file, fmt::format("line {}: {}: expected a number of metres", lineno, key));
      (key == "XOffset" ? g.x0_mm : g.y0_mm) = *v;
    }
  }
  g.z_mm = Eigen::Map<core::HeightArray>(z.data(), h.ny, h.nx);
  return g;
}

}  // namespace

core::HeightGrid read_sdf(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string bytes = std::move(ss).str();
  if (bytes.size() >= 8 && (bytes.compare(0, 4, "bISO") == 0 || bytes.compare(0, 4, "bBCR") == 0))
    return read_binary(file, bytes);
  if (bytes.size() >= 8 && (bytes.compare(0, 4, "aISO") == 0 || bytes.compare(0, 4, "aBCR") == 0))
    return read_ascii(file, bytes);
  fail(file, "not an SDF file: it starts neither with aISO-1.0 (ASCII) nor bISO-1.0 (binary)");
}

void write_sdf(const std::filesystem::path& file, const core::HeightGrid& g) {
  if (g.nx() < 1 || g.ny() < 1 || g.nx() > 65535 || g.ny() > 65535)
    fail(file, fmt::format("SDF holds 1 to 65535 points per axis; this grid is {} x {}", g.nx(), g.ny()));
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char date[16];
  std::strftime(date, sizeof date, "%d%m%Y%H%M", &tm);  // DDMMYYYYHHMM (ISO 25178-71)
  core::AtomicFile out(file);
  auto& s = out.stream();
  s << "aISO-1.0\n";
  s << "ManufacID   = vmsim\n";
  s << "CreateDate  = " << date << "\nModDate     = " << date << "\n";
  s << "NumPoints   = " << g.nx() << "\nNumProfiles = " << g.ny() << "\n";
  s << "Xscale      = " << format_scaled(g.dx_mm, -3) << "\n";
  s << "Yscale      = " << format_scaled(g.dy_mm, -3) << "\n";
  s << "Zscale      = 1.0E-03\n";  // values are mm
  s << "Zresolution = -1\n";       // unknown (a prediction has no instrument resolution)
  s << "Compression = 0\nDataType    = 7\nCheckType   = 0\n*\n";
  std::string line;
  for (Eigen::Index j = 0; j < g.ny(); ++j) {
    line.clear();
    for (Eigen::Index i = 0; i < g.nx(); ++i) {
      if (i) line += ' ';
      const double z = g.z_mm(j, i);
      line += std::isfinite(z) ? fmt::format("{}", z) : std::string("NaN");
    }
    line += '\n';
    s << line;
  }
  s << "*\n";
  s << "XOffset = " << format_scaled(g.x0_mm, -3) << "\n";
  s << "YOffset = " << format_scaled(g.y0_mm, -3) << "\n";
  s << "Creator = vmsim\n*\n";
  out.commit();
}

}  // namespace vmsim::metrology
