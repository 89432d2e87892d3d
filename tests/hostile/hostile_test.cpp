// Hostile inputs (the issue: "Truncated, garbled or hostile G-code, CL and TOML get a clear error, never a crash
// or hang"). Deterministic mutants of real and built-in samples go through program::read_program, load_machine,
// load_job and core's CSV reader, compiled with AddressSanitizer and UBSan (tests/hostile/CMakeLists.txt). The only
// acceptable outcomes are success, or a core::Error whose message starts with the file's name; any other exception
// fails, a crash aborts the process (the sanitizer report and the input's path are printed), and each input must finish
// within 20 s (a hang guard, not a performance test; a watchdog ends the process after 60 s).
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/job.hpp"
#include "core/machine.hpp"
#include "program/program.hpp"
#include "core/stl.hpp"

#include <gtest/gtest.h>
#include <sanitizer/common_interface_defs.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <ctime>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
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

namespace vmsim::core {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Per input, in CPU time of the reading thread (wall time stretches on a loaded machine): anything slower is
// reported as a hang. The slowest legitimate input takes ~2 s under ASan on an idle core.
constexpr double kInputLimitS = 20.0;
// The G-code reader's bound on work (program::ProgramOptions::max_blocks, 20 M by default) lowered for the mutants:
// a mutant that loops forever (a loop counter reset inside its loop) then ends with the reader's "possible endless
// loop" error after 1 M blocks instead of 20 M (~25 s under ASan). The bound, not its size, is what is tested.
constexpr std::uint64_t kHostileMaxBlocks = 1'000'000;

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}
constexpr double kWatchdogS = 60.0;  // an input still running after this is a real hang: end the process

// ---- what is running now, for the sanitizer's death callback and the watchdog ----

char g_current[1024] = "(none)";
std::atomic<std::int64_t> g_started_ns{0};  // 0: no input running

void set_current(const std::string& what) {
  std::snprintf(g_current, sizeof g_current, "%s", what.c_str());
  g_started_ns = Clock::now().time_since_epoch().count();
}

void on_sanitizer_death() {
  std::fprintf(stderr, "\nhostile: the sanitizer stopped the process while reading %s\n", g_current);
}

// One watchdog for the process: started once, checks every 100 ms.
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

// ---- deterministic mutation ----

// splitmix64: a tiny PRNG whose sequence is the same on every platform (std distributions are not).
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

std::uint64_t fnv1a(const std::string& s) {
  std::uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ULL;
  return h;
}

enum class Flavor { Gcode, Apt, Toml, Stl, Csv };

struct Mutant {
  std::string what;  // how it was made, for failure reports
  std::string text;
};

std::vector<std::string> split_lines(const std::string& s) {
  std::vector<std::string> lines;
  std::string cur;
  for (char c : s) {
    cur += c;
    if (c == '\n') {
      lines.push_back(cur);
      cur.clear();
    }
  }
  if (!cur.empty()) lines.push_back(cur);
  return lines;
}

std::string join(const std::vector<std::string>& lines) {
  std::string s;
  for (const auto& l : lines) s += l;
  return s;
}

// Tokens that break lexers and number parsers, whatever the dialect.
const std::vector<std::string> kGarbage = {"[[[[",
                                           "]]]]",
                                           "((((",
                                           "))))",
                                           "{{{{",
                                           "}}}}",
                                           "1e400",
                                           "-1e400",
                                           "1e-400",
                                           "NaN",
                                           "nan",
                                           "inf",
                                           "-inf",
                                           "99999999999999999999999999",
                                           "-0",
                                           "0x1p9999",
                                           "#",
                                           "##",
                                           "#<",
                                           "#<>",
                                           "<",
                                           ">",
                                           "=",
                                           "==",
                                           "/",
                                           "//",
                                           ",",
                                           ",,,,",
                                           "$",
                                           "$$",
                                           "\"",
                                           "'",
                                           "\\",
                                           ";",
                                           "%",
                                           "O",
                                           "o",
                                           "G",
                                           "X",
                                           "F",
                                           "E",
                                           "e",
                                           ".",
                                           "..",
                                           "-",
                                           "+-",
                                           std::string("\0", 1),
                                           "\xff\xfe",
                                           "\xc3\x28",
                                           "\t",
                                           "\r",
                                           "\r\n",
                                           "\n\n",
                                           "[1/0]",
                                           "SQRT[-1]",
                                           "ATAN[0]/[0]",
                                           "EXP[1000]",
                                           "LN[0]",
                                           "ASIN[2]",
                                           "#5000=",
                                           "#-1",
                                           "#99999999999",
                                           "GOTO/",
                                           "CIRCLE/",
                                           "FEDRAT/",
                                           "\"\"\"",
                                           "'''",
                                           "= [",
                                           "= {",
                                           "a.b.c.d.e.f = 1",
                                           "[x]",
                                           "[[x]]",
                                           "1979-05-27T07:32:00Z",
                                           "true",
                                           "0o777",
                                           "+inf"};

