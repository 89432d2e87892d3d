#pragma once
// MD5 (RFC 1321). X3P files (ISO 5436-2 / ISO 25178-72) carry MD5 checksums of main.xml and of their binary data
// files, and vmsim must write and check them. No library of the dependency stack (STACK.md) offers MD5 (libzip
// only does CRC-32), so it is written here, beside core/sha256, and tested against the RFC's own test suite
// (appendix A.5). It is a checksum for file integrity as the format prescribes, not a security measure.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace vmsim::core {

class Md5 {
 public:
  Md5();
  void update(const void* data, std::size_t n);
  // The 16-byte digest; the object is finished afterwards (construct a new one for another message).
  std::array<std::uint8_t, 16> digest();
  // Lower-case hex, as md5sum prints it.
  std::string hex();

 private:
  void compress(const std::uint8_t* block);
  std::array<std::uint32_t, 4> s_;
  std::array<std::uint8_t, 64> buf_{};
  std::size_t fill_ = 0;
  std::uint64_t total_ = 0;
};

std::string md5_hex(std::string_view data);

}  // namespace vmsim::core
