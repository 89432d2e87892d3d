#pragma once
// Shared by the command-line tests: a scratch directory removed at the end of the test, vmsim run as a user runs it
// (stdout and stderr captured), and small file helpers (a whole file as a string, a file written, JSON and CSV read).
#include "core/csv.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace vmsim_test {

class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "vmsim_cli_") {
    std::random_device rd;
    dir_ = std::filesystem::temp_directory_path() / (prefix + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(dir_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return dir_; }

 private:
  std::filesystem::path dir_;
};

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline void write_file(const std::filesystem::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
}

inline nlohmann::json read_json(const std::filesystem::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

// A path as one shell word, in single quotes (the tests' paths hold no quote).
inline std::string quoted_arg(const std::filesystem::path& p) {
  std::string s(1, '\'');  // appended, not "'" + ...: GCC 12 warns falsely (-Wrestrict) on that operator+
  s += p.string();
  s += '\'';
  return s;
}

// The number after "key": in a JSON text (from offset `from`), NaN when the key is absent.
inline double json_number_after(const std::string& text, const std::string& key, std::size_t from = 0) {
  const auto k = text.find("\"" + key + "\"", from);
  if (k == std::string::npos) return NAN;
  const auto colon = text.find(':', k);
  return std::stod(text.substr(colon + 1));
}

struct CliRun {
  int code = -1;  // the exit status; -1 when vmsim did not exit normally (a signal)
  std::string out, err;
};

#ifdef VMSIM_EXE
// `PREFIX 'vmsim' ARGS` through the shell (prefix: e.g. "env -u DISPLAY "), stdout and stderr captured in the
// scratch directory's stdout.txt and stderr.txt.
inline CliRun run_vmsim(const std::string& args, const TempDir& tmp, const std::string& prefix = "") {
  const std::filesystem::path out = tmp.path() / "stdout.txt", err = tmp.path() / "stderr.txt";
  const std::string cmd = prefix + "'" + VMSIM_EXE + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
  const int status = std::system(cmd.c_str());
  CliRun r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}
#endif

#ifdef VMSIM_PYTHON
// A result directory's report.html checked against its report.json (or study.json) by
// tests/app/check_report_html.py: valid HTML5 (html5lib strict, tidy), self-contained (every link and picture inside
// the directory), every number and string of the JSON on the page, the key figures as the reader sees them.
// `options`: e.g. "--pictures yes", "--note 'TEXT'". Without python3-html5lib (make test installs it) it says so and
// checks only that the page exists.
inline void expect_report_html(const std::filesystem::path& dir, const std::string& options = "") {
  ASSERT_TRUE(std::filesystem::exists(dir / "report.html")) << dir;
  const std::filesystem::path log = dir.parent_path() / (dir.filename().string() + "_report_html_check.txt");
  const std::string cmd = std::string("'") + VMSIM_PYTHON + "' '" + VMSIM_SOURCE_DIR +
                          "/tests/app/check_report_html.py' '" + dir.string() + "' " + options + " >'" + log.string() +
                          "' 2>&1";
  const int status = std::system(cmd.c_str());
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  const std::string out = slurp(log);
  if (code == 77) {
    std::printf("[   NOTE   ] %s: report.html not validated: %s", dir.string().c_str(), out.c_str());
    return;
  }
  EXPECT_EQ(code, 0) << out;
}
#endif

// A CSV file vmsim wrote, through core/csv's reader (its '#' lines skipped, every row as wide as the header): header
// names and rows of numbers (cells that are not numbers read as NaN).
struct Csv {
  std::vector<std::string> names;
  std::vector<std::vector<double>> rows;
  int col(const std::string& n) const {  // a missing column fails the test
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == n) return static_cast<int>(i);
    ADD_FAILURE() << "no column " << n;
    return 0;
  }
};

inline Csv read_csv(const std::filesystem::path& p) {
  Csv c;
  vmsim::core::CsvReader in(p);
  c.names = in.columns();
  while (in.next()) {
    std::vector<double> r;
    for (std::size_t i = 0; i < in.cells(); ++i) r.push_back(vmsim::core::parse_number(in.cell(i)).value_or(NAN));
    c.rows.push_back(std::move(r));
  }
  return c;
}

}  // namespace vmsim_test