// Whole lines that are legal-looking but hostile for each dialect.
const std::vector<std::string> kGcodeLines = {"G2 X0 Y0 I0 J0\n",
                                              "G2 X1 Y0 R0.1\n",
                                              "G3 X0 Y0 I1 J0 P999999999\n",
                                              "G2 X0 Y0 I1e300 J0\n",
                                              "G1 X1e300 Y-1e300 F1\n",
                                              "G1 X1 F1e-300\n",
                                              "G93 G1 X1 F0\n",
                                              "G1 F-5 X1\n",
                                              "S-1 M3\n",
                                              "T-1 M6\n",
                                              "G4 P1e300\n",
                                              "G4 P-1\n",
                                              "G43 H99999\n",
                                              "G10 L2 P999 X1\n",
                                              "G10 L20 P1 X1e308\n",
                                              "#5999999 = 1\n",
                                              "#1 = [#1 + 1]\n",
                                              "#<_a> = [1e308 * 1e308]\n",
                                              "G1 X[1e308 * 10]\n",
                                              "G1 X[-1e308 - 1e308]\n",
                                              "G1 X[1/0]\n",
                                              "G1 X[0/0]\n",
                                              "G64 P-1\n",
                                              "G5.2 X1 Y1\n",
                                              "G91.1 G2 X1 I1\n",
                                              "G20 G1 X1e307\n",
                                              "M98 P100 L999999999\n",
                                              "M99\n",
                                              "M2\n",
                                              "M30\n",
                                              "%\n",
                                              "o100 sub\n",
                                              "o100 endsub\n",
                                              "o100 call\n",
                                              "o101 while [1]\no101 endwhile\n",
                                              "o102 do\no102 while [1]\n",
                                              "o103 repeat [1e9]\no103 endrepeat\n",
                                              "o104 if [1]\n",
                                              "o105 return\n",
                                              "(msg, hello\n",
                                              "(debug, #1 #2 #<_x>\n",
                                              "(print, [[[\n",
                                              "G38.2 Z-1 F1\n",
                                              "G28\n",
                                              "G30\n",
                                              "G92 X1e308\n",
                                              "G53 G0 X1\n",
                                              "G52 X1\n",
                                              "G33 Z-1 K1\n",
                                              "G76 P1 Z-1 I1 J1 K1\n",
                                              "G81 R1 Z-1 L999999999 F1\n",
                                              "G83 R1 Z-1 Q0 F1\n",
                                              "G41 D99\n",
                                              "G41.1 D-1\n",
                                              "N99999999999999 G1 X1\n"};
const std::vector<std::string> kAptLines = {"CIRCLE/0,0,0,0,0,1,0\n",
                                            "CIRCLE/0,0,0,0,0,1,1e-300\n",
                                            "CIRCLE/1e308,1e308,0,0,0,1,1e308\n",
                                            "GOTO/1e308,1e308,1e308\n",
                                            "GOTO/1,2,3,0,0,0\n",
                                            "GOTO/1,2,3,1e-320,0,0\n",
                                            "FEDRAT/1e-300\n",
                                            "FEDRAT/1e308,IPM\n",
                                            "UNITS/INCHES\n",
                                            "RAPID\n",
                                            "MOVARC/0,0,0,0,0,1,10,ANGLE,1e300\n",
                                            "GODLTA/1e308\n",
                                            "GOHOME\n",
                                            "FROM/1e308,0,0\n",
                                            "TLAXIS/0,0,0\n",
                                            "CUTTER/1e308,1e308\n",
                                            "LOADTL/1e300\n",
                                            "MULTAX/ON\n",
                                            "CYCLE/DRILL,1,MMPM,1,1\n",
                                            "FINI\n",
                                            "$\n",
                                            "$$\n",
                                            "GOTO/$\n",
                                            "PARTNO/$\n",
                                            "INDIRV/0,0,0\n"};
