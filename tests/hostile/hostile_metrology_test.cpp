// Hostile surface files (the metrology issue: "truncated, corrupted and hostile files (bad zip, wrong sizes, huge
// declared dimensions) give a clear error without crashing or allocating unbounded memory"). Deterministic mutants
// of X3P, SDF, CSV, .sur and ASCII grid files go through metrology::read_surface_file (and read_x3p), compiled with
// AddressSanitizer and UBSan (tests/hostile/CMakeLists.txt). The only acceptable outcomes are success or a
// core::Error whose message starts with the file's name. Memory: this executable caps every single allocation at
// 1 GiB (__asan_default_options below), so a reader that sizes a buffer from a declared dimension before checking
// it against the data aborts the run and names the input. Each input must finish within 20 s (a hang guard).
#include "core/error.hpp"
#include "core/hash.hpp"
#include "metrology/grid_io.hpp"
#include "metrology/sdf.hpp"
#include "metrology/sur.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"

#include <gtest/gtest.h>
#include <sanitizer/common_interface_defs.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <typeinfo>
#include <vector>

// Any single allocation above 1 GiB is a failure here (no hostile input in this file is meant to need one).
extern "C" const char* __asan_default_options() { return "max_allocation_size_mb=1024:allocator_may_return_null=0"; }

namespace vmsim::metrology {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr double kInputLimitS = 20.0;
constexpr double kWatchdogS = 60.0;

char g_current[1024] = "(none)";
std::atomic<std::int64_t> g_started_ns{0};

void set_current(const std::string& what) {
  std::snprintf(g_current, sizeof g_current, "%s", what.c_str());
  g_started_ns = Clock::now().time_since_epoch().count();
}

void on_sanitizer_death() {
  std::fprintf(stderr, "\nhostile: the sanitizer stopped the process while reading %s\n", g_current);
}

void start_watchdog() {
  static std::once_flag once;
  std::call_once(once, [] {
    __sanitizer_set_death_callback(on_sanitizer_death);
    std::thread([] {
      for (;;) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        const std::int64_t started = g_started_ns.load();
        if (started == 0) continue;
        const double s =
            std::chrono::duration<double>(Clock::duration(Clock::now().time_since_epoch().count() - started)).count();
        if (s > kWatchdogS) {
          std::fprintf(stderr, "\nhostile: HANG: still reading %s after %.0f s\n", g_current, s);
          std::fflush(stderr);
          std::_Exit(3);
        }
      }
    }).detach();
  });
}

// splitmix64: the same sequence on every platform.
struct Rng {
  std::uint64_t s;
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  std::size_t below(std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(next() % n); }
};

struct Mutant {
  std::string what, bytes;
};

fs::path work_dir(const std::string& name) {
  const fs::path d = fs::path(VMSIM_BINARY_DIR) / "tests" / "hostile" / "work" / ("metrology-" + name);
  fs::create_directories(d);
  return d;
}

void write_file(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << bytes;
}

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// ---- mutation ----

const char* const kNumbers[] = {"1e400",
                                "-1e400",
                                "NaN",
                                "nan",
                                "inf",
                                "-1",
                                "0",
                                "-0",
                                "1e-320",
                                "4294967295",
                                "4294967296",
                                "268435457",
                                "65535",
                                "65536",
                                "2147483648",
                                "-2147483649",
                                "99999999999999999999",
                                "18446744073709551616",
                                "0x10",
                                "1e",
                                ".",
                                ""};
const char* const kGarbage[] = {"\xff\xfe", "\x00\x00",     "<",  ">",    "</", "<!--", "]]>",  "&",  "&amp;",
                                "&#0;",     "&#xFFFFFFFF;", ";",  ";;;",  ",",  ",,,",  "*",    "**", "=",
                                "#",        "# x0_mm=",     "\r", "\n\n", "\t", "NaN",  "1e400"};

