#include "hmap/io/depth_image.hpp"

#include <png.h>

#include <bit>
#include <csetjmp>
#include <cstring>
#include <string>
#include <string_view>

#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/read_support.hpp"

namespace hmap {

namespace {

/// What the libpng callbacks share with read_depth_png: the file in memory, how far libpng has
/// read, and the message of the error that stopped it.
struct PngSource {
  std::string_view bytes;
  std::size_t offset = 0;
  char message[160] = {};
};

void read_from_memory(png_structp png, png_bytep out, png_size_t length) {
  auto* src = static_cast<PngSource*>(png_get_io_ptr(png));
  if (length > src->bytes.size() - src->offset) {
    png_error(png, "the file ends in the middle of the image");
  }
  std::memcpy(out, src->bytes.data() + src->offset, length);
  src->offset += length;
}

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
  auto* src = static_cast<PngSource*>(png_get_error_ptr(png));
  std::snprintf(src->message, sizeof src->message, "%s", message);
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}  // libpng warnings are not errors

/// Decodes into `image`; returns false (with src.message) when libpng stopped. No C++ object is
/// created in this frame after setjmp, so the longjmp skips no destructor.
bool decode_png(png_structp png, png_infop info, PngSource& src, DepthImage& image,
                std::vector<png_bytep>& rows, std::string& problem) {
  if (setjmp(png_jmpbuf(png))) return false;  // NOLINT: libpng reports errors by longjmp
  png_set_read_fn(png, &src, read_from_memory);
  png_set_user_limits(png, 1U << 15, 1U << 15);
  png_read_info(png, info);
  const png_uint_32 width = png_get_image_width(png, info);
  const png_uint_32 height = png_get_image_height(png, info);
  const int bit_depth = png_get_bit_depth(png, info);
  const int color_type = png_get_color_type(png, info);
  if (bit_depth != 16 || color_type != PNG_COLOR_TYPE_GRAY) {
    problem = "expected a 16-bit grayscale depth image, found bit depth " + std::to_string(bit_depth) +
              " and PNG colour type " + std::to_string(color_type);
    return true;
  }
  // zlib expands at most ~1032:1; a header claiming more pixels than that is refused unallocated.
  const double claimed = 2.0 * static_cast<double>(width) * static_cast<double>(height);
  if (claimed > 1100.0 * static_cast<double>(src.bytes.size()) + 65536.0) {
    problem = "header claims " + std::to_string(width) + "x" + std::to_string(height) +
              " pixels, more than the " + std::to_string(src.bytes.size()) + " bytes of the file can hold";
    return true;
  }
  if constexpr (std::endian::native == std::endian::little) png_set_swap(png);
  (void)png_set_interlace_handling(png);
  png_read_update_info(png, info);
  image.width = static_cast<int>(width);
  image.height = static_cast<int>(height);
  image.pixels.resize(static_cast<std::size_t>(width) * height);
  rows.resize(height);
  for (png_uint_32 v = 0; v < height; ++v) {
    rows[v] = reinterpret_cast<png_bytep>(image.pixels.data() + static_cast<std::size_t>(v) * width);
  }
  png_read_image(png, rows.data());
  png_read_end(png, nullptr);
  return true;
}

void write_to_stream(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::ostream*>(png_get_io_ptr(png));
  out->write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(length));
}

void flush_stream(png_structp png) { static_cast<std::ostream*>(png_get_io_ptr(png))->flush(); }

}  // namespace

DepthImage read_depth_png(const std::filesystem::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  const std::string source = path.string();
  if (bytes.size() < 8 || png_sig_cmp(reinterpret_cast<png_const_bytep>(bytes.data()), 0, 8) != 0) {
    throw InputError(source, detail::byte_position(0), "not a PNG file (bad signature)");
  }
  PngSource src;
  src.bytes = bytes;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &src, on_png_error, on_png_warning);
  if (png == nullptr) throw Error("libpng could not start");
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    throw Error("libpng could not start");
  }
  DepthImage image;
  std::vector<png_bytep> rows;
  std::string problem;
  const bool finished = decode_png(png, info, src, image, rows, problem);
  png_destroy_read_struct(&png, &info, nullptr);
  if (!finished) {
    throw InputError(source, detail::byte_position(src.offset), std::string("corrupt PNG: ") + src.message);
  }
  if (!problem.empty()) throw InputError(source, "PNG header", problem);
  return image;
}

