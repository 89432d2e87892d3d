// PNG files of pictures: one fixed row filter (chosen per picture in bench/README.md "Pictures' CPU, round 2"), the
// rows deflated by libdeflate (default; "round 4") or by zlib through libpng; read back through VTK's reader (an
// independent decoder path for tests and tools).
#include "render/detail.hpp"
#include "render/image.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"

#include <libdeflate.h>
#include <png.h>

#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>

#include <fmt/format.h>

#include <csetjmp>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <memory>
#include <vector>
#include <zlib.h>

namespace vmsim::render {

namespace {

// libpng reports errors by longjmp: the encoder below keeps no C++ object with a destructor alive across its
// setjmp, and the error text goes into this plain buffer.
struct PngSink {
  std::string* bytes = nullptr;
  char error[256] = {0};
};

void png_error_to_sink(png_structp png, png_const_charp msg) {
  auto* sink = static_cast<PngSink*>(png_get_error_ptr(png));
  std::snprintf(sink->error, sizeof sink->error, "%s", msg ? msg : "unknown libpng error");
  png_longjmp(png, 1);
}

void png_warning_ignored(png_structp, png_const_charp) {}

void png_append(png_structp png, png_bytep data, png_size_t n) {
  auto* sink = static_cast<PngSink*>(png_get_io_ptr(png));
  bool ok = true;
  try {
    sink->bytes->append(reinterpret_cast<const char*>(data), n);
  } catch (const std::bad_alloc&) {
    ok = false;
  }
  if (!ok) png_error(png, "out of memory while encoding");
}

void png_flush_nothing(png_structp) {}

int libpng_filter(PngFilter f) {
  switch (f) {
    case PngFilter::None:
      return PNG_FILTER_NONE;
    case PngFilter::Sub:
      return PNG_FILTER_SUB;
    case PngFilter::Up:
      return PNG_FILTER_UP;
    case PngFilter::Paeth:
      return PNG_FILTER_PAETH;
    case PngFilter::Adaptive:
      return PNG_ALL_FILTERS;
  }
  return PNG_FILTER_NONE;
}

// Returns false with sink.error set when libpng failed. Only plain data lives in this frame (see PngSink).
bool encode_rows(const Image& image, const PngEncoding& enc, PngSink& sink) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, png_error_to_sink, png_warning_ignored);
  if (!png) {
    std::snprintf(sink.error, sizeof sink.error, "cannot create libpng's writer");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    std::snprintf(sink.error, sizeof sink.error, "cannot create libpng's info");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, &sink, png_append, png_flush_nothing);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8,
               PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, libpng_filter(enc.filter));
  png_set_compression_level(png, enc.level);
  png_set_compression_strategy(png, enc.rle ? Z_RLE : Z_DEFAULT_STRATEGY);
  png_write_info(png, info);
  const std::size_t row = static_cast<std::size_t>(image.width) * 3;
  for (int y = 0; y < image.height; ++y)
    png_write_row(png, const_cast<png_bytep>(image.rgb.data() + static_cast<std::size_t>(y) * row));
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return true;
}

// ---- libdeflate ----------------------------------------------------------------------------------------------
// libpng can only hand its rows to zlib, so with libdeflate the file's few chunks are written here (W3C PNG, 2nd
// edition: signature, IHDR, one IDAT holding the zlib stream of the filtered rows, IEND; each chunk's CRC-32 over
// its type and data).

void put_be32(std::string& out, std::uint32_t v) {
  const char b[4] = {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8),
                     static_cast<char>(v)};
  out.append(b, 4);
}

void put_chunk(std::string& out, const char type[4], const std::uint8_t* data, std::size_t n) {
  put_be32(out, static_cast<std::uint32_t>(n));
  const std::size_t at = out.size();
  out.append(type, 4);
  out.append(reinterpret_cast<const char*>(data), n);
  put_be32(out, libdeflate_crc32(0, out.data() + at, n + 4));
}

std::uint8_t paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return static_cast<std::uint8_t>(pa <= pb && pa <= pc ? a : pb <= pc ? b : c);
}

// Each row as its filter-type byte and the row's differences from the filter's prediction (PNG section 9).
std::vector<std::uint8_t> filtered_rows(const Image& image, PngFilter filter) {
  const std::size_t row = static_cast<std::size_t>(image.width) * 3;
  std::vector<std::uint8_t> out((row + 1) * static_cast<std::size_t>(image.height));
  const std::uint8_t type = filter == PngFilter::Sub     ? 1
                            : filter == PngFilter::Up    ? 2
                            : filter == PngFilter::Paeth ? 4
                                                         : 0;
  for (int y = 0; y < image.height; ++y) {
    const std::uint8_t* cur = image.rgb.data() + static_cast<std::size_t>(y) * row;
    const std::uint8_t* up = y > 0 ? cur - row : nullptr;  // the row above; zeros for the first
    std::uint8_t* o = out.data() + static_cast<std::size_t>(y) * (row + 1);
    *o++ = type;
    switch (filter) {
      case PngFilter::Sub:
        for (std::size_t i = 0; i < row; ++i) o[i] = static_cast<std::uint8_t>(cur[i] - (i >= 3 ? cur[i - 3] : 0));
        break;
      case PngFilter::Up:
        if (up)
          for (std::size_t i = 0; i < row; ++i) o[i] = static_cast<std::uint8_t>(cur[i] - up[i]);
        else
          std::memcpy(o, cur, row);
        break;
      case PngFilter::Paeth:
        for (std::size_t i = 0; i < row; ++i)
          o[i] = static_cast<std::uint8_t>(
              cur[i] - paeth(i >= 3 ? cur[i - 3] : 0, up ? up[i] : 0, up && i >= 3 ? up[i - 3] : 0));
        break;
      default:
        std::memcpy(o, cur, row);
    }
  }
  return out;
}