// Byte-level mutants (any format), then text-level ones (for text formats: lines and numbers).
std::vector<Mutant> mutate(const std::string& base, std::size_t count, const std::string& seed_name, bool text) {
  std::uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : seed_name) h = (h ^ c) * 1099511628211ULL;
  Rng rng{h};
  std::vector<Mutant> out;
  out.push_back({"empty file", ""});
  out.push_back({"unmutated", base});
  const std::size_t cuts = std::min<std::size_t>(count / 4, base.size());
  for (std::size_t i = 1; i <= cuts; ++i) {
    const std::size_t at = base.size() * i / (cuts + 1);
    out.push_back({"truncated at byte " + std::to_string(at), base.substr(0, at)});
  }
  const int kinds = text ? 9 : 5;
  for (std::size_t i = 0; out.size() < count + 2; ++i) {
    std::string t = base;
    std::string what;
    const std::size_t pos = rng.below(t.size() + 1);
    switch (static_cast<int>(i % static_cast<std::size_t>(kinds))) {
      case 0: {
        if (t.empty()) continue;
        const std::size_t p = rng.below(t.size());
        const int bit = static_cast<int>(rng.below(8));
        t[p] = static_cast<char>(t[p] ^ (1 << bit));
        what = "bit " + std::to_string(bit) + " flipped at byte " + std::to_string(p);
        break;
      }
      case 1: {
        const std::size_t n = 1 + rng.below(8);
        for (std::size_t k = 0; k < n && !t.empty(); ++k) t[rng.below(t.size())] = static_cast<char>(rng.below(256));
        what = std::to_string(n) + " random bytes overwritten";
        break;
      }
      case 2: {
        std::string bin;
        const std::size_t n = 1 + rng.below(300);
        for (std::size_t k = 0; k < n; ++k) bin += static_cast<char>(rng.below(256));
        t.insert(pos, bin);
        what = std::to_string(n) + " random bytes inserted at " + std::to_string(pos);
        break;
      }
      case 3: {
        if (t.empty()) continue;
        const std::size_t p = rng.below(t.size()), n = 1 + rng.below(64);
        t.erase(p, n);
        what = std::to_string(n) + " bytes deleted at " + std::to_string(p);
        break;
      }
      case 4: {  // a 4-byte little-endian field overwritten with an extreme value
        if (t.size() < 4) continue;
        static const std::uint32_t kExtreme[] = {0,           1,           0xffffffffu, 0x7fffffffu,
                                                 0x80000000u, 0x10000000u, 0xffffu,     0x10000u};
        const std::uint32_t v = kExtreme[rng.below(std::size(kExtreme))];
        const std::size_t p = rng.below(t.size() - 3);
        std::memcpy(&t[p], &v, 4);
        what = "uint32 " + std::to_string(v) + " written at byte " + std::to_string(p);
        break;
      }
      case 5: {  // a number replaced by an extreme one
        std::size_t p = t.find_first_of("0123456789", pos);
        if (p == std::string::npos) p = t.find_first_of("0123456789");
        if (p == std::string::npos) continue;
        std::size_t e = p;
        while (e < t.size() && (std::isdigit(static_cast<unsigned char>(t[e])) || t[e] == '.' || t[e] == 'E' ||
                                t[e] == 'e' || t[e] == '-'))
          ++e;
        const char* n = kNumbers[rng.below(std::size(kNumbers))];
        t.replace(p, e - p, n);
        what = "number at byte " + std::to_string(p) + " replaced by \"" + n + "\"";
        break;
      }
      case 6: {  // a garbage token
        const char* g = kGarbage[rng.below(std::size(kGarbage))];
        t.insert(pos, g, std::strlen(g) ? std::strlen(g) : 2);
        what = "garbage token inserted at byte " + std::to_string(pos);
        break;
      }
      case 7: {  // a line deleted or duplicated many times
        std::vector<std::string> lines;
        std::string cur;
        for (char c : t) {
          cur += c;
          if (c == '\n') lines.push_back(cur), cur.clear();
        }
        if (!cur.empty()) lines.push_back(cur);
        if (lines.empty()) continue;
        const std::size_t l = rng.below(lines.size());
        if (rng.below(2)) {
          lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(l));
          what = "line " + std::to_string(l + 1) + " deleted";
        } else {
          const std::size_t n = rng.below(3) == 0 ? 5000 : 2;
          lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(l), n, lines[l]);
          what = "line " + std::to_string(l + 1) + " repeated " + std::to_string(n) + " times";
        }
        t.clear();
        for (const auto& s : lines) t += s;
        break;
      }
      case 8: {  // a very long line
        static const char* kUnits[] = {"9", "1,", "nan ", " ", "<a>", "-"};
        const char* u = kUnits[rng.below(std::size(kUnits))];
        std::string longline;
        while (longline.size() < 200000) longline += u;
        t.insert(pos, longline + "\n");
        what = std::string("200 kB of \"") + u + "\" inserted at byte " + std::to_string(pos);
        break;
      }
    }
    for (char& c : what)
      if (static_cast<unsigned char>(c) < 0x20) c = '?';
    out.push_back({what, std::move(t)});
  }
  return out;
}

// ---- a zip writer (stored entries), so headers can lie ----

struct Entry {
  std::string name, data;
  std::int64_t declared_size = -1;  // header's uncompressed (and compressed) size; -1: the true size
  bool bad_crc = false;
  std::uint16_t flags = 0;  // general purpose flags (1: encrypted)
};

void put16(std::string& s, std::uint16_t v) { s += static_cast<char>(v & 0xff), s += static_cast<char>(v >> 8); }
void put32(std::string& s, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) s += static_cast<char>((v >> (8 * k)) & 0xff);
}

std::string zip_of(const std::vector<Entry>& entries) {
  std::string out, central;
  for (const Entry& e : entries) {
    const std::uint32_t crc = static_cast<std::uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(e.data.data()),
                                                               static_cast<uInt>(e.data.size()))) ^
                              (e.bad_crc ? 0x5a5a5a5au : 0u);
    const std::uint32_t size =
        e.declared_size >= 0 ? static_cast<std::uint32_t>(e.declared_size) : static_cast<std::uint32_t>(e.data.size());
    const std::uint32_t offset = static_cast<std::uint32_t>(out.size());
    put32(out, 0x04034b50), put16(out, 20), put16(out, e.flags), put16(out, 0), put16(out, 0), put16(out, 0x21);
    put32(out, crc), put32(out, size), put32(out, size), put16(out, static_cast<std::uint16_t>(e.name.size())),
        put16(out, 0);
    out += e.name;
    out += e.data;
    put32(central, 0x02014b50), put16(central, 20), put16(central, 20), put16(central, e.flags), put16(central, 0);
    put16(central, 0), put16(central, 0x21), put32(central, crc), put32(central, size), put32(central, size);
    put16(central, static_cast<std::uint16_t>(e.name.size())), put16(central, 0), put16(central, 0), put16(central, 0);
    put16(central, 0), put32(central, 0), put32(central, offset);
    central += e.name;
  }
  const std::uint32_t cd = static_cast<std::uint32_t>(out.size());
  out += central;
  put32(out, 0x06054b50), put16(out, 0), put16(out, 0), put16(out, static_cast<std::uint16_t>(entries.size()));
  put16(out, static_cast<std::uint16_t>(entries.size())), put32(out, static_cast<std::uint32_t>(central.size())),
      put32(out, cd);
  put16(out, 0);
  return out;
}

