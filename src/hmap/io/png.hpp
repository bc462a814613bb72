#pragma once
// PNG pictures (libpng), written atomically.

#include <cstdint>
#include <filesystem>
#include <vector>

namespace hmap {

/// An 8-bit RGB picture, row-major from the top row.
struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;  ///< width · height · 3 bytes

  RgbImage() = default;
  RgbImage(int w, int h, std::uint8_t fill = 0)
      : width(w), height(h), rgb(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3, fill) {}
  void set(int x, int y, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
    const std::size_t k = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3;
    rgb[k] = r;
    rgb[k + 1] = g;
    rgb[k + 2] = b;
  }
};

/// Writes `image` as a PNG file, replacing `path` atomically. Throws hmap::Error on failure.
void write_png(const std::filesystem::path& path, const RgbImage& image);

}  // namespace hmap
