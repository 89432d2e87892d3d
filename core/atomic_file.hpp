#pragma once
// Outputs are written to a temporary name beside the target and renamed when complete, so a crash or an
// error never leaves a half-written file that looks whole.
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace vmsim::core {

class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path target);
  ~AtomicFile();  // removes the temporary file unless commit() ran
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ofstream& stream() { return out_; }
  // Flushes, checks the stream, and renames the temporary file to the target. Throws on any I/O error.
  void commit();

 private:
  std::filesystem::path target_, temp_;
  std::ofstream out_;
  bool committed_ = false;
};

void write_file_atomic(const std::filesystem::path& target, std::string_view content);

}  // namespace vmsim::core