// md5checksum.hex's line for main.xml, through the same core MD5 the reader checks with.
std::string md5_line(const std::string& xml) { return core::md5_hex(xml) + " *main.xml\n"; }

// A main.xml of a SUR matrix with the pieces a crafted case replaces.
struct XmlParts {
  std::string feature = "SUR",
              cx = "<AxisType>I</AxisType><DataType>D</DataType><Increment>1E-05</Increment><Offset>0</Offset>";
  std::string cy = "<AxisType>I</AxisType><DataType>D</DataType><Increment>1E-05</Increment><Offset>0</Offset>";
  std::string cz = "<AxisType>A</AxisType><DataType>D</DataType><Increment>1</Increment><Offset>0</Offset>";
  std::string dims = "<MatrixDimension><SizeX>4</SizeX><SizeY>3</SizeY><SizeZ>1</SizeZ></MatrixDimension>";
  std::string data =
      "<DataLink><PointDataLink>bindata/data.bin</PointDataLink><MD5ChecksumPointData></MD5ChecksumPointData></"
      "DataLink>";
  std::string extra;  // after Record4
};
std::string xml_of(const XmlParts& p) {
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<p:ISO5436_2 xmlns:p=\"http://www.opengps.eu/2008/ISO5436_2\">"
         "<Record1><Revision>ISO5436 - 2000</Revision><FeatureType>" +
         p.feature + "</FeatureType><Axes><CX>" + p.cx + "</CX><CY>" + p.cy + "</CY><CZ>" + p.cz +
         "</CZ></Axes></Record1><Record3>" + p.dims + p.data +
         "</Record3><Record4><ChecksumFile>md5checksum.hex</ChecksumFile></Record4>" + p.extra + "</p:ISO5436_2>\n";
}

std::string doubles(std::size_t n, double v = 1e-6) {
  std::string s(n * 8, '\0');
  for (std::size_t k = 0; k < n; ++k) std::memcpy(&s[k * 8], &v, 8);
  return s;
}

// ---- running ----

struct Outcome {
  std::size_t inputs = 0, ok = 0, errors = 0;
  std::string base_error;
  double slowest_s = 0;
  std::string slowest;
};

Outcome run(const std::string& sample, const std::vector<Mutant>& mutants, const fs::path& input,
            const std::function<void(const fs::path&)>& read) {
  start_watchdog();
  Outcome o;
  int kept = 0;
  const std::string prefix = input.string() + ":";
  const auto keep = [&](const Mutant& m, const std::string& problem) {
    const fs::path copy = input.parent_path() / ("failure-" + std::to_string(++kept) + input.extension().string());
    if (kept <= 20) write_file(copy, m.bytes);
    ADD_FAILURE() << sample << ": " << m.what << ": " << problem << "\n  input kept as " << copy.string();
  };
  for (const Mutant& m : mutants) {
    write_file(input, m.bytes);
    set_current(sample + " / " + m.what + " (input: " + input.string() + ")");
    const auto t0 = Clock::now();
    try {
      read(input);
      ++o.ok;
    } catch (const core::Error& e) {
      ++o.errors;
      const std::string msg = e.what();
      if (m.what == "unmutated") o.base_error = msg;
      if (msg.rfind(prefix, 0) != 0) keep(m, "core::Error does not start with the file name: " + msg.substr(0, 300));
    } catch (const std::exception& e) {
      keep(m, std::string("exception other than core::Error (") + typeid(e).name() +
                  "): " + std::string(e.what()).substr(0, 300));
    } catch (...) {
      keep(m, "unknown exception type");
    }
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    g_started_ns = 0;
    ++o.inputs;
    if (s > o.slowest_s) o.slowest_s = s, o.slowest = m.what;
    if (s > kInputLimitS) keep(m, "took " + std::to_string(s) + " s");
  }
  std::printf("[ hostile  ] %s: %zu inputs, %zu read, %zu clean errors; slowest %.3f s (%s)\n", sample.c_str(),
              o.inputs, o.ok, o.errors, o.slowest_s, o.slowest.c_str());
  return o;
}

void read_any(const fs::path& p) { (void)read_surface_file(p); }
void read_x3p_any(const fs::path& p) {
  (void)read_x3p(p);
  (void)read_surface_file(p);
}

core::HeightGrid small_grid() {
  core::HeightGrid g;
  g.x0_mm = -1.5, g.y0_mm = 2.25, g.dx_mm = 0.01, g.dy_mm = 0.02;
  g.z_mm.resize(6, 9);
  for (Eigen::Index j = 0; j < 6; ++j)
    for (Eigen::Index i = 0; i < 9; ++i)
      g.z_mm(j, i) = 0.001 * static_cast<double>(i * i) - 0.0007 * static_cast<double>(j) + 1.0 / 3.0;
  g.z_mm(2, 3) = NAN;
  return g;
}