const std::vector<std::string> kTomlLines = {"[machine]\n",
                                             "[[axes]]\n",
                                             "[job]\n",
                                             "[tool]\n",
                                             "a = {b = {c = {d = 1}}}\n",
                                             "x = 1979-05-27T07:32:00Z\n",
                                             "max_velocity_m_per_min = 1e400\n",
                                             "max_velocity_m_per_min = 1e308\n",
                                             "travel_mm = [1, 2, 3]\n",
                                             "travel_mm = [nan, inf]\n",
                                             "name = \"\\u0000\"\n",
                                             "\"\" = 1\n",
                                             "a.b.c.d.e = 1\n",
                                             "key = \"\"\"\n",
                                             "machine = \"/\"\n",
                                             "program = \"/dev/zero\"\n",
                                             "machine = \"/dev/zero\"\n",
                                             "program = \"\"\n",
                                             "machine = \"..\"\n",
                                             "diameter_mm = -0.0\n",
                                             "period_ms = 1e-320\n",
                                             "type = 1\n",
                                             "axes = []\n",
                                             "axes = [1, 2]\n",
                                             "[[axes]]\nname = \"X\"\n",
                                             "travel_deg = [-1e308, 1e308]\n",
                                             "x = 9223372036854775808\n"};
const std::vector<std::string> kCsvLines = {"t_s,X_command_mm,X_actual_mm\n",
                                            "t_s,t_s,t_s\n",
                                            "0,1e400,1\n",
                                            "0,nan,inf\n",
                                            ",,\n",
                                            ",,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,\n",
                                            "\xEF\xBB\xBF" "0,1,2\n",  // a BOM, then a row (split: \xBF0 would be one escape)
                                            "# k=v\n",
                                            "#\n",
                                            "0x1p3,+-1,.\n",
                                            "\"1\",\"2\",\"3\"\n",
                                            "1\r\r\n"};
const std::vector<std::string> kStlLines = {"solid\n",
                                            "endsolid\n",
                                            "facet normal 0 0 0\n",
                                            "outer loop\n",
                                            "vertex 1e400 0 0\n",
                                            "vertex nan 0 0\n",
                                            "vertex 0 0 0\n",
                                            "endloop\n",
                                            "endfacet\n",
                                            "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0 0 0\n"
                                            "vertex 0 0 0\nendloop\nendfacet\n"};

std::string nested(std::size_t depth, Flavor f, Rng& rng) {
  const char* open = "[";
  const char* close = "]";
  if (f == Flavor::Gcode && rng.below(3) == 0) {
    open = "(";
    close = ")";
  }
  std::string s;
  for (std::size_t i = 0; i < depth; ++i) s += open;
  s += "1";
  for (std::size_t i = 0; i < depth; ++i) s += close;
  switch (f) {
    case Flavor::Gcode:
      return "G1 X" + s + "\n";
    case Flavor::Apt:
      return "GOTO/" + s + ",0,0\n";
    case Flavor::Toml:
      return "x = " + s + "\n";
    case Flavor::Stl:
      return "vertex " + s + " 0 0\n";
    case Flavor::Csv:
      return "0," + s + ",0\n";
  }
  return s;
}