std::string encode_libdeflate(const Image& image, const PngEncoding& enc) {
  if (enc.filter == PngFilter::Adaptive || enc.rle)
    throw core::Error("libdeflate offers neither libpng's adaptive filtering nor zlib's RLE strategy (use zlib)");
  const std::vector<std::uint8_t> rows = filtered_rows(image, enc.filter);
  const std::unique_ptr<libdeflate_compressor, decltype(&libdeflate_free_compressor)> c(
      libdeflate_alloc_compressor(enc.level), libdeflate_free_compressor);
  if (!c) throw core::Error("cannot allocate libdeflate's compressor");
  std::string out;
  out.append("\x89PNG\r\n\x1a\n", 8);
  std::string ihdr;
  put_be32(ihdr, static_cast<std::uint32_t>(image.width));
  put_be32(ihdr, static_cast<std::uint32_t>(image.height));
  // 8 bits per channel, colour type 2 (RGB), deflate, adaptive-filter method 0, no interlace.
  ihdr.append({'\x08', '\x02', '\0', '\0', '\0'});
  put_chunk(out, "IHDR", reinterpret_cast<const std::uint8_t*>(ihdr.data()), ihdr.size());
  // The IDAT chunk's data compressed in place in the file's buffer (no second copy of the stream), its length and
  // CRC written around it.
  const std::size_t length_at = out.size();
  put_be32(out, 0);
  out.append("IDAT", 4);
  const std::size_t data_at = out.size();
  out.resize(data_at + libdeflate_zlib_compress_bound(c.get(), rows.size()));
  const std::size_t n =
      libdeflate_zlib_compress(c.get(), rows.data(), rows.size(), out.data() + data_at, out.size() - data_at);
  if (n == 0) throw core::Error("libdeflate could not compress the image");
  out.resize(data_at + n);
  std::string length;
  put_be32(length, static_cast<std::uint32_t>(n));
  out.replace(length_at, 4, length);
  put_be32(out, libdeflate_crc32(0, out.data() + data_at - 4, n + 4));
  put_chunk(out, "IEND", nullptr, 0);
  return out;
}

}  // namespace

std::string encode_png(const Image& image, const PngEncoding& enc) {
  const int max_level = enc.deflater == PngDeflater::Libdeflate ? 12 : 9;
  if (enc.level < 0 || enc.level > max_level)
    throw core::Error(fmt::format("PNG compression level {} is not in 0..{} ({})", enc.level, max_level,
                                  enc.deflater == PngDeflater::Libdeflate ? "libdeflate" : "zlib"));
  if (image.width <= 0 || image.height <= 0 ||
      image.rgb.size() != static_cast<std::size_t>(image.width) * image.height * 3)
    throw core::Error("not a complete RGB image");
  if (static_cast<double>(image.rgb.size()) + image.height > 2e9)
    throw core::Error("the image is too large for one PNG data chunk");
  if (enc.deflater == PngDeflater::Libdeflate) return encode_libdeflate(image, enc);
  std::string bytes;
  // A picture compresses to a fraction of its raw size; reserving that avoids most regrowth.
  bytes.reserve(image.rgb.size() / 8 + 1024);
  PngSink sink;
  sink.bytes = &bytes;
  if (!encode_rows(image, enc, sink)) throw core::Error(std::string("cannot encode the PNG: libpng: ") + sink.error);
  return bytes;
}

void write_png(const std::filesystem::path& file, const Image& image, int level) {
  PngEncoding enc;
  enc.level = level;
  write_png(file, image, enc);
}

void write_png(const std::filesystem::path& file, const Image& image, const PngEncoding& enc) {
  std::string bytes;
  try {
    bytes = encode_png(image, enc);
  } catch (const core::Error& e) {
    throw core::Error(file.string() + ": " + e.what());
  }
  core::write_file_atomic(file, bytes);
}

Image read_png(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw core::Error(file.string() + ": cannot open file");
  detail::VtkMessages messages;
  vtkNew<vtkPNGReader> r;
  if (!r->CanReadFile(file.string().c_str())) throw core::Error(file.string() + ": not a PNG file");
  r->SetFileName(file.string().c_str());
  r->Update();
  messages.check(file.string() + ": cannot read the PNG file");
  vtkImageData* data = r->GetOutput();
  int dims[3];
  data->GetDimensions(dims);
  const int nc = data->GetNumberOfScalarComponents();
  if (data->GetScalarType() != VTK_UNSIGNED_CHAR || nc < 1 || nc > 4)
    throw core::Error(file.string() + ": not an 8-bit PNG file");
  Image img;
  img.width = dims[0];
  img.height = dims[1];
  img.rgb.resize(static_cast<std::size_t>(img.width) * img.height * 3);
  const auto* src = static_cast<const std::uint8_t*>(data->GetScalarPointer());
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = src + (static_cast<std::size_t>(img.height - 1 - y) * img.width + x) * nc;
      std::uint8_t* q = img.rgb.data() + (static_cast<std::size_t>(y) * img.width + x) * 3;
      for (int c = 0; c < 3; ++c) q[c] = nc >= 3 ? p[c] : p[0];
    }
  return img;
}

}  // namespace vmsim::render
