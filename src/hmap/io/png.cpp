#include "hmap/io/png.hpp"

#include <png.h>

#include <sstream>

#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"

namespace hmap {

namespace {

void write_to_stream(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::ostream*>(png_get_io_ptr(png));
  out->write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(length));
}

void flush_stream(png_structp png) { static_cast<std::ostream*>(png_get_io_ptr(png))->flush(); }

}  // namespace

void write_png(const std::filesystem::path& path, const RgbImage& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgb.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * 3) {
    throw Error(path.string() + ": cannot write an empty or inconsistent picture");
  }
  write_file_atomic(path, [&](std::ostream& out) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    if (png == nullptr) throw Error("libpng could not start");
    png_infop info = png_create_info_struct(png);
    if (info == nullptr || setjmp(png_jmpbuf(png))) {  // NOLINT: libpng reports errors by longjmp
      png_destroy_write_struct(&png, &info);
      throw Error("libpng failed while writing");
    }
    png_set_write_fn(png, &out, write_to_stream, flush_stream);
    png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8,
                 PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < image.height; ++y) {
      png_write_row(png, const_cast<png_bytep>(image.rgb.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) * 3));
    }
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
  });
}

}  // namespace hmap
