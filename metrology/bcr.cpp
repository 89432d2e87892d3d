#include "metrology/bcr.hpp"
#include "metrology/reader_common.hpp"
#include "core/regular_file.hpp"

#include "core/error.hpp"
#include "metrology/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

namespace vmsim::metrology {

namespace {

constexpr std::size_t kMaxHeaderChars = 1 << 20;

[[noreturn]] void fail(const std::string& name, const std::string& what) { throw core::Error(name + ": " + what); }

bool utf16_header(std::string_view b) {
  return b.size() >= 4 && b[0] == 'f' && b[1] == '\0' && b[2] == 'i' && b[3] == '\0';
}

// The header's characters (UTF-16 code units narrowed: the keys and values are ASCII).
std::string narrow(std::string_view b, bool utf16, std::size_t chars) {
  std::string s;
  const std::size_t n = std::min(chars, utf16 ? b.size() / 2 : b.size());
  s.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (!utf16) {
      s += b[k];
      continue;
    }
    const unsigned lo = static_cast<unsigned char>(b[2 * k]), hi = static_cast<unsigned char>(b[2 * k + 1]);
    s += hi == 0 ? static_cast<char>(lo) : '?';
  }
  return s;
}

std::map<std::string, std::string> parse_keys(const std::string& text) {
  std::map<std::string, std::string> keys;
  std::size_t p = 0;
  while (p < text.size()) {
    std::size_t e = text.find('\n', p);
    if (e == std::string::npos) e = text.size();
    const std::string line = trim_blanks(std::string_view(text).substr(p, e - p));
    p = e + 1;
    if (line.empty() || line[0] == '%' || line[0] == '\0') continue;
    const std::size_t eq = line.find('=');
    if (eq == std::string::npos) continue;
    std::string key = trim_blanks(std::string_view(line).substr(0, eq));
    for (char& c : key) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    keys.emplace(key, trim_blanks(std::string_view(line).substr(eq + 1)));
  }
  return keys;
}

}  // namespace

bool looks_like_bcr(std::string_view head) {
  const std::string s = narrow(head.substr(0, std::min<std::size_t>(head.size(), 128)), utf16_header(head), 64);
  return s.rfind("fileformat = bcrstm", 0) == 0 || s.rfind("fileformat = bcrf", 0) == 0;
}

