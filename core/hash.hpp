#pragma once
// MD5 and SHA-256 as lower-case hex (as md5sum and sha256sum print them), from OpenSSL's libcrypto (EVP).
// MD5: the checksums X3P files (ISO 5436-2 / ISO 25178-72) carry for main.xml and their binary data; a file-integrity
// checksum the format prescribes, not a security measure. SHA-256: the input hashes of report.json.
#include <filesystem>
#include <string>
#include <string_view>

namespace vmsim::core {

std::string md5_hex(std::string_view data);
std::string sha256_hex(std::string_view data);
// The file read in pieces (never whole). Throws core::Error naming the file when it cannot be read.
std::string sha256_file_hex(const std::filesystem::path& file);

}  // namespace vmsim::core