std::string written(const std::string& ext, const std::function<void(const fs::path&)>& write) {
  const fs::path p = work_dir("samples") / ("sample" + ext);
  write(p);
  return read_file(p);
}

fs::path shared_surface() { return fs::path(VMSIM_SHARED_DIR) / "data" / "surface"; }

}  // namespace

TEST(HostileMetrology, X3pWrittenByVmsimByteMutants) {
  const std::string base = written(".x3p", [](const fs::path& p) { write_x3p(p, small_grid()); });
  const fs::path input = work_dir("x3p-vmsim") / "scan.x3p";
  const Outcome o = run("X3P (vmsim)", mutate(base, 700, "x3p-vmsim", false), input, read_x3p_any);
  EXPECT_EQ(o.base_error, "") << "the sample itself must read";
}

TEST(HostileMetrology, X3pSharedSamplesByteMutants) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(shared_surface(), ec))
    if (e.path().extension() == ".x3p") files.push_back(e.path());
  if (files.empty()) GTEST_SKIP() << shared_surface() << " has no .x3p (a fresh clone has no ../shared)";
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) {
    const fs::path input = work_dir("x3p-shared") / f.filename();
    const Outcome o = run("X3P " + f.filename().string(), mutate(read_file(f), 250, f.filename().string(), false),
                          input, [](const fs::path& p) { (void)read_x3p(p); });
    EXPECT_EQ(o.base_error, "") << f;
  }
}

TEST(HostileMetrology, X3pMainXmlMutantsInValidZips) {
  // Text mutants of a complete main.xml, re-zipped with data.bin, valid.bin and a matching md5checksum.hex (so the
  // parser, not the checksum, meets them) and once more with the original checksum.
  XmlParts parts;
  const std::string data = doubles(12), valid = std::string("\xff\x0e", 2);
  parts.data =
      "<DataLink><PointDataLink>bindata/data.bin</PointDataLink><MD5ChecksumPointData></MD5ChecksumPointData>"
      "<ValidPointsLink>bindata/valid.bin</ValidPointsLink><MD5ChecksumValidPoints></MD5ChecksumValidPoints></"
      "DataLink>";
  const std::string xml = xml_of(parts);
  std::vector<Mutant> mutants;
  for (const Mutant& m : mutate(xml, 600, "main.xml", true)) {
    mutants.push_back({m.what + ", checksum matching", zip_of({{"main.xml", m.bytes},
                                                               {"bindata/data.bin", data},
                                                               {"bindata/valid.bin", valid},
                                                               {"md5checksum.hex", md5_line(m.bytes)}})});
    if (mutants.size() % 3 == 0)
      mutants.push_back({m.what + ", checksum stale", zip_of({{"main.xml", m.bytes},
                                                              {"bindata/data.bin", data},
                                                              {"bindata/valid.bin", valid},
                                                              {"md5checksum.hex", md5_line(xml)}})});
  }
  const fs::path input = work_dir("x3p-xml") / "scan.x3p";
  const Outcome o = run("X3P main.xml mutants", mutants, input, read_x3p_any);
}

