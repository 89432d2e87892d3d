#include "core/atomic_file.hpp"

#include "core/error.hpp"

#include <ext/stdio_filebuf.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <random>

namespace vmsim::core {

// libstdc++'s filebuf over a file descriptor: the standard streams cannot open a file with O_EXCL | O_NOFOLLOW.
struct AtomicFile::Buffer {
  int fd;
  __gnu_cxx::stdio_filebuf<char> buf;
  std::ostream out;
  explicit Buffer(int f) : fd(f), buf(f, std::ios::out | std::ios::binary), out(&buf) {}
};

namespace {

std::string random_suffix() {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  return fmt::format("{:016x}", rng());
}

}  // namespace

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
  // A random name, created exclusively and never through a symlink: a name another process guessed and planted
  // cannot redirect the write. A collision (a file already there) draws another name.
  for (int attempt = 0;; ++attempt) {
    temp_ = target_;
    temp_ += fmt::format(".tmp{}.{}", static_cast<long>(::getpid()), random_suffix());
    const int fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
    if (fd >= 0) {
      buf_ = std::make_unique<Buffer>(fd);
      return;
    }
    if (errno != EEXIST || attempt >= 16)
      throw Error(fmt::format("{}: cannot create file: {}", temp_.string(), std::strerror(errno)));
  }
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    buf_.reset();  // closes the descriptor
    std::error_code ec;
    std::filesystem::remove(temp_, ec);
  }
}

std::ostream& AtomicFile::stream() { return buf_->out; }

void AtomicFile::commit() {
  buf_->out.flush();
  if (!buf_->out) throw Error(fmt::format("{}: write failed (disk full?)", target_.string()));
  if (::fsync(buf_->fd) != 0)
    throw Error(fmt::format("{}: cannot flush the file to disk: {}", target_.string(), std::strerror(errno)));
  if (buf_->buf.close() == nullptr)
    throw Error(fmt::format("{}: write failed on close (disk full?)", target_.string()));
  std::error_code ec;
  std::filesystem::rename(temp_, target_, ec);
  if (ec) throw Error(fmt::format("{}: cannot move the finished file into place: {}", target_.string(), ec.message()));
  committed_ = true;
  const std::filesystem::path dir = target_.parent_path().empty() ? std::filesystem::path(".") : target_.parent_path();
  fsync_directory(dir);
}

void write_file_atomic(const std::filesystem::path& target, std::string_view content) {
  AtomicFile f(target);
  f.stream().write(content.data(), static_cast<std::streamsize>(content.size()));
  f.commit();
}

void fsync_directory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw Error(fmt::format("{}: cannot open the directory: {}", dir.string(), std::strerror(errno)));
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  // Some file systems refuse fsync on a directory (EINVAL); their renames are as durable as they get.
  if (rc != 0 && err != EINVAL)
    throw Error(fmt::format("{}: cannot flush the directory to disk: {}", dir.string(), std::strerror(err)));
}

}  // namespace vmsim::core
