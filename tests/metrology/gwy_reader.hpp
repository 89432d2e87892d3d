#pragma once
// Gwyddion as an independent reader for the metrology tests: a file converted headless to Gwyddion's own .gwy
// format (`gwyddion --convert-to-gwy`, Gwyddion 2.62 from Debian), and that format read back (the Gwyddion user
// guide, "Gwyddion native file format"). Skips are the caller's: gwyddion_available() says whether it can run.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace vmsim_test {

// The GWY serialisation: "GWYP", then an object: its type name (NUL-terminated), the byte size of its
// components, and components: name, one type character, value.
struct GwyObject {
  std::string type;
  std::map<std::string, double> numbers;
  std::map<std::string, std::string> strings;
  std::map<std::string, std::vector<double>> arrays;
  std::map<std::string, GwyObject> objects;
};

struct GwyReader {
  const std::string& b;
  std::size_t p = 0;
  std::string cstr() {
    const std::size_t e = b.find('\0', p);
    if (e == std::string::npos) throw std::runtime_error("gwy: unterminated string");
    std::string s = b.substr(p, e - p);
    p = e + 1;
    return s;
  }
  template <typename T>
  T get() {
    if (p + sizeof(T) > b.size()) throw std::runtime_error("gwy: truncated");
    T v;
    std::memcpy(&v, b.data() + p, sizeof v);
    p += sizeof v;
    return v;
  }
  GwyObject object() {
    GwyObject o;
    o.type = cstr();
    const std::uint32_t size = get<std::uint32_t>();
    const std::size_t end = p + size;
    while (p < end) {
      const std::string name = cstr();
      const char t = b[p++];
      switch (t) {
        case 'b':
        case 'c':
          o.numbers[name] = static_cast<unsigned char>(b[p++]);
          break;
        case 'i':
          o.numbers[name] = get<std::int32_t>();
          break;
        case 'q':
          o.numbers[name] = static_cast<double>(get<std::int64_t>());
          break;
        case 'd':
          o.numbers[name] = get<double>();
          break;
        case 's':
          o.strings[name] = cstr();
          break;
        case 'o':
          o.objects[name] = object();
          break;
        case 'D': {
          const std::uint32_t n = get<std::uint32_t>();
          auto& a = o.arrays[name];
          a.resize(n);
          if (p + 8 * static_cast<std::size_t>(n) > b.size()) throw std::runtime_error("gwy: truncated array");
          std::memcpy(a.data(), b.data() + p, 8 * static_cast<std::size_t>(n));
          p += 8 * static_cast<std::size_t>(n);
          break;
        }
        case 'C': {
          const std::uint32_t n = get<std::uint32_t>();
          p += n;
          break;
        }
        case 'I': {
          const std::uint32_t n = get<std::uint32_t>();
          p += 4 * static_cast<std::size_t>(n);
          break;
        }
        case 'Q': {
          const std::uint32_t n = get<std::uint32_t>();
          p += 8 * static_cast<std::size_t>(n);
          break;
        }
        case 'S':
          for (std::uint32_t k = 0, n = get<std::uint32_t>(); k < n; ++k) cstr();
          break;
        case 'O':
          for (std::uint32_t k = 0, n = get<std::uint32_t>(); k < n; ++k) (void)object();
          break;
        default:
          throw std::runtime_error("gwy: unknown component type " + std::to_string(static_cast<int>(t)) + " of " +
                                   name + " at byte " + std::to_string(p));
      }
    }
    p = end;
    return o;
  }
};

inline bool gwyddion_available() { return std::system("command -v gwyddion > /dev/null 2>&1") == 0; }

// Gwyddion's first data field of `file` (its channel "/0/data", and "/0/mask" when it made one), converted in
// `scratch`. nullopt when Gwyddion cannot read the file (the log says why: `why` receives it).
struct GwyField {
  long xres = 0, yres = 0;
  double xreal = 0, yreal = 0, xoff = 0, yoff = 0;  // metres
  std::vector<double> data;                         // row-major, row 0 first, SI units (metres)
  std::vector<double> mask;                         // empty when Gwyddion made none; 1 = masked
};
inline std::optional<GwyField> gwyddion_read(const std::filesystem::path& file, const std::filesystem::path& scratch,
                                             std::string* why = nullptr) {
  std::filesystem::create_directories(scratch);
  const std::filesystem::path out = scratch / (file.filename().string() + ".gwy"),
                              log = scratch / (file.filename().string() + ".log");
  const std::string cmd = "timeout 300 gwyddion --convert-to-gwy='" + out.string() + "' '" + file.string() + "' > '" +
                          log.string() + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  std::ifstream in(out, std::ios::binary);
  if (rc != 0 || !in) {
    if (why) {
      std::ifstream l(log);
      std::stringstream ss;
      ss << l.rdbuf();
      *why = ss.str();
    }
    return std::nullopt;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string bytes = ss.str();
  if (bytes.substr(0, 4) != "GWYP") throw std::runtime_error(out.string() + ": not a GWY file");
  GwyReader r{bytes, 4};
  const GwyObject top = r.object();
  if (!top.objects.count("/0/data")) throw std::runtime_error(out.string() + ": no channel /0/data");
  const GwyObject& f = top.objects.at("/0/data");
  GwyField g;
  g.xres = static_cast<long>(f.numbers.at("xres"));
  g.yres = static_cast<long>(f.numbers.at("yres"));
  g.xreal = f.numbers.at("xreal");
  g.yreal = f.numbers.at("yreal");
  if (f.numbers.count("xoff")) g.xoff = f.numbers.at("xoff");
  if (f.numbers.count("yoff")) g.yoff = f.numbers.at("yoff");
  g.data = f.arrays.at("data");
  if (top.objects.count("/0/mask")) g.mask = top.objects.at("/0/mask").arrays.at("data");
  return g;
}

}  // namespace vmsim_test
