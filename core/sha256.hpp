#pragma once
// SHA-256 (FIPS 180-4) of files, for the input hashes of report.json. Written here because the dependency stack
// (STACK.md) has no hashing library; it is small, and tested against the FIPS/NIST example vectors.
#include <filesystem>
#include <string>
#include <string_view>

namespace vmsim::core {

std::string sha256_hex(std::string_view data);
// Throws core::Error naming the file when it cannot be read.
std::string sha256_file_hex(const std::filesystem::path& file);

}  // namespace vmsim::core
