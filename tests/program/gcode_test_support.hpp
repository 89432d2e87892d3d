#pragma once
// Helpers for the G-code reader tests: small programs written to a temporary folder, canonical calls
// split into name and numbers, error capture.
#include "core/error.hpp"
#include "program/gcode.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace vmsim::program::gcode_test {

namespace fs = std::filesystem;

// A folder of its own under the system temp dir, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    dir_ = fs::temp_directory_path() /
           ("vmsim_gcode_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(dir_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  const fs::path& path() const { return dir_; }

 private:
  fs::path dir_;
};

inline GcodeResult run(const std::string& program, GcodeOptions options = {}, const std::string& name = "test.ngc") {
  TempDir dir;
  return interpret_gcode(dir.write(name, program), options);
}

// The error message interpret_gcode throws for the program ("" if it does not throw).
inline std::string error_of(const std::string& program, GcodeOptions options = {},
                            const std::string& name = "test.ngc") {
  try {
    run(program, options, name);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

struct Call {
  std::string name;
  std::vector<double> numbers;
  std::string text;
};

// "ARC_FEED(1.0000, 2.0000, ..., -1, ...)" -> name and every number; other texts (COMMENT("...")) keep no numbers.
inline Call parse_call(const std::string& text) {
  Call c;
  c.text = text;
  const std::size_t open = text.find('(');
  c.name = text.substr(0, open);
  if (open == std::string::npos || text.find('"') != std::string::npos) return c;
  const char* p = text.c_str() + open + 1;
  while (*p != '\0' && *p != ')') {
    char* end = nullptr;
    const double v = std::strtod(p, &end);
    if (end == p) {
      ++p;
      continue;
    }
    c.numbers.push_back(v);
    p = end;
  }
  return c;
}

inline bool is_motion(const std::string& name) {
  return name == "STRAIGHT_TRAVERSE" || name == "STRAIGHT_FEED" || name == "ARC_FEED";
}

inline std::vector<Call> motions(const GcodeResult& r) {
  std::vector<Call> out;
  for (const CanonCall& c : r.canon) {
    Call call = parse_call(c.text);
    if (is_motion(call.name)) out.push_back(call);
  }
  return out;
}

inline std::vector<std::string> texts(const GcodeResult& r) {
  std::vector<std::string> out;
  for (const CanonCall& c : r.canon) out.push_back(c.text);
  return out;
}

// The calls after rs274's six-line preamble, without the two final ON_RESET().
inline std::vector<std::string> body(const GcodeResult& r) {
  std::vector<std::string> t = texts(r);
  if (t.size() < 8) return {};
  return std::vector<std::string>(t.begin() + 6, t.end() - 2);
}

}  // namespace vmsim::program::gcode_test
