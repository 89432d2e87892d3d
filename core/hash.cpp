#include "core/hash.hpp"

#include "core/error.hpp"

#include <openssl/evp.h>

#include <array>
#include <fstream>
#include <memory>
#include <vector>

namespace vmsim::core {

namespace {

// One digest computation through EVP; any failure of the library is an error (it never happens with the default
// provider, which holds both algorithms, but a FIPS-only configuration would refuse MD5).
class Digest {
 public:
  Digest(const EVP_MD* md, const char* name) : ctx_(EVP_MD_CTX_new(), EVP_MD_CTX_free), name_(name) {
    if (!ctx_ || EVP_DigestInit_ex(ctx_.get(), md, nullptr) != 1) fail();
  }
  void update(const void* data, std::size_t n) {
    if (n > 0 && EVP_DigestUpdate(ctx_.get(), data, n) != 1) fail();
  }
  std::string hex() {
    std::array<unsigned char, EVP_MAX_MD_SIZE> d{};
    unsigned int n = 0;
    if (EVP_DigestFinal_ex(ctx_.get(), d.data(), &n) != 1) fail();
    static constexpr char kHex[] = "0123456789abcdef";
    std::string s;
    s.reserve(2 * n);
    for (unsigned int i = 0; i < n; ++i) {
      s += kHex[d[i] >> 4];
      s += kHex[d[i] & 15];
    }
    return s;
  }

 private:
  [[noreturn]] void fail() const { throw Error(std::string("OpenSSL's libcrypto cannot compute ") + name_); }
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx_;
  const char* name_;
};

}  // namespace

std::string md5_hex(std::string_view data) {
  Digest d(EVP_md5(), "MD5");
  d.update(data.data(), data.size());
  return d.hex();
}

std::string sha256_hex(std::string_view data) {
  Digest d(EVP_sha256(), "SHA-256");
  d.update(data.data(), data.size());
  return d.hex();
}

std::string sha256_file_hex(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw Error(file.string() + ": cannot open file to hash it");
  Digest d(EVP_sha256(), "SHA-256");
  std::vector<char> buf(1 << 16);
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    d.update(buf.data(), static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) throw Error(file.string() + ": read error while hashing");
  return d.hex();
}

}  // namespace vmsim::core