std::vector<Mutant> make_mutants(const std::string& base, std::size_t count, const std::string& seed_name,
                                 Flavor flavor) {
  Rng rng{fnv1a(seed_name)};
  std::vector<Mutant> out;
  out.push_back({"empty file", ""});
  out.push_back({"unmutated", base});
  const std::vector<std::string>& dialect_lines = flavor == Flavor::Gcode ? kGcodeLines
                                                  : flavor == Flavor::Apt ? kAptLines
                                                  : flavor == Flavor::Stl ? kStlLines
                                                  : flavor == Flavor::Csv ? kCsvLines
                                                                          : kTomlLines;
  // Truncation at evenly spaced points (every part of the file gets cut once), then random mutations.
  const std::size_t truncations = std::min<std::size_t>(count / 4, base.size());
  for (std::size_t i = 1; i <= truncations; ++i) {
    const std::size_t at = base.size() * i / (truncations + 1);
    out.push_back({"truncated at byte " + std::to_string(at), base.substr(0, at)});
  }
  constexpr int kKinds = 13;
  for (std::size_t i = 0; out.size() < count + 2; ++i) {
    const int kind = static_cast<int>(i % kKinds);
    std::string t = base;
    std::vector<std::string> lines = split_lines(base);
    const std::size_t pos = rng.below(t.size() + 1);
    std::string what;
    switch (kind) {
      case 0: {  // flip one bit
        if (t.empty()) continue;
        const std::size_t p = rng.below(t.size());
        const int bit = static_cast<int>(rng.below(8));
        t[p] = static_cast<char>(t[p] ^ (1 << bit));
        what = "bit " + std::to_string(bit) + " flipped at byte " + std::to_string(p);
        break;
      }
      case 1: {  // a few random bytes overwritten
        const std::size_t n = 1 + rng.below(8);
        for (std::size_t k = 0; k < n && !t.empty(); ++k) t[rng.below(t.size())] = static_cast<char>(rng.below(256));
        what = std::to_string(n) + " random bytes overwritten";
        break;
      }
      case 2: {  // a line deleted
        if (lines.empty()) continue;
        const std::size_t l = rng.below(lines.size());
        lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(l));
        t = join(lines);
        what = "line " + std::to_string(l + 1) + " deleted";
        break;
      }
      case 3: {  // a line duplicated (possibly many times)
        if (lines.empty()) continue;
        const std::size_t l = rng.below(lines.size());
        const std::size_t n = rng.below(4) == 0 ? 1000 : 1;
        lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(l), n, lines[l]);
        t = join(lines);
        what = "line " + std::to_string(l + 1) + " duplicated " + std::to_string(n) + " times";
        break;
      }
      case 4: {  // two lines swapped
        if (lines.size() < 2) continue;
        const std::size_t a = rng.below(lines.size()), b = rng.below(lines.size());
        std::swap(lines[a], lines[b]);
        t = join(lines);
        what = "lines " + std::to_string(a + 1) + " and " + std::to_string(b + 1) + " swapped";
        break;
      }
      case 5:
      case 6: {  // a garbage token inserted
        const std::string& g = kGarbage[rng.below(kGarbage.size())];
        t.insert(pos, g);
        what = "garbage token #" + std::to_string(&g - kGarbage.data()) + " inserted at byte " + std::to_string(pos);
        break;
      }
      case 7: {  // a number replaced by an extreme one
        static const char* kNumbers[] = {"1e400",
                                         "-1e400",
                                         "NaN",
                                         "inf",
                                         "1e308",
                                         "-1e308",
                                         "99999999999999999999",
                                         "0",
                                         "-0",
                                         "1e-320",
                                         "4.9e-324",
                                         "2147483648",
                                         "-9223372036854775809"};
        std::size_t p = t.find_first_of("0123456789", pos);
        if (p == std::string::npos) p = t.find_first_of("0123456789");
        if (p == std::string::npos) continue;
        std::size_t e = p;
        while (e < t.size() && (std::isdigit(static_cast<unsigned char>(t[e])) || t[e] == '.')) ++e;
        const char* n = kNumbers[rng.below(std::size(kNumbers))];
        t.replace(p, e - p, n);
        what = "number at byte " + std::to_string(p) + " replaced by " + n;
        break;
      }
      case 8: {  // deeply nested brackets on a new line
        static const std::size_t kDepths[] = {64, 300, 5000, 100000};
        const std::size_t depth = kDepths[rng.below(std::size(kDepths))];
        const std::size_t l = rng.below(lines.size() + 1);
        lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(l), nested(depth, flavor, rng));
        t = join(lines);
        what = "brackets nested " + std::to_string(depth) + " deep inserted before line " + std::to_string(l + 1);
        break;
      }
      case 9: {  // a very long line
        static const char* kUnits[] = {"9", "X1 ", "$", ",", "#1=", "[", "a", " ", "G1"};
        const char* u = kUnits[rng.below(std::size(kUnits))];
        std::string longline;
        while (longline.size() < 200000) longline += u;
        const std::size_t l = rng.below(lines.size() + 1);
        lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(l), longline + "\n");
        t = join(lines);
        what = std::string("200 kB line of \"") + u + "\" inserted before line " + std::to_string(l + 1);
        break;
      }
      case 10: {  // a block of binary bytes
        std::string bin;
        const std::size_t n = 16 + rng.below(240);
        for (std::size_t k = 0; k < n; ++k) bin += static_cast<char>(rng.below(256));
        t.insert(pos, bin);
        what = std::to_string(n) + " binary bytes inserted at byte " + std::to_string(pos);
        break;
      }
      case 11: {  // a hostile line of the dialect
        const std::size_t which = rng.below(dialect_lines.size());
        const std::size_t l = rng.below(lines.size() + 1);
        lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(l), dialect_lines[which]);
        t = join(lines);
        what = "dialect line #" + std::to_string(which) + " (" + dialect_lines[which].substr(0, 40) +
               ") inserted before line " + std::to_string(l + 1);
        while (!what.empty() && (what.back() == '\n')) what.pop_back();
        break;
      }
      case 12: {  // truncated at a random point, then a random line appended
        t = t.substr(0, pos) + dialect_lines[rng.below(dialect_lines.size())];
        what = "truncated at byte " + std::to_string(pos) + " and a dialect line appended";
        break;
      }
    }
    // Control characters in descriptions would garble the report.
    for (char& c : what)
      if (static_cast<unsigned char>(c) < 0x20) c = '?';
    out.push_back({what, std::move(t)});
  }
  return out;
}