TEST(HostileMetrology, X3pCraftedArchives) {
  std::vector<Mutant> m;
  const auto add = [&](const std::string& what, const XmlParts& p, std::vector<Entry> extra, bool with_data = true) {
    std::vector<Entry> e = {{"main.xml", xml_of(p)}};
    if (with_data) e.push_back({"bindata/data.bin", doubles(12)});
    for (auto& x : extra) e.push_back(std::move(x));
    e.push_back({"md5checksum.hex", md5_line(xml_of(p))});
    m.push_back({what, zip_of(e)});
  };
  XmlParts p;
  add("well formed (control)", p, {});
  for (const char* dims :
       {"<SizeX>4294967295</SizeX><SizeY>4294967295</SizeY><SizeZ>1</SizeZ>",
        "<SizeX>268435457</SizeX><SizeY>1</SizeY><SizeZ>1</SizeZ>",
        "<SizeX>16384</SizeX><SizeY>16384</SizeY><SizeZ>1</SizeZ>",
        "<SizeX>100000</SizeX><SizeY>100000</SizeY><SizeZ>1</SizeZ>",
        "<SizeX>999999999999999999</SizeX><SizeY>1</SizeY><SizeZ>1</SizeZ>",
        "<SizeX>18446744073709551616</SizeX><SizeY>1</SizeY><SizeZ>1</SizeZ>",
        "<SizeX>0</SizeX><SizeY>3</SizeY><SizeZ>1</SizeZ>", "<SizeX>-4</SizeX><SizeY>3</SizeY><SizeZ>1</SizeZ>",
        "<SizeX>4</SizeX><SizeY>3</SizeY><SizeZ>7</SizeZ>", "<SizeX>4</SizeX><SizeY>3</SizeY>",
        "<SizeX>4.5</SizeX><SizeY>3</SizeY><SizeZ>1</SizeZ>", "<SizeX> 4 </SizeX><SizeY>3</SizeY><SizeZ>1</SizeZ>"}) {
    XmlParts q = p;
    q.dims = std::string("<MatrixDimension>") + dims + "</MatrixDimension>";
    add(std::string("dimensions ") + dims, q, {});
  }
  // A data.bin whose zip headers declare the 2 GiB that 16384 x 16384 doubles need, holding 96 bytes.
  {
    XmlParts q = p;
    q.dims = "<MatrixDimension><SizeX>16384</SizeX><SizeY>16384</SizeY><SizeZ>1</SizeZ></MatrixDimension>";
    std::vector<Entry> e = {{"main.xml", xml_of(q)},
                            {"bindata/data.bin", doubles(12), 16384LL * 16384 * 8},
                            {"md5checksum.hex", md5_line(xml_of(q))}};
    m.push_back({"data.bin declares 2 GiB, holds 96 bytes", zip_of(e)});
    e[1].declared_size = 0xffffffffLL;
    m.push_back({"data.bin declares 4 GiB, holds 96 bytes", zip_of(e)});
  }
  {
    std::vector<Entry> e = {
        {"main.xml", xml_of(p)}, {"bindata/data.bin", doubles(12)}, {"md5checksum.hex", md5_line(xml_of(p))}};
    e[1].bad_crc = true;
    m.push_back({"data.bin with a wrong CRC", zip_of(e)});
    e[1].bad_crc = false;
    e[1].flags = 1;
    m.push_back({"data.bin flagged encrypted", zip_of(e)});
    e[1].flags = 0;
    e[1].declared_size = 200;
    m.push_back({"data.bin declares more bytes than the archive has", zip_of(e)});
    e[1].declared_size = 40;
    m.push_back({"data.bin declares fewer bytes than it holds", zip_of(e)});
    e[0].declared_size = 0x7fffffff;
    m.push_back({"main.xml declares 2 GiB", zip_of(e)});
  }
  add("data.bin too short", p, {}, false);
  {
    std::vector<Entry> e = {
        {"main.xml", xml_of(p)}, {"bindata/data.bin", doubles(11)}, {"md5checksum.hex", md5_line(xml_of(p))}};
    m.push_back({"data.bin one point short", zip_of(e)});
    e[1].data = doubles(13);
    m.push_back({"data.bin one point long", zip_of(e)});
    e[1].data = doubles(12, std::numeric_limits<double>::quiet_NaN());
    m.push_back({"data.bin all NaN", zip_of(e)});
    e[1].data = doubles(12, 1e308);
    m.push_back({"data.bin 1e308 m heights", zip_of(e)});
    e[2].data = "0123456789abcdef0123456789abcdef *main.xml\n";
    m.push_back({"md5checksum.hex wrong", zip_of(e)});
    e[2].data = std::string(5000, 'z');
    m.push_back({"md5checksum.hex 5000 bytes of garbage", zip_of(e)});
  }
  for (const char* link : {"../../etc/passwd", "/bindata/data.bin", "bindata/", "", "bindata/data.bin\x01",
                           "md5checksum.hex", "main.xml"}) {
    XmlParts q = p;
    q.data = std::string("<DataLink><PointDataLink>") + link +
             "</PointDataLink><MD5ChecksumPointData></MD5ChecksumPointData></DataLink>";
    add(std::string("PointDataLink \"") + link + "\"", q, {});
  }
  {
    XmlParts q = p;
    q.data =
        "<DataLink><PointDataLink>bindata/data.bin</PointDataLink><MD5ChecksumPointData>00</MD5ChecksumPointData>"
        "<ValidPointsLink>bindata/valid.bin</ValidPointsLink><MD5ChecksumValidPoints></MD5ChecksumValidPoints></"
        "DataLink>";
    add("data.bin MD5 wrong", q, {{"bindata/valid.bin", std::string(2, '\xff')}});
    q.data =
        "<DataLink><PointDataLink>bindata/data.bin</PointDataLink><MD5ChecksumPointData></MD5ChecksumPointData>"
        "<ValidPointsLink>bindata/valid.bin</ValidPointsLink><MD5ChecksumValidPoints></MD5ChecksumValidPoints></"
        "DataLink>";
    add("valid.bin missing", q, {});
    add("valid.bin too long", q, {{"bindata/valid.bin", std::string(1000, '\xff')}});
    add("valid.bin empty", q, {{"bindata/valid.bin", ""}});
    add("valid.bin all invalid", q, {{"bindata/valid.bin", std::string(2, '\0')}});
  }
  for (const char* axis :
       {"<AxisType>I</AxisType><DataType>D</DataType><Increment>0</Increment><Offset>0</Offset>",
        "<AxisType>I</AxisType><DataType>D</DataType><Increment>-1E-05</Increment><Offset>0</Offset>",
        "<AxisType>I</AxisType><DataType>D</DataType><Increment>1e400</Increment><Offset>0</Offset>",
        "<AxisType>I</AxisType><DataType>D</DataType><Increment>1e-400</Increment><Offset>0</Offset>",
        "<AxisType>I</AxisType><DataType>D</DataType><Increment>NaN</Increment><Offset>0</Offset>",
        "<AxisType>I</AxisType><DataType>D</DataType><Increment>1E-05</Increment><Offset>1e400</Offset>",
        "<AxisType>I</AxisType><DataType>D</DataType><Increment>1E-05</Increment><Offset>1e300</Offset>",
        "<AxisType>I</AxisType><DataType>D</DataType><Increment></Increment>",
        "<AxisType>Q</AxisType><DataType>D</DataType><Increment>1</Increment>",
        "<AxisType>A</AxisType><DataType>Z</DataType><Increment>1</Increment>",
        "<AxisType>A</AxisType><DataType>I</DataType><Increment>1e-3</Increment>",
        "<AxisType>A</AxisType><DataType>L</DataType><Increment>1</Increment><Offset>-5</Offset>", ""}) {
    XmlParts q = p;
    q.cx = axis;
    add(std::string("CX ") + axis, q, {});
    XmlParts r = p;
    r.cz = axis;
    add(std::string("CZ ") + axis, r, {});
  }
  // Absolute x stored per point (int16), irregular or constant.
  {
    XmlParts q = p;
    q.cx = "<AxisType>A</AxisType><DataType>I</DataType><Increment>1e-3</Increment><Offset>0</Offset>";
    std::string d;
    for (int k = 0; k < 12; ++k) {
      const std::int16_t x = static_cast<std::int16_t>(k % 4 == 2 ? 7 : k % 4);
      d.append(reinterpret_cast<const char*>(&x), 2);
      const double z = 1e-6 * k;
      d.append(reinterpret_cast<const char*>(&z), 8);
    }
    m.push_back({"absolute CX, irregular",
                 zip_of({{"main.xml", xml_of(q)}, {"bindata/data.bin", d}, {"md5checksum.hex", md5_line(xml_of(q))}})});
  }
  // Data in the XML: counts that disagree, values that are not numbers, a list of a billion billion points.
  const std::string datum12 = [] {
    std::string s;
    for (int k = 0; k < 12; ++k) s += "<Datum>1e-6</Datum>";
    return s;
  }();
  for (const std::string& list :
       {std::string("<DataList>") + datum12 + "<Datum>1</Datum></DataList>",
        std::string("<DataList><Datum>1</Datum></DataList>"), std::string("<DataList></DataList>"),
        std::string("<DataList>") + datum12.substr(0, datum12.size() - 19) + "<Datum>abc</Datum></DataList>",
        std::string("<DataList>") + datum12.substr(0, datum12.size() - 19) + "<Datum>1;2;3;4;5</Datum></DataList>",
        std::string("<DataList>") + datum12.substr(0, datum12.size() - 19) + "<Datum><x/></Datum></DataList>",
        std::string("<DataList>") + datum12.substr(0, datum12.size() - 19) + "<Datum>;</Datum></DataList>"}) {
    XmlParts q = p;
    q.data = list;
    add("DataList " + list.substr(0, 60), q, {}, false);
  }
  for (const char* dims : {"<ListDimension>1000000000000000000</ListDimension>", "<ListDimension>3</ListDimension>",
                           "<ListDimension>0</ListDimension>"}) {
    XmlParts q = p;
    q.feature = "PCL";
    q.cx = q.cy = "<AxisType>A</AxisType><DataType>D</DataType><Increment>1</Increment>";
    q.dims = dims;
    q.data = "<DataList><Datum>0;0;1</Datum><Datum>1e9;1e9;2</Datum><Datum>1e-9;0;3</Datum></DataList>";
    add(std::string("PCL ") + dims + " (points far apart)", q, {}, false);
  }
  // XML that is not a document, nested 100000 deep, or an entity bomb (pugixml does not expand DTD entities).
  for (const std::string& xml :
       {std::string(), std::string("\xef\xbb\xbf"), std::string("<notx3p/>"), std::string(100000, '<'),
        [] {
          std::string s = "<p:ISO5436_2 xmlns:p=\"x\"><Record1>";
          for (int k = 0; k < 100000; ++k) s += "<a>";
          return s;
        }(),
        std::string("<!DOCTYPE l [<!ENTITY a \"aaaaaaaaaa\"><!ENTITY b \"&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;\">"
                    "<!ENTITY c \"&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;\">]><p:ISO5436_2>&c;&c;&c;</p:ISO5436_2>")}) {
    m.push_back({"main.xml: " + std::to_string(xml.size()) + " bytes of non-X3P XML",
                 zip_of({{"main.xml", xml}, {"bindata/data.bin", doubles(12)}, {"md5checksum.hex", md5_line(xml)}})});
  }
  m.push_back({"no main.xml", zip_of({{"bindata/data.bin", doubles(12)}})});
  m.push_back({"empty zip", zip_of({})});
  m.push_back(
      {"two main.xml", zip_of({{"main.xml", xml_of(p)}, {"main.xml", "<x/>"}, {"bindata/data.bin", doubles(12)}})});
  const fs::path input = work_dir("x3p-crafted") / "scan.x3p";
  const Outcome o = run("X3P crafted archives", m, input, read_x3p_any);
  EXPECT_GE(o.ok, 1u) << "the control archive must read";
}

