#include "metrology/gzip.hpp"
#include "core/regular_file.hpp"

#include "core/error.hpp"

#include <fmt/format.h>
#include <zlib.h>

#include <fstream>
#include <sstream>
#include <vector>

namespace vmsim::metrology {

std::string gunzip_file(const std::filesystem::path& file, std::size_t max_bytes) {
  core::require_regular_file(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw core::Error(file.string() + ": cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string z = std::move(ss).str();
  if (!looks_like_gzip(z)) throw core::Error(file.string() + ": not a gzip file (it does not start with 1f 8b)");
  z_stream s{};
  // 16 + MAX_WBITS: a gzip wrapper (header and CRC checked by zlib).
  if (inflateInit2(&s, 16 + MAX_WBITS) != Z_OK) throw core::Error(file.string() + ": zlib cannot start inflating");
  std::string out;
  std::vector<char> buf(1 << 16);
  s.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(z.data()));
  s.avail_in = static_cast<uInt>(z.size());
  int r = Z_OK;
  for (;;) {
    s.next_out = reinterpret_cast<Bytef*>(buf.data());
    s.avail_out = static_cast<uInt>(buf.size());
    r = inflate(&s, Z_NO_FLUSH);
    if (r != Z_OK && r != Z_STREAM_END) break;
    out.append(buf.data(), buf.size() - s.avail_out);
    if (out.size() > max_bytes) {
      inflateEnd(&s);
      throw core::Error(fmt::format("{}: inflates to more than the {} bytes vmsim accepts", file.string(), max_bytes));
    }
    if (r == Z_STREAM_END) {
      if (s.avail_in < 2 || !looks_like_gzip(std::string_view(reinterpret_cast<const char*>(s.next_in), 2))) break;
      // Another gzip member follows (concatenated files): inflate it too. Other trailing bytes are ignored, as gzip
      // does.
      if (inflateReset(&s) != Z_OK) break;
      continue;
    }
    if (s.avail_in == 0 && s.avail_out != 0) break;  // input exhausted before the end of the stream
  }
  const std::string why = s.msg ? s.msg : "";
  inflateEnd(&s);
  if (r != Z_STREAM_END)
    throw core::Error(fmt::format("{}: corrupt or truncated gzip data after {} inflated bytes{}", file.string(),
                                  out.size(), why.empty() ? "" : " (" + why + ")"));
  return out;
}

}  // namespace vmsim::metrology
