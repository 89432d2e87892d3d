#pragma once
// Shared by the command-line tests: a scratch directory removed at the end of the test, and a whole file as a string.
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

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

}  // namespace vmsim_test