TEST(HostileMetrology, SdfAscii) {
  std::vector<std::pair<std::string, std::string>> bases = {
      {"vmsim", written(".sdf", [](const fs::path& p) { write_sdf(p, small_grid()); })}};
  if (fs::exists(shared_surface() / "sdf-1.sdf"))
    bases.emplace_back("sdf-1", read_file(shared_surface() / "sdf-1.sdf"));
  for (const auto& [name, base] : bases) {
    std::vector<Mutant> m = mutate(base, 600, "sdf-" + name, true);
    // Declared sizes far beyond the data.
    std::string big = base;
    const auto at = big.find("NumPoints");
    if (at != std::string::npos) {
      big.insert(at, "NumPoints = 1048576\nNumProfiles = 1048576\n");
      m.push_back({"NumPoints x NumProfiles = 2^40 declared first", big});
    }
    const Outcome o = run("SDF ASCII " + name, m, work_dir("sdf") / "scan.sdf", read_any);
    EXPECT_EQ(o.base_error, "") << name;
  }
}

TEST(HostileMetrology, SdfBinary) {
  // An 81-byte binary header (ISO 25178-71) with 4 x 3 doubles, then mutants and extreme header fields.
  std::string h = "bISO-1.0" + std::string(10, 'M') + std::string(12, '0') + std::string(12, '0');
  const auto u16 = [](std::uint16_t v) { return std::string(reinterpret_cast<const char*>(&v), 2); };
  const auto f64 = [](double v) { return std::string(reinterpret_cast<const char*>(&v), 8); };
  const auto header = [&](std::uint16_t nx, std::uint16_t ny, double xs, double zs, char type) {
    return h + u16(nx) + u16(ny) + f64(xs) + f64(xs) + f64(zs) + f64(1e-9) + std::string(1, '\0') +
           std::string(1, type) + std::string(1, '\0');
  };
  const std::string base = header(4, 3, 1e-5, 1e-6, 7) + doubles(12, 1.5);
  std::vector<Mutant> m = mutate(base, 500, "sdf-binary", false);
  m.push_back({"65535 x 65535 declared, 12 points present", header(65535, 65535, 1e-5, 1e-6, 7) + doubles(12)});
  m.push_back({"data type 200", header(4, 3, 1e-5, 1e-6, static_cast<char>(200)) + doubles(12)});
  m.push_back({"zero spacing", header(4, 3, 0, 1e-6, 7) + doubles(12)});
  m.push_back({"NaN z scale", header(4, 3, 1e-5, std::numeric_limits<double>::quiet_NaN(), 7) + doubles(12)});
  m.push_back({"int16 with the bad-data value", header(4, 3, 1e-5, 1e-6, 5) + std::string(24, '\0') + u16(0x8000)});
  const Outcome o = run("SDF binary", m, work_dir("sdf-binary") / "scan.sdf", read_any);
  EXPECT_EQ(o.base_error, "");
}

