#include "hmap/render/text.hpp"

#include <ft2build.h>
#include FT_FREETYPE_H

#include <algorithm>
#include <mutex>

#include "hmap/core/error.hpp"

namespace hmap::render {

namespace {

/// The UTF-8 code points of `text` (a malformed byte stands for itself, as Latin-1).
std::vector<char32_t> code_points(std::string_view text) {
  std::vector<char32_t> out;
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    int extra = c >= 0xF0 ? 3 : c >= 0xE0 ? 2 : c >= 0xC0 ? 1 : 0;
    char32_t cp = extra == 3 ? c & 0x07U : extra == 2 ? c & 0x0FU : extra == 1 ? c & 0x1FU : c;
    if (extra > 0 && i + static_cast<std::size_t>(extra) >= text.size()) {  // cut short: the byte alone
      extra = 0;
      cp = c;
    }
    for (int k = 1; k <= extra; ++k) cp = (cp << 6) | (static_cast<unsigned char>(text[i + static_cast<std::size_t>(k)]) & 0x3FU);
    out.push_back(cp);
    i += 1 + static_cast<std::size_t>(extra);
  }
  return out;
}

/// The one font face of the process, loaded on first use (FreeType faces are not thread-safe:
/// every use holds the mutex).
class Font {
 public:
  static Font& instance() {
    static Font font;
    return font;
  }
  std::mutex mutex;

  /// Sets the size and returns the face.
  FT_Face at(int pixel_height) {
    if (FT_Set_Pixel_Sizes(face_, 0, static_cast<FT_UInt>(std::max(1, pixel_height))) != 0) {
      throw Error(std::string(HMAP_FONT_FILE) + ": FreeType cannot set a size of " + std::to_string(pixel_height) + " px");
    }
    return face_;
  }

 private:
  Font() {
    if (FT_Init_FreeType(&library_) != 0) throw Error("FreeType could not be initialised");
    if (FT_New_Face(library_, HMAP_FONT_FILE, 0, &face_) != 0) {
      FT_Done_FreeType(library_);
      throw Error(std::string(HMAP_FONT_FILE) + ": cannot load the font for the pictures' text (apt-get install fonts-dejavu-core)");
    }
  }
  ~Font() {
    FT_Done_Face(face_);
    FT_Done_FreeType(library_);
  }
  FT_Library library_ = nullptr;
  FT_Face face_ = nullptr;
};

int line_height(FT_Face face) {
  return static_cast<int>((face->size->metrics.ascender - face->size->metrics.descender + 63) >> 6);
}

/// Measures, and draws when `image` is given, holding the font's mutex.
TextSize typeset(RgbImage* image, int x, int y, std::string_view text, int pixel_height, std::uint8_t r, std::uint8_t g,
                std::uint8_t b) {
  Font& font = Font::instance();
  const std::lock_guard lock(font.mutex);
  FT_Face face = font.at(pixel_height);
  const int baseline = y + static_cast<int>((face->size->metrics.ascender + 63) >> 6);
  long pen = 0;  // [1/64 px]
  for (const char32_t cp : code_points(text)) {
    if (FT_Load_Char(face, cp, image != nullptr ? FT_LOAD_RENDER : FT_LOAD_DEFAULT) != 0) continue;
    if (image != nullptr) {
      const FT_Bitmap& bm = face->glyph->bitmap;
      const int left = x + static_cast<int>(pen >> 6) + face->glyph->bitmap_left;
      const int top = baseline - face->glyph->bitmap_top;
      for (unsigned row = 0; row < bm.rows; ++row) {
        for (unsigned col = 0; col < bm.width; ++col) {
          const int px = left + static_cast<int>(col);
          const int py = top + static_cast<int>(row);
          if (px < 0 || py < 0 || px >= image->width || py >= image->height) continue;
          const unsigned a = bm.buffer[static_cast<std::ptrdiff_t>(row) * bm.pitch + col];
          if (a == 0) continue;
          std::uint8_t* p = &image->rgb[3 * (static_cast<std::size_t>(py) * static_cast<std::size_t>(image->width) +
                                             static_cast<std::size_t>(px))];
          const std::uint8_t colour[3] = {r, g, b};
          for (int k = 0; k < 3; ++k) p[k] = static_cast<std::uint8_t>((colour[k] * a + p[k] * (255U - a) + 127U) / 255U);
        }
      }
    }
    pen += face->glyph->advance.x;
  }
  return {static_cast<int>((pen + 63) >> 6), line_height(face)};
}

}  // namespace

TextSize measure_text(std::string_view text, int pixel_height) { return typeset(nullptr, 0, 0, text, pixel_height, 0, 0, 0); }

TextSize draw_text(RgbImage& image, int x, int y, std::string_view text, int pixel_height, std::uint8_t r, std::uint8_t g,
                   std::uint8_t b) {
  return typeset(&image, x, y, text, pixel_height, r, g, b);
}

FittedText fit_text(std::string_view text, int max_width, int max_height, int min_height) {
  FittedText fitted;
  for (int h = max_height; h >= min_height; --h) {
    const TextSize size = measure_text(text, h);
    if (size.width <= max_width) {
      fitted.pixel_height = h;
      fitted.line_height = size.height;
      fitted.lines = {std::string(text)};
      return fitted;
    }
  }
  fitted.pixel_height = min_height;
  fitted.line_height = measure_text("", min_height).height;
  std::string line;
  const auto flush = [&] {
    if (!line.empty()) fitted.lines.push_back(line);
    line.clear();
  };
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find(' ', start);
    if (end == std::string_view::npos) end = text.size();
    std::string word(text.substr(start, end - start));
    start = end + 1;
    if (word.empty()) continue;
    const std::string joined = line.empty() ? word : line + " " + word;
    if (measure_text(joined, min_height).width <= max_width) {
      line = joined;
      continue;
    }
    flush();
    while (!word.empty() && measure_text(word, min_height).width > max_width) word.pop_back();  // cut at the box
    line = word;
  }
  flush();
  return fitted;
}

int draw_fitted(RgbImage& image, int x, int y, const FittedText& text, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  for (std::size_t k = 0; k < text.lines.size(); ++k) {
    draw_text(image, x, y + static_cast<int>(k) * text.line_height, text.lines[k], text.pixel_height, r, g, b);
  }
  return text.height();
}

}  // namespace hmap::render