// ---- running one reader over the mutants ----

struct Outcome {
  std::size_t inputs = 0, ok = 0, errors = 0;
  std::string base_error;  // what reading the unmutated sample gave ("" = it read)
  double slowest_s = 0;
  std::string slowest;
};

fs::path work_dir(const std::string& name) {
  fs::path d = fs::path(VMSIM_BINARY_DIR) / "tests" / "hostile" / "work" / name;
  fs::create_directories(d);
  return d;
}

void write_file(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
  ASSERT_TRUE(out.good()) << "cannot write " << p;
}

// Each mutant is written to `input` and read with `read`; an error message must start with one of `prefixes`.
// Failing inputs are kept beside it (failure-N.<ext>) so they can be replayed.
Outcome run(const std::string& sample, const std::vector<Mutant>& mutants, const fs::path& input,
            const std::vector<std::string>& prefixes, const std::function<void(const fs::path&)>& read) {
  start_watchdog();
  Outcome o;
  int kept = 0;
  const auto keep = [&](const Mutant& m, const std::string& problem) {
    const fs::path copy = input.parent_path() / ("failure-" + std::to_string(++kept) + input.extension().string());
    if (kept <= 20) write_file(copy, m.text);
    ADD_FAILURE() << sample << ": " << m.what << ": " << problem << "\n  input kept as " << copy.string();
  };
  for (const Mutant& m : mutants) {
    write_file(input, m.text);
    set_current(sample + " / " + m.what + " (input: " + input.string() + ")");
    const double c0 = thread_cpu_s();
    try {
      read(input);
      ++o.ok;
    } catch (const Error& e) {
      ++o.errors;
      const std::string msg = e.what();
      if (m.what == "unmutated") o.base_error = msg;
      bool named = false;
      for (const auto& p : prefixes) named = named || msg.rfind(p, 0) == 0;
      if (!named) keep(m, "core::Error does not start with the file name: " + msg.substr(0, 300));
    } catch (const std::exception& e) {
      keep(m, std::string("exception other than core::Error (") + typeid(e).name() +
                  "): " + std::string(e.what()).substr(0, 300));
    } catch (...) {
      keep(m, "unknown exception type");
    }
    const double s = thread_cpu_s() - c0;
    g_started_ns = 0;
    ++o.inputs;
    if (s > o.slowest_s) {
      o.slowest_s = s;
      o.slowest = m.what;
    }
    if (s > kInputLimitS)
      keep(m, "took " + std::to_string(s) + " s of CPU (limit " + std::to_string(kInputLimitS) + " s)");
  }
  std::printf("[ hostile  ] %s: %zu inputs, %zu read, %zu clean errors; slowest %.3f s (%s)\n", sample.c_str(),
              o.inputs, o.ok, o.errors, o.slowest_s, o.slowest.c_str());
  if (!o.base_error.empty())
    std::printf("[ hostile  ]   the unmutated sample does not read: %s\n", o.base_error.c_str());
  return o;
}

// ---- samples ----

// G-code written for this test (so it means something without ../shared): arcs in the three planes with I/J/K
// and R, a helix with P turns, parameters and expressions, inch units, dwell, spindle, and o-word control flow.
const char* kGcodeMm =
    "%\n"
    "(vmsim hostile sample: mm, arcs in three planes)\n"
    "G21 G90 G94 G17\n"
    "G0 X0 Y0 Z5\n"
    "#1 = 2.5\n"
    "#<depth> = [#1 * 2]\n"
    "G1 Z-#<depth> F300\n"
    "G1 X10 Y0 F[600 / 2]\n"
    "G2 X20 Y10 I10 J0\n"
    "G3 X10 Y20 R10\n"
    "G18 G2 X0 Z-5 I-5 K0\n"
    "G19 G3 Y0 Z-5 J-10 K0\n"
    "G17 G2 X0 Y0 Z-7 I5 J0 P2 ; helix, two turns\n"
    "G91 G1 X1 Y1\n"
    "G90 G0 Z10\n"
    "M2\n"
    "%\n";
const char* kGcodeInch =
    "N10 G20 G90 G17 (inch)\n"
    "N20 M3 S1000\n"
    "N30 G0 X1 Y1 Z0.1\n"
    "N40 G1 Z-0.05 F10\n"
    "N50 X2 Y1.5 ; semicolon comment\n"
    "N60 G2 X3 Y1.5 I0.5 J0\n"
    "N70 G4 P0.5\n"
    "N80 G0 Z1\n"
    "N90 M5\n"
    "N100 M30\n";