TEST(HostileMetrology, VmsimCsv) {
  const std::string base = written(".csv", [](const fs::path& p) { write_height_csv(p, small_grid()); });
  std::vector<Mutant> m = mutate(base, 600, "csv", true);
  m.push_back(
      {"header nx=100000 ny=100000, 3 values", "# x0_mm=0 y0_mm=0 dx_mm=1 dy_mm=1 nx=100000 ny=100000\n1,2,3\n"});
  m.push_back({"header nx=16384 ny=16384, no rows", "# x0_mm=0 y0_mm=0 dx_mm=1 dy_mm=1 nx=16384 ny=16384\n"});
  const Outcome o = run("vmsim CSV", m, work_dir("csv") / "grid.csv", read_any);
  EXPECT_EQ(o.base_error, "");
}

TEST(HostileMetrology, AsciiPointAndMatrixGrids) {
  const std::string xyz = written(".xyz", [](const fs::path& p) { write_xyz(p, small_grid()); });
  std::vector<Mutant> m = mutate(xyz, 500, "xyz", true);
  m.push_back({"two points a light year apart", "0 0 1\n9.46e18 9.46e18 2\n1e-9 0 3\n"});
  m.push_back({"points on a 1e-300 lattice", "0 0 1\n1e-300 0 2\n0 1e-300 3\n"});
  Outcome o = run("ASCII x y z", m, work_dir("xyz") / "points.xyz", read_any);
  EXPECT_EQ(o.base_error, "");
  const std::string mat =
      "# Channel: Height\n# Width: 90 um\n# Height: 60 um\n# Value units: m\n"
      "1e-6 2e-6 3e-6\n4e-6 NaN 6e-6\n7e-6 8e-6 9e-6\n";
  o = run("ASCII matrix", mutate(mat, 500, "matrix", true), work_dir("matrix") / "grid.txt", read_any);
  EXPECT_EQ(o.base_error, "");
}

TEST(HostileMetrology, DigitalSurf) {
  const std::string base = written(".sur", [](const fs::path& p) { write_sur(p, small_grid()); });
  std::vector<Mutant> m = mutate(base, 600, "sur", false);
  const auto field = [&](std::size_t off, std::int64_t v, int bytes, const std::string& what) {
    std::string t = base;
    std::memcpy(&t[off], &v, static_cast<std::size_t>(bytes));  // little-endian low bytes
    m.push_back({what, t});
  };
  for (std::int64_t v : {0LL, -1LL, 65535LL, 2147483647LL, -2147483648LL, 16384LL}) {
    field(108, v, 4, "points per line " + std::to_string(v));
    field(112, v, 4, "lines " + std::to_string(v));
    field(116, v, 4, "total points " + std::to_string(v));
  }
  for (std::int64_t v : {0LL, 8LL, 64LL, -16LL}) field(98, v, 2, "bits per point " + std::to_string(v));
  for (std::int64_t v : {65535LL, 32767LL, -1LL}) {
    field(334, v, 2, "comment size " + std::to_string(v));
    field(336, v, 2, "private size " + std::to_string(v));
  }
  field(18, 5, 2, "object type 5");
  field(100, -2147483647LL - 1, 4, "Zmin = INT32_MIN");
  {
    std::string t = base;
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    std::memcpy(&t[128], &nan, 4);
    m.push_back({"z spacing NaN", t});
    std::memcpy(&t[120], &inf, 4);
    m.push_back({"x spacing inf", t});
    t = base;
    std::memcpy(&t[180], "furlongs\0\0\0\0\0\0\0\0", 16);
    m.push_back({"x unit furlongs", t});
  }
  // Compressed: stream tables that lie.
  {
    std::string t = base.substr(0, 512);
    std::memcpy(&t[0], "DSCOMPRESSED", 12);
    const auto put = [&](std::uint32_t v) { t.append(reinterpret_cast<const char*>(&v), 4); };
    std::string c = t;
    put(1), put(54 * 4), put(8);
    t += "garbage!";
    m.push_back({"compressed, a corrupt stream", t});
    t = c;
    put(1), put(0x7fffffff), put(100);
    m.push_back({"compressed, a stream declaring 2 GiB", t});
    t = c;
    put(0xffffffffu);
    m.push_back({"compressed, 4 billion streams", t});
    t = c;
    std::memcpy(&t[108], "\x00\x40\x00\x00", 4);  // 16384 points per line
    std::memcpy(&t[112], "\x00\x40\x00\x00", 4);  // 16384 lines
    std::memcpy(&t[116], "\x00\x00\x00\x10", 4);  // total 2^28
    put(1), put(0x40000000u), put(64);
    t += std::string(64, 'x');
    m.push_back({"compressed, 1 GiB declared in 64 bytes", t});
  }
  const Outcome o = run("Digital Surf .sur", m, work_dir("sur") / "scan.sur", read_any);
  EXPECT_EQ(o.base_error, "");
}

