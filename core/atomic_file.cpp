#include "core/atomic_file.hpp"

#include "core/error.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>

namespace vmsim::core {

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
  static std::atomic<unsigned> counter{0};
  temp_ = target_;
  temp_ += fmt::format(".tmp{}.{}", static_cast<long>(::getpid()), counter++);
  out_.open(temp_, std::ios::binary | std::ios::trunc);
  if (!out_) throw Error(fmt::format("{}: cannot create file: {}", temp_.string(), std::strerror(errno)));
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    out_.close();
    std::error_code ec;
    std::filesystem::remove(temp_, ec);
  }
}

void AtomicFile::commit() {
  out_.flush();
  if (!out_) throw Error(fmt::format("{}: write failed (disk full?)", target_.string()));
  out_.close();
  std::error_code ec;
  std::filesystem::rename(temp_, target_, ec);
  if (ec) throw Error(fmt::format("{}: cannot move the finished file into place: {}", target_.string(), ec.message()));
  committed_ = true;
}

void write_file_atomic(const std::filesystem::path& target, std::string_view content) {
  AtomicFile f(target);
  f.stream().write(content.data(), static_cast<std::streamsize>(content.size()));
  f.commit();
}

}  // namespace vmsim::core
