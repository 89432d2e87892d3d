// PNG files of pictures: encoded with libpng directly (one fixed row filter, chosen per picture in bench/README.md
// "Pictures' CPU, round 2"), read back through VTK's reader (an independent decoder path for tests and tools).
#include "render/detail.hpp"
#include "render/image.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"

#include <png.h>

#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>

#include <fmt/format.h>

#include <csetjmp>
#include <cstring>
#include <new>
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
  png_set_compression_level(png, enc.zlib_level);
  png_set_compression_strategy(png, enc.rle ? Z_RLE : Z_DEFAULT_STRATEGY);
  png_write_info(png, info);
  const std::size_t row = static_cast<std::size_t>(image.width) * 3;
  for (int y = 0; y < image.height; ++y)
    png_write_row(png, const_cast<png_bytep>(image.rgb.data() + static_cast<std::size_t>(y) * row));
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

std::string encode_png(const Image& image, const PngEncoding& enc) {
  if (enc.zlib_level < 0 || enc.zlib_level > 9)
    throw core::Error(fmt::format("PNG compression level {} is not in 0..9", enc.zlib_level));
  if (image.width <= 0 || image.height <= 0 ||
      image.rgb.size() != static_cast<std::size_t>(image.width) * image.height * 3)
    throw core::Error("not a complete RGB image");
  std::string bytes;
  // A picture compresses to a fraction of its raw size; reserving that avoids most regrowth.
  bytes.reserve(image.rgb.size() / 8 + 1024);
  PngSink sink;
  sink.bytes = &bytes;
  if (!encode_rows(image, enc, sink)) throw core::Error(std::string("cannot encode the PNG: libpng: ") + sink.error);
  return bytes;
}

void write_png(const std::filesystem::path& file, const Image& image, int zlib_level) {
  PngEncoding enc;
  enc.zlib_level = zlib_level;
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
