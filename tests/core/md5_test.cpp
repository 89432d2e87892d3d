// MD5 against the test suite of RFC 1321 appendix A.5, plus messages that straddle the 64-byte block and the
// 56-byte padding boundary (checked against GNU md5sum).
#include "core/md5.hpp"

#include <gtest/gtest.h>

#include <string>

using vmsim::core::md5_hex;

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

TEST(Md5, BlockBoundariesAndIncrementalUpdates) {
  EXPECT_EQ(md5_hex(std::string(55, 'x')), "04364420e25c512fd958a70738aa8f72");
  EXPECT_EQ(md5_hex(std::string(56, 'x')), "668a72d5ba17f08e62dabcafad6db14b");
  EXPECT_EQ(md5_hex(std::string(64, 'x')), "c1bb4f81d892b2d57947682aeb252456");
  EXPECT_EQ(md5_hex(std::string(1000000, 'a')), "7707d6ae4e027c70eea2a935c2296f21");
  // The same message fed in pieces of every size from 1 to 70 bytes gives the same digest.
  const std::string msg(1000, 'q');
  const std::string whole = md5_hex(msg);
  for (std::size_t piece = 1; piece <= 70; ++piece) {
    vmsim::core::Md5 m;
    for (std::size_t at = 0; at < msg.size(); at += piece) m.update(msg.data() + at, std::min(piece, msg.size() - at));
    EXPECT_EQ(m.hex(), whole) << "piece " << piece;
  }
}