const char* kGcodeOwords =
    "o100 sub\n"
    "  G1 X#1 Y#2\n"
    "o100 endsub\n"
    "G21 G90 F100\n"
    "G0 X0 Y0 Z1\n"
    "G1 Z0\n"
    "#3 = 0\n"
    "o200 while [#3 LT 5]\n"
    "  o100 call [#3] [#3 * 2]\n"
    "  #3 = [#3 + 1]\n"
    "o200 endwhile\n"
    "o300 if [#3 EQ 5]\n"
    "  G1 X0 Y0\n"
    "o300 endif\n"
    "M2\n";

// An APT CL sample in the syntax CATIA, NX and Autodesk's ISO 4343 post write: continuation lines, comments,
// 5-axis GOTOs, CIRCLE/ and MOVARC/ arcs, units, feeds.
const char* kApt =
    "$$ -----------------------------------------------------------------\n"
    "$$*CATIA0\n"
    "PARTNO hostile sample\n"
    "MACHIN/MILL,1\n"
    "UNITS/MM\n"
    "MULTAX/ON\n"
    "CUTTER/ 10.000000, 5.000000, 0.000000, 5.000000, 0.000000,$\n"
    "        0.000000, 40.000000\n"
    "LOADTL/1,1\n"
    "SPINDL/ 8000.0000,RPM,CLW\n"
    "COOLNT/ON\n"
    "FROM/0,0,100,0,0,1\n"
    "RAPID\n"
    "GOTO  / 10.00000, 0.00000, 5.00000, 0.000000, 0.000000, 1.000000\n"
    "FEDRAT/ 600.0000,MMPM\n"
    "GOTO  / 10.00000, 0.00000, 0.00000, 0.000000, 0.000000, 1.000000\n"
    "CIRCLE/0.0000,0.0000,0.0000,0.0000000,0.0000000,1.0000000,10.0000,0.0600,0.5000,10.0000,0.0000\n"
    "GOTO/0.0000,10.0000,0.0000\n"
    "MOVARC/0,0,0,0,0,-1,10,ANGLE,450\n"
    "GOTO/10.0000,0.0000,-1.0000\n"
    "CIRCLE/10.0000,0.0000,5.0000,0.0000000,1.0000000,0.0000000,6.0000\n"
    "GOTO/10.0000,0.0000,-1.0000\n"
    "FEDRAT/40,IPM\n"
    "GOTO  / 20.00000, 0.00000, 0.00000, 0.500000, 0.000000, 0.866025\n"
    "GOTO  / 30.00000,$\n"
    "        5.00000, 0.00000, 0.000000, 0.500000, 0.866025\n"
    "TLAXIS/0,0,1\n"
    "MULTAX/OFF\n"
    "GODLTA/0,0,10\n"
    "GOHOME\n"
    "COOLNT/OFF\n"
    "END\n"
    "FINI\n";

const char* kJob =
    "# hostile sample job\n"
    "[job]\n"
    "name = \"hostile\"\n"
    "description = \"mutated by tests/hostile\"\n"
    "machine = \"machine.toml\"\n"
    "program = \"part.ngc\"\n"
    "tool_table = \"tools.tbl\"\n"
    "\n"
    "[tool]\n"
    "type = \"bullnose\"\n"
    "diameter_mm = 10.0\n"
    "corner_radius_mm = 1.0\n"
    "flute_length_mm = 25.0\n"
    "length_mm = 60\n"
    "\n"
    "[stock]\n"
    "type = \"box\"\n"
    "min_mm = [0, 0, -20]\n"
    "max_mm = [100.0, 50.0, 0.0]\n"
    "\n"
    "[interpolation]\n"
    "period_ms = 1\n"
    "tolerance_mm = 0.02\n";

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

fs::path shared_data() { return fs::path(VMSIM_SHARED_DIR) / "data"; }

// Mutants per sample: several hundred for small files, fewer for large ones, whose every read costs more (3D_Chips,
// 200 kB, reads in ~0.05 s under ASan: ~140 mutants).
std::size_t mutant_count(std::size_t bytes) { return std::clamp<std::size_t>(30000000 / (bytes + 20000), 100, 500); }