// The formats issue 17 added: BCR-STM (binary points, a text header), Dektak CSV profiles, gzip-compressed text,
// and the real files of ../shared/data/real/scans when present (X3P laid out by other tools, .sur, BCR).
TEST(HostileMetrology, BcrStm) {
  std::string h =
      "fileformat = bcrstm\nheadersize = 2048\nxpixels = 4\nypixels = 3\nxlength = 400\nylength = 600\n"
      "bit2nm = 0.5\nvoidpixels = 1\nintelmode = 1\n";
  h.resize(2048, ' ');
  for (int k = 0; k < 12; ++k) {
    const std::int16_t v = static_cast<std::int16_t>(k * 100 - 300);
    h.append(reinterpret_cast<const char*>(&v), 2);
  }
  std::vector<Mutant> m = mutate(h, 500, "bcr", false);
  std::string t = h;
  t.replace(t.find("xpixels = 4"), 11, "xpixels = 999999999");
  m.push_back({"a billion points declared", t});
  t = h;
  t.replace(t.find("headersize = 2048"), 17, "headersize = 99999");
  m.push_back({"header larger than the file", t});
  const Outcome o = run("BCR-STM", m, work_dir("bcr") / "scan.bcr", read_any);
  EXPECT_EQ(o.base_error, "");
}

TEST(HostileMetrology, DektakCsv) {
  std::string t =
      "Scan Parameters\r\r\nStylus,Radius: 2.5 \xb5m\r\n\r\r\nScan Data\r\r\nLateral um,Raw Micrometer,\r\n";
  for (int i = 0; i < 40; ++i)
    t += std::to_string(0.15625 * i).substr(0, 5) + "," + std::to_string(0.01 * i) + ",,\r\n";
  const Outcome o = run("Dektak CSV", mutate(t, 500, "dektak", true), work_dir("dektak") / "trace.csv", read_any);
  EXPECT_EQ(o.base_error, "");
}

TEST(HostileMetrology, GzipText) {
  const std::string text =
      "h=3 w=3\npixel size=2 um\ndata unit=rad\nheight conversion factor (-> m)=1e-8\n1 2 3\n4 5 6\n7 8 9\n";
  std::string z(compressBound(static_cast<uLong>(text.size())) + 64, '\0');
  z_stream s{};
  deflateInit2(&s, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY);  // a gzip wrapper
  s.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
  s.avail_in = static_cast<uInt>(text.size());
  s.next_out = reinterpret_cast<Bytef*>(z.data());
  s.avail_out = static_cast<uInt>(z.size());
  deflate(&s, Z_FINISH);
  z.resize(s.total_out);
  deflateEnd(&s);
  std::vector<Mutant> m = mutate(z, 500, "gzip", false);
  m.push_back({"a gzip magic before a zlib stream", [] {
                 std::string big(std::size_t{1} << 20, '0');
                 std::string out(compressBound(static_cast<uLong>(big.size())), '\0');
                 uLongf n = out.size();
                 compress(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(big.data()),
                          big.size());
                 out.resize(n);
                 return std::string("\x1f\x8b", 2) + out;  // a zlib stream behind a gzip magic: corrupt
               }()});
  const Outcome o = run("gzip text", m, work_dir("gzip") / "grid.txt.gz", read_any);
  EXPECT_EQ(o.base_error, "");
}

TEST(HostileMetrology, RealScansByteMutants) {
  const fs::path dir = fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "scans";
  const char* files[] = {"sample-land.x3p", "SurfaceTopography/sur-3.sur", "SurfaceTopography/bcrf-1.bcrf"};
  int ran = 0;
  for (const char* f : files) {
    if (!fs::exists(dir / f)) continue;
    ++ran;
    const std::string base = read_file(dir / f);
    const fs::path name = fs::path(f).filename();
    const Outcome o = run(name.string(), mutate(base, 120, name.string(), false), work_dir("real") / name, read_any);
    EXPECT_EQ(o.base_error, "") << f;
  }
  if (ran == 0) GTEST_SKIP() << dir << " is absent; the real scans are not mutated";
}

}  // namespace vmsim::metrology
