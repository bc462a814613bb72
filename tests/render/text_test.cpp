// Text in pictures (src/hmap/render/text.hpp): a real font, fitted to its box, drawn inside it.

#include "hmap/render/text.hpp"

#include <gtest/gtest.h>

#include <string>

namespace hmap::render {
namespace {

/// The rightmost and lowest column / row holding ink (a pixel not white); -1 when none.
std::pair<int, int> ink_extent(const RgbImage& img) {
  int right = -1, bottom = -1;
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const std::size_t k = 3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(x));
      if (img.rgb[k] != 255 || img.rgb[k + 1] != 255 || img.rgb[k + 2] != 255) {
        right = std::max(right, x);
        bottom = std::max(bottom, y);
      }
    }
  }
  return {right, bottom};
}

// The width measured is the width drawn, and longer text is wider.
TEST(TextTest, MeasureMatchesTheInkDrawn) {
  const TextSize a = measure_text("HMAP", 20);
  const TextSize b = measure_text("HMAP 2D grid judged from the final map", 20);
  EXPECT_GT(a.width, 20);
  EXPECT_GT(b.width, 3 * a.width);
  EXPECT_GE(a.height, 20);
  RgbImage img(400, 60, 255);
  draw_text(img, 10, 5, "HMAP", 20, 0, 0, 0);
  const auto [right, bottom] = ink_extent(img);
  EXPECT_GT(right, 10 + a.width / 2);
  EXPECT_LE(right, 10 + a.width);
  EXPECT_LE(bottom, 5 + a.height);
  EXPECT_EQ(measure_text("", 20).width, 0);
}

// Labels of any length fit their panel: drawn into a picture wider than the box, no ink falls
// beyond the box (the clipping at the picture's edge cannot hide an overflow), and there is ink.
TEST(TextTest, FittedTextStaysInsideItsBox) {
  const std::string labels[] = {"II", "IIIb HMAP 2D grid judged from the final map",
                                "a very long title that no panel of one hundred pixels could hold on one line",
                                "Supercalifragilisticexpialidocious-without-spaces", "0.50 m", "path poses_tum.txt"};
  for (const int box : {60, 100, 137, 300}) {
    for (const std::string& label : labels) {
      SCOPED_TRACE(label + " in " + std::to_string(box) + " px");
      const FittedText fitted = fit_text(label, box, 20, 11);
      ASSERT_FALSE(fitted.lines.empty());
      EXPECT_GE(fitted.pixel_height, 11);
      EXPECT_LE(fitted.pixel_height, 20);
      RgbImage img(box + 300, fitted.height() + 40, 255);
      const int h = draw_fitted(img, 0, 0, fitted, 0, 0, 0);
      const auto [right, bottom] = ink_extent(img);
      EXPECT_GE(right, 0);
      EXPECT_LT(right, box);
      EXPECT_LT(bottom, h + 2);
      for (const std::string& line : fitted.lines) EXPECT_LE(measure_text(line, fitted.pixel_height).width, box) << line;
    }
  }
  // A short label keeps the large size on one line; a long one shrinks, then wraps.
  EXPECT_EQ(fit_text("II", 100, 20, 11).pixel_height, 20);
  EXPECT_EQ(fit_text(labels[2], 100, 20, 11).pixel_height, 11);
  EXPECT_GT(fit_text(labels[2], 100, 20, 11).lines.size(), 2U);
}

}  // namespace
}  // namespace hmap::render