void run_gcode_sample(const std::string& name, const std::string& text, program::ProgramOptions options) {
  options.max_blocks = kHostileMaxBlocks;
  const fs::path input = work_dir("gcode-" + name) / (name + ".ngc");
  const auto mutants = make_mutants(text, mutant_count(text.size()), "gcode:" + name, Flavor::Gcode);
  // The unmutated program not reading is a limit of the G-code reader, reported above, not a hostile-input failure.
  run("G-code " + name, mutants, input, {input.string() + ":"},
      [&](const fs::path& p) { (void)program::read_program(p, options); });
}

TEST(Hostile, GcodeBuiltInMm) { run_gcode_sample("builtin-mm", kGcodeMm, {}); }
TEST(Hostile, GcodeBuiltInInch) { run_gcode_sample("builtin-inch", kGcodeInch, {}); }
TEST(Hostile, GcodeBuiltInOwords) { run_gcode_sample("builtin-owords", kGcodeOwords, {}); }

// The LinuxCNC sample programs of ../shared (one test each, so ctest runs them in parallel), with the tool tables
// and remapped M codes their rs274 runs used.
std::vector<std::string> shared_programs() {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(shared_data() / "gcode" / "programs", ec))
    if (e.path().extension() == ".ngc") names.push_back(e.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

class HostileShared : public ::testing::TestWithParam<std::string> {};
GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(HostileShared);

TEST_P(HostileShared, GcodeProgram) {
  const fs::path p = shared_data() / "gcode" / "programs" / (GetParam() + ".ngc");
  program::ProgramOptions options;
  const bool boat = GetParam() == "boat-xyzac";
  const fs::path table = shared_data() / "gcode" / "tooltables" / (boat ? "xyzac-trt.tbl" : "tool_common.tbl");
  if (fs::exists(table)) options.tool_table = table;
  if (boat) options.no_motion_mcodes = {428, 429};
  run_gcode_sample(GetParam(), read_text(p), options);
}

INSTANTIATE_TEST_SUITE_P(Shared, HostileShared, ::testing::ValuesIn(shared_programs()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string n = info.param;
                           for (char& c : n)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return n;
                         });

TEST(Hostile, GcodeSharedProgramsPresent) {
  if (shared_programs().empty())
    GTEST_SKIP() << shared_data() / "gcode" / "programs"
                 << " has no .ngc (a fresh clone has no ../shared); the "
                 << "built-in G-code samples still run";
}

TEST(Hostile, AptClSample) {
  const fs::path input = work_dir("apt") / "part.apt";
  const auto mutants = make_mutants(kApt, 600, "apt", Flavor::Apt);
  const Outcome o = run("APT CL sample", mutants, input, {input.string() + ":"},
                        [](const fs::path& p) { (void)program::read_program(p); });
  EXPECT_EQ(o.base_error, "") << "the sample itself must read, or the mutants test little";
}

TEST(Hostile, MachineFile) {
  const std::string text = read_text(fs::path(VMSIM_SOURCE_DIR) / "parts" / "machines" / "mikron_ucp710.toml");
  ASSERT_FALSE(text.empty());
  const fs::path input = work_dir("machine") / "mikron_ucp710.toml";
  const auto mutants = make_mutants(text, 600, "machine", Flavor::Toml);
  const Outcome o = run("machine file mikron_ucp710.toml", mutants, input, {input.string() + ":"},
                        [](const fs::path& p) { (void)load_machine(p); });
  EXPECT_EQ(o.base_error, "");
}

TEST(Hostile, JobFile) {
  // The job's directory holds what it names: the Mikron machine file, a program and a tool table. Errors may
  // name the job file or a file it names (a mutated job can point its machine key at the program, say).
  const fs::path dir = work_dir("job");
  write_file(dir / "machine.toml", read_text(fs::path(VMSIM_SOURCE_DIR) / "parts" / "machines" / "mikron_ucp710.toml"));
  write_file(dir / "part.ngc", kGcodeMm);
  write_file(dir / "tools.tbl", "T1 P1 Z0 D10 ;bull nose\n");
  const fs::path input = dir / "job.toml";
  const auto mutants = make_mutants(kJob, 600, "job", Flavor::Toml);
  const Outcome o =
      run("job file", mutants, input, {(dir / "").string()}, [](const fs::path& p) { (void)load_job(p); });
  EXPECT_EQ(o.base_error, "");
}

// CSV files (core/csv): a position trace as vmsim writes it, its mutants read cell by cell as numbers (nan allowed).
TEST(Hostile, CsvTrace) {
  std::string text = "# vmsim position trace\n# period_s=0.001\nt_s,X_command_mm,X_actual_mm\n";
  for (int k = 0; k < 40; ++k)
    text += std::to_string(k * 0.001) + "," + std::to_string(0.25 * k) + "," + std::to_string(0.25 * k - 0.001) + "\n";
  const fs::path input = work_dir("csv") / "trace.csv";
  const auto mutants = make_mutants(text, 600, "csv", Flavor::Csv);
  const Outcome o = run("CSV trace", mutants, input, {input.string() + ":"}, [](const fs::path& p) {
    CsvReader r(p);
    if (!r.has_header()) throw Error(p.string() + ": no header");
    (void)r.require("t_s");
    while (r.next())
      for (std::size_t c = 0; c < r.cells(); ++c) (void)r.number_or_nan(c);
  });
  EXPECT_EQ(o.base_error, "");
}

// STL stocks: a closed octahedron written by core's own writers (ASCII and binary), its mutants through read_stl
// and check_closed. The binary sample also gets triangle counts that do not match the file size (4 billion in a
// 384-byte file must be an error, not an allocation).
void read_stl_stock(const fs::path& p) { check_closed(read_stl(p), p.string()); }

std::string octahedron_stl(bool binary) {
  TriangleMesh m;
  m.vertices_mm.resize(6, 3);
  m.vertices_mm << 10, 0, 0, -10, 0, 0, 0, 10, 0, 0, -10, 0, 0, 0, 10, 0, 0, -10;
  m.triangles.resize(8, 3);
  m.triangles << 0, 2, 4, 0, 5, 2, 0, 4, 3, 0, 3, 5, 1, 4, 2, 1, 2, 5, 1, 3, 4, 1, 5, 3;
  const fs::path p = work_dir("stl-sample") / (binary ? "octahedron_bin.stl" : "octahedron_ascii.stl");
  binary ? write_stl_binary(p, m) : write_stl_ascii(p, m, "octahedron");
  return read_text(p);
}

TEST(Hostile, StlAscii) {
  const fs::path input = work_dir("stl-ascii") / "stock.stl";
  const auto mutants = make_mutants(octahedron_stl(false), 600, "stl-ascii", Flavor::Stl);
  const Outcome o = run("ASCII STL", mutants, input, {input.string() + ":"}, read_stl_stock);
  EXPECT_EQ(o.base_error, "");
}

TEST(Hostile, StlBinary) {
  const std::string base = octahedron_stl(true);
  auto mutants = make_mutants(base, 600, "stl-binary", Flavor::Stl);
  for (std::uint32_t n : {0u, 7u, 9u, 65535u, 0x7fffffffu, 4000000000u, 0xffffffffu}) {
    std::string t = base;
    for (int k = 0; k < 4; ++k) t[80 + static_cast<std::size_t>(k)] = static_cast<char>((n >> (8 * k)) & 0xffu);
    mutants.push_back({"triangle count set to " + std::to_string(n), t});
    t.replace(0, 5, "solid");  // and a header that looks like ASCII
    mutants.push_back({"triangle count set to " + std::to_string(n) + ", header \"solid\"", t});
  }
  const fs::path input = work_dir("stl-binary") / "stock.stl";
  const Outcome o = run("binary STL", mutants, input, {input.string() + ":"}, read_stl_stock);
  EXPECT_EQ(o.base_error, "");
}

// Replays one kept input: VMSIM_HOSTILE_REPLAY=<file> [VMSIM_HOSTILE_TOOL_TABLE=<tbl>] hostile_tests
// --gtest_filter=Hostile.Replay. The reader is chosen as the harness chose it: job.toml -> load_job, other .toml ->
// load_machine, .stl -> read_stl + check_closed, anything else -> read_program.
TEST(Hostile, Replay) {
  const char* file = std::getenv("VMSIM_HOSTILE_REPLAY");
  if (!file) GTEST_SKIP() << "set VMSIM_HOSTILE_REPLAY=<input> to replay one input";
  const fs::path p(file);
  const auto t0 = Clock::now();
  try {
    if (p.extension() == ".toml" && p.stem().string().rfind("job", 0) == 0) {
      (void)load_job(p);
    } else if (p.extension() == ".toml") {
      (void)load_machine(p);
    } else if (p.extension() == ".stl") {
      read_stl_stock(p);
    } else {
      program::ProgramOptions options;
      if (const char* t = std::getenv("VMSIM_HOSTILE_TOOL_TABLE")) options.tool_table = fs::path(t);
      (void)program::read_program(p, options);
    }
    std::printf("read without error");
  } catch (const Error& e) {
    std::printf("core::Error: %s", e.what());
  }
  std::printf(" (%.3f s)\n", std::chrono::duration<double>(Clock::now() - t0).count());
}

}  // namespace
}  // namespace vmsim::core