void write_depth_png(const std::filesystem::path& path, const DepthImage& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.pixels.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height)) {
    throw Error(path.string() + ": cannot write an empty or inconsistent depth image");
  }
  write_file_atomic(path, [&](std::ostream& out) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    if (png == nullptr) throw Error("libpng could not start");
    png_infop info = png_create_info_struct(png);
    std::vector<std::uint8_t> row(static_cast<std::size_t>(image.width) * 2);
    if (info == nullptr || setjmp(png_jmpbuf(png))) {  // NOLINT: libpng reports errors by longjmp
      png_destroy_write_struct(&png, &info);
      throw Error("libpng failed while writing");
    }
    png_set_write_fn(png, &out, write_to_stream, flush_stream);
    png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 16,
                 PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int v = 0; v < image.height; ++v) {
      for (int u = 0; u < image.width; ++u) {  // PNG stores 16-bit samples big-endian
        const std::uint16_t d = image.at(u, v);
        row[static_cast<std::size_t>(u) * 2] = static_cast<std::uint8_t>(d >> 8);
        row[static_cast<std::size_t>(u) * 2 + 1] = static_cast<std::uint8_t>(d & 0xFFU);
      }
      png_write_row(png, row.data());
    }
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
  });
}

DepthCamera read_intrinsics(const std::filesystem::path& path, const DepthCamera& base) {
  const std::string bytes = detail::read_file_bytes(path);
  const std::string source = path.string();
  std::vector<double> values;
  std::vector<std::string_view> tokens;
  detail::LineReader lines(bytes);
  std::string_view line;
  std::string cleaned;
  while (lines.next(line)) {
    if (!line.empty() && line.front() == '#') continue;
    cleaned.assign(line);
    for (char& c : cleaned) {
      if (c == ',') c = ' ';
    }
    detail::split_whitespace(cleaned, tokens);
    for (const auto token : tokens) {
      double value = 0.0;
      if (!detail::parse_double(token, value) || !std::isfinite(value)) {
        throw InputError(source, detail::line_position(lines.line_number()),
                         "expected a number, found " + detail::quoted(token));
      }
      if (values.size() == 9) throw InputError(source, detail::line_position(lines.line_number()),
                                               "more than 9 numbers: expected fx fy cx cy or a 3x3 matrix");
      values.push_back(value);
    }
  }
  DepthCamera camera = base;
  if (values.size() == 9) {
    camera.fx = values[0];
    camera.cx = values[2];
    camera.fy = values[4];
    camera.cy = values[5];
  } else if (values.size() == 4) {
    camera.fx = values[0];
    camera.fy = values[1];
    camera.cx = values[2];
    camera.cy = values[3];
  } else {
    throw InputError(source, "", "holds " + std::to_string(values.size()) +
                                     " numbers: expected fx fy cx cy or a 3x3 camera matrix");
  }
  if (!(camera.fx > 0.0) || !(camera.fy > 0.0)) {
    throw InputError(source, "", "focal lengths must be positive");
  }
  return camera;
}

void depth_to_points(const DepthImage& image, const DepthCamera& camera, PointCloud& points_cam,
                     CloudReadStats* stats) {
  points_cam.clear();
  std::size_t invalid = 0;
  const double inv_fx = 1.0 / camera.fx;
  const double inv_fy = 1.0 / camera.fy;
  for (int v = 0; v < image.height; ++v) {
    const double ray_y = (static_cast<double>(v) - camera.cy) * inv_fy;
    for (int u = 0; u < image.width; ++u) {
      const std::uint16_t raw = image.at(u, v);
      if (raw == 0 || raw == camera.invalid_value) {
        ++invalid;
        continue;
      }
      const double d = static_cast<double>(raw) * camera.depth_scale;
      const double ray_x = (static_cast<double>(u) - camera.cx) * inv_fx;
      points_cam.emplace_back(static_cast<float>(ray_x * d), static_cast<float>(ray_y * d), static_cast<float>(d));
    }
  }
  if (stats != nullptr) {
    stats->points_read += image.pixels.size();
    stats->non_finite_dropped += invalid;
  }
}

}  // namespace hmap
