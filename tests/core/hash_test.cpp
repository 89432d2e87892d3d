// core/hash (OpenSSL's libcrypto) against published vectors: MD5 against the test suite of RFC 1321 appendix A.5 plus
// messages that straddle the 64-byte block and the 56-byte padding boundary (checked against GNU md5sum); SHA-256
// against the example vectors of FIPS 180-2 appendix B / NIST's SHA examples; the file hash against the same vectors
// and against the in-memory hash on files around its read buffer's size.
#include "core/hash.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

using vmsim::core::md5_hex;
using vmsim::core::sha256_file_hex;
using vmsim::core::sha256_hex;

namespace {

std::filesystem::path scratch_file(const std::string& name, const std::string& content) {
  const auto p =
      std::filesystem::temp_directory_path() / ("vmsim_hash_test_" + std::to_string(::getpid()) + "_" + name);
  std::ofstream(p, std::ios::binary) << content;
  return p;
}

}  // namespace

TEST(Md5, Rfc1321TestSuite) {
  EXPECT_EQ(md5_hex(""), "d41d8cd98f00b204e9800998ecf8427e");
  EXPECT_EQ(md5_hex("a"), "0cc175b9c0f1b6a831c399e269772661");
  EXPECT_EQ(md5_hex("abc"), "900150983cd24fb0d6963f7d28e17f72");
  EXPECT_EQ(md5_hex("message digest"), "f96b697d7cb7938d525a2f31aaf161d0");
  EXPECT_EQ(md5_hex("abcdefghijklmnopqrstuvwxyz"), "c3fcd3d76192e4007dfb496cca67e13b");
  EXPECT_EQ(md5_hex("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789"),
            "d174ab98d277d9f5a5611c2c9f419d9f");
  EXPECT_EQ(md5_hex("12345678901234567890123456789012345678901234567890123456789012345678901234567890"),
            "57edf4a22be3c955ac49da2e2107b67a");
}

TEST(Md5, BlockBoundaries) {
  EXPECT_EQ(md5_hex(std::string(55, 'x')), "04364420e25c512fd958a70738aa8f72");
  EXPECT_EQ(md5_hex(std::string(56, 'x')), "668a72d5ba17f08e62dabcafad6db14b");
  EXPECT_EQ(md5_hex(std::string(64, 'x')), "c1bb4f81d892b2d57947682aeb252456");
  EXPECT_EQ(md5_hex(std::string(1000000, 'a')), "7707d6ae4e027c70eea2a935c2296f21");
  // Binary data with NUL bytes is hashed whole, not up to the first NUL.
  EXPECT_NE(md5_hex(std::string("a\0b", 3)), md5_hex("a"));
}

TEST(Sha256, FipsExampleVectors) {
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(sha256_hex(std::string(1000000, 'a')), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Sha256, FilesAreHashedInPiecesAsAWhole) {
  // A million 'a' through the file reader: the FIPS vector again, read in 64 KiB pieces.
  const auto million = scratch_file("million", std::string(1000000, 'a'));
  EXPECT_EQ(sha256_file_hex(million), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
  std::filesystem::remove(million);
  const auto empty = scratch_file("empty", "");
  EXPECT_EQ(sha256_file_hex(empty), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  std::filesystem::remove(empty);
  // Random bytes of sizes around the read buffer (65536) agree with the in-memory hash.
  std::mt19937 rng(7);
  for (const std::size_t n : {65535u, 65536u, 65537u, 131072u, 200003u}) {
    std::string s(n, '\0');
    for (char& c : s) c = static_cast<char>(rng() & 0xff);
    const auto p = scratch_file("random", s);
    EXPECT_EQ(sha256_file_hex(p), sha256_hex(s)) << n << " bytes";
    std::filesystem::remove(p);
  }
}

TEST(Sha256, MissingFileNamesTheFile) {
  try {
    sha256_file_hex("/nonexistent/vmsim/input.toml");
    FAIL() << "no error";
  } catch (const vmsim::core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/vmsim/input.toml"), std::string::npos) << e.what();
  }
}