core::HeightGrid read_bcr_bytes(std::string_view b, const std::string& name) {
  const bool utf16 = utf16_header(b);
  const std::size_t unit = utf16 ? 2 : 1;
  // headersize is in the first lines; read them first, then the whole header.
  std::map<std::string, std::string> keys = parse_keys(narrow(b, utf16, 4096));
  const auto format = keys.find("fileformat");
  if (format == keys.end()) fail(name, "not a BCR-STM file: no \"fileformat = bcrstm\" or \"bcrf\" line");
  const std::string kind = format->second;
  const bool is_float = kind == "bcrf" || kind == "bcrf_unicode";
  if (!is_float && kind != "bcrstm" && kind != "bcrstm_unicode")
    fail(name, "fileformat = " + kind + ": vmsim reads bcrstm, bcrf, bcrstm_unicode and bcrf_unicode");
  const auto number = [&](const char* key, std::optional<double> fallback) -> double {
    const auto it = keys.find(key);
    if (it == keys.end()) {
      if (fallback) return *fallback;
      fail(name, fmt::format("header: the key \"{}\" is missing", key));
    }
    const auto v = parse_decimal_scaled(it->second);
    if (!v || !std::isfinite(*v))
      fail(name, fmt::format("header: {} = \"{}\" is not a number", key, it->second.substr(0, 40)));
    return *v;
  };
  const auto count = [&](const char* key) -> std::uint64_t {
    const double v = number(key, std::nullopt);
    if (!(v >= 1) || v != std::floor(v) || v > static_cast<double>(kMaxGridPoints))
      fail(name, fmt::format("header: {} = {} is not a point count (1 .. {})", key, v, kMaxGridPoints));
    return static_cast<std::uint64_t>(v);
  };
  const double header_chars = number("headersize", 2048.0);
  if (!(header_chars >= 1) || header_chars > static_cast<double>(kMaxHeaderChars) ||
      header_chars != std::floor(header_chars))
    fail(name, fmt::format("header: headersize = {} is not a size in characters", header_chars));
  const std::size_t header_bytes = static_cast<std::size_t>(header_chars) * unit;
  if (header_bytes > b.size())
    fail(name, fmt::format("headersize {} characters: the file has {} bytes", header_chars, b.size()));
  keys = parse_keys(narrow(b, utf16, static_cast<std::size_t>(header_chars)));
  const std::uint64_t nx = count("xpixels"), ny = count("ypixels");
  if (nx > kMaxGridPoints / ny) fail(name, fmt::format("header: {} x {} points is more than vmsim accepts", nx, ny));
  const auto unit_pow = [&](const char* key) {
    const auto it = keys.find(key);
    if (it == keys.end()) return -9;  // nm, the format's default
    const auto p = length_unit_pow10(it->second);
    if (!p)
      fail(name,
           fmt::format("header: {} = \"{}\" is not a length unit (m, mm, um, nm, A)", key, it->second.substr(0, 20)));
    return *p;
  };
  const int px = unit_pow("xunit"), py = unit_pow("yunit"), pz = unit_pow("zunit");
  core::HeightGrid g;
  g.dx_mm = number("xlength", std::nullopt) * std::pow(10.0, px + 3) / static_cast<double>(nx);
  g.dy_mm = number("ylength", std::nullopt) * std::pow(10.0, py + 3) / static_cast<double>(ny);
  if (!(g.dx_mm > 0) || !(g.dy_mm > 0) || !std::isfinite(g.dx_mm) || !std::isfinite(g.dy_mm))
    fail(name, "header: xlength and ylength must be positive");
  g.x0_mm = number("xoffset", 0.0) * std::pow(10.0, px + 3);
  g.y0_mm = number("yoffset", 0.0) * std::pow(10.0, py + 3);
  const double scale_mm = number("bit2nm", 1.0) * std::pow(10.0, pz + 3);
  if (scale_mm == 0) fail(name, "header: bit2nm = 0 would make every height zero");
  const bool little = number("intelmode", 1.0) != 0;
  const bool declares_void = keys.count("voidpixels") && number("voidpixels", 0.0) != 0;

  const std::size_t psize = is_float ? 4 : 2;
  const std::uint64_t n = nx * ny;
  if (b.size() < header_bytes + n * psize)
    fail(name, fmt::format("{} bytes of points after the {}-byte header; {} x {} points of {} bytes need {}",
                           b.size() - header_bytes, header_bytes, nx, ny, psize, n * psize));
  g.z_mm.resize(static_cast<Eigen::Index>(ny), static_cast<Eigen::Index>(nx));
  const char* p = b.data() + header_bytes;
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  for (std::uint64_t i = 0; i < n; ++i, p += psize) {
    unsigned char c[4];
    std::memcpy(c, p, psize);
    if (!little) std::reverse(c, c + psize);
    double z;
    bool void_point;
    if (is_float) {
      float f;
      std::memcpy(&f, c, 4);
      void_point = !std::isfinite(f) || (declares_void && std::abs(f) >= 3.4028e38f);
      z = static_cast<double>(f);
    } else {
      std::int16_t s;
      std::memcpy(&s, c, 2);
      void_point = declares_void && s == 32767;
      z = static_cast<double>(s);
    }
    g.z_mm.data()[i] = void_point ? kNaN : z * scale_mm;
  }
  return g;
}

core::HeightGrid read_bcr(const std::filesystem::path& file) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file.string(), "cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return read_bcr_bytes(ss.str(), file.string());
}

}  // namespace vmsim::metrology
