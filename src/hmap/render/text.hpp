#pragma once
// Text in pictures with a real font: DejaVu Sans (Debian's fonts-dejavu-core) rendered by FreeType,
// measured before it is drawn so that a label of any length can be fitted to its panel.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/io/png.hpp"

namespace hmap::render {

/// The box a line of text takes at `pixel_height` (the font's em in pixels): its advance width and
/// the line's height (ascender − descender), in pixels.
struct TextSize {
  int width = 0;
  int height = 0;
};

/// Measures `text` (UTF-8). Throws hmap::Error naming the font file when it cannot be loaded.
[[nodiscard]] TextSize measure_text(std::string_view text, int pixel_height);

/// Draws `text` with the top of its line box at (x, y), anti-aliased over the picture; pixels outside
/// the picture are skipped. Returns the size measure_text gives.
TextSize draw_text(RgbImage& image, int x, int y, std::string_view text, int pixel_height, std::uint8_t r,
                   std::uint8_t g, std::uint8_t b);

/// `text` laid out to fit `max_width` pixels: the largest height in [min_height, max_height] at
/// which it fits on one line; else, at min_height, its words wrapped onto as many lines as they
/// need (a word wider than the box alone on its line is cut at the box). Every line fits.
struct FittedText {
  int pixel_height = 0;
  std::vector<std::string> lines;
  int line_height = 0;  ///< [px] from one line's top to the next
  [[nodiscard]] int height() const { return line_height * static_cast<int>(lines.size()); }
};
[[nodiscard]] FittedText fit_text(std::string_view text, int max_width, int max_height, int min_height);

/// Draws a FittedText from (x, y) down; returns its height.
int draw_fitted(RgbImage& image, int x, int y, const FittedText& text, std::uint8_t r, std::uint8_t g, std::uint8_t b);

}  // namespace hmap::render
