#pragma once
// Outputs are written to a temporary name beside the target and renamed when complete, so a crash or an
// error never leaves a half-written file that looks whole. The temporary file is created exclusively (O_EXCL,
// O_NOFOLLOW, a random name): a file or symlink planted at that name is never followed nor overwritten. It is
// fsync'd before the rename, and the directory after, so a power cut leaves the old file or the new one.
#include <filesystem>
#include <memory>
#include <ostream>
#include <string>
#include <string_view>

namespace vmsim::core {

class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path target);
  ~AtomicFile();  // removes the temporary file unless commit() ran
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ostream& stream();
  // Flushes, checks the stream, fsyncs, and renames the temporary file to the target. Throws on any I/O error.
  void commit();
  const std::filesystem::path& temp_path() const { return temp_; }

 private:
  struct Buffer;
  std::filesystem::path target_, temp_;
  std::unique_ptr<Buffer> buf_;
  bool committed_ = false;
};

void write_file_atomic(const std::filesystem::path& target, std::string_view content);

// fsync of a directory (its entries: a rename into it survives a power cut). Throws core::Error naming it.
void fsync_directory(const std::filesystem::path& dir);

}  // namespace vmsim::core
