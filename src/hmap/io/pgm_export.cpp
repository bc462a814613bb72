#include "hmap/io/pgm_export.hpp"

#include <algorithm>
#include <charconv>
#include <climits>
#include <cmath>
#include <sstream>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"

namespace hmap {

namespace {

/// The shortest decimal that reads back to the same double.
std::string shortest(double v) {
  char buf[32];
  const auto end = std::to_chars(buf, buf + sizeof buf, v).ptr;
  return {buf, static_cast<std::size_t>(end - buf)};
}

}  // namespace

std::string decimal_multiple(std::int64_t index, double cell) {
  // The shortest round-trip digits of `cell` as mantissa · 10^exponent, multiplied exactly.
  const std::string text = shortest(cell);
  if (!std::isfinite(cell)) return shortest(static_cast<double>(index) * cell);
  std::string digits;
  int exponent = 0;
  bool after_point = false;
  for (std::size_t k = 0; k < text.size(); ++k) {
    const char c = text[k];
    if (c == '-') continue;
    if (c == '.') {
      after_point = true;
    } else if (c == 'e' || c == 'E') {
      exponent += std::stoi(text.substr(k + 1));
      break;
    } else {
      digits += c;
      if (after_point) --exponent;
    }
  }
  // At most 17 significant digits times |index| <= 2^63 fits in 128 bits (a GCC/Clang extension).
  __extension__ typedef unsigned __int128 Wide;
  Wide product = 0;
  for (const char c : digits) product = product * 10 + static_cast<Wide>(c - '0');
  const bool negative = (index < 0) != (cell < 0.0) && index != 0 && product != 0;
  const Wide magnitude = index < 0 ? Wide(0) - static_cast<Wide>(index) : static_cast<Wide>(index);
  product *= magnitude;
  std::string out;
  do {
    out.push_back(static_cast<char>('0' + static_cast<int>(product % 10)));
    product /= 10;
  } while (product > 0);
  std::reverse(out.begin(), out.end());
  // Place the decimal point: out · 10^exponent.
  if (exponent >= 0) {
    if (out != "0") out.append(static_cast<std::size_t>(exponent), '0');
  } else {
    const auto shift = static_cast<std::size_t>(-exponent);
    if (out.size() <= shift) out = std::string(shift - out.size() + 1, '0') + out;
    out = out.substr(0, out.size() - shift) + "." + out.substr(out.size() - shift);
    while (out.back() == '0') out.pop_back();
    if (out.back() == '.') out.pop_back();
  }
  return negative ? "-" + out : out;
}

std::filesystem::path pgm_stem(const std::filesystem::path& stem_in) {
  std::filesystem::path stem = stem_in;
  if (stem.extension() == ".pgm" || stem.extension() == ".yaml") stem.replace_extension();
  return stem;
}

void write_pgm_map(const std::filesystem::path& stem_in, const OccupancyGrid& grid, const PgmExportParams& params) {
  if (!(params.free_thresh > 0.0 && params.free_thresh < params.occupied_thresh && params.occupied_thresh < 1.0)) {
    throw Error("PGM export: thresholds must satisfy 0 < free_thresh < occupied_thresh < 1");
  }
  const std::filesystem::path stem = pgm_stem(stem_in);
  long i_min = LONG_MAX, i_max = LONG_MIN, j_min = LONG_MAX, j_max = LONG_MIN;
  grid.for_each_cell([&](const CellKey& k, float) {
    i_min = std::min<long>(i_min, k.i);
    i_max = std::max<long>(i_max, k.i);
    j_min = std::min<long>(j_min, k.j);
    j_max = std::max<long>(j_max, k.j);
  });
  if (i_min > i_max) throw Error(stem.string() + ": the occupancy grid holds no observed cell, nothing to export");
  const long width = i_max - i_min + 1;
  const long height = j_max - j_min + 1;
  if (width * height > 400L * 1000 * 1000) throw Error(stem.string() + ": the grid is too large for one PGM picture");
  // map_server reads occ = (255 − pixel) / 255 (negate 0): 0 is occupied, 254 free, 205 unknown.
  std::vector<unsigned char> pixels(static_cast<std::size_t>(width * height), 205);
  grid.for_each_cell([&](const CellKey& k, float l) {
    const double p = probability(l);
    const CellClass c = params.reading.classify(p);
    const unsigned char v = c == CellClass::kOccupied ? 0 : c == CellClass::kFree ? 254 : 205;
    const long row = j_max - k.j;  // first row: the largest y
    const long col = k.i - i_min;
    pixels[static_cast<std::size_t>(row * width + col)] = v;
  });
  const std::filesystem::path pgm = std::filesystem::path(stem).concat(".pgm");
  const std::filesystem::path yaml = std::filesystem::path(stem).concat(".yaml");
  std::ostringstream header;
  header << "P5\n# hmap 2D occupancy, " << grid.cell_size() << " m per pixel\n" << width << " " << height << "\n255\n";
  std::string bytes = header.str();
  bytes.append(reinterpret_cast<const char*>(pixels.data()), pixels.size());
  std::ostringstream y;
  y << "image: " << pgm.filename().string() << "\n"
    << "mode: trinary\n"
    << "resolution: " << shortest(grid.cell_size()) << "\n"
    << "origin: [" << decimal_multiple(i_min, grid.cell_size()) << ", "
    << decimal_multiple(j_min, grid.cell_size()) << ", 0.0]\n"
    << "negate: 0\n"
    << "occupied_thresh: " << shortest(params.occupied_thresh) << "\n"
    << "free_thresh: " << shortest(params.free_thresh) << "\n";
  // The YAML says where the image lies: it is the pair's record, removed first and written last,
  // so that a killed export never leaves an old origin beside a new image.
  write_files_with_record({{pgm, bytes}}, yaml, y.str());
}

void write_costmap_pgm(const std::filesystem::path& stem_in, const TraversabilityLayers& layers) {
  std::filesystem::path stem = stem_in;
  if (stem.extension() == ".pgm" || stem.extension() == ".yaml") stem.replace_extension();
  if (layers.width <= 0 || layers.height <= 0) throw Error(stem.string() + ": the costmap holds no cell, nothing to export");
  const auto width = static_cast<std::size_t>(layers.width);
  const auto height = static_cast<std::size_t>(layers.height);
  std::vector<unsigned char> pixels(width * height, 0);
  for (std::size_t row = 0; row < height; ++row) {
    for (std::size_t col = 0; col < width; ++col) {
      const std::uint8_t c = layers.cost[row * width + col];
      const int cost = c == TraversabilityLayers::kUnknown ? 100 : c;
      // First PGM row: the northernmost (largest j).
      pixels[(height - 1 - row) * width + col] = static_cast<unsigned char>(255 - std::lround(2.55 * cost));
    }
  }
  const std::filesystem::path pgm = std::filesystem::path(stem).concat(".pgm");
  const std::filesystem::path yaml = std::filesystem::path(stem).concat(".yaml");
  std::ostringstream header;
  header << "P5\n# hmap traversability cost (0 free .. 100 lethal), " << layers.cell_size << " m per pixel\n" << width << " "
         << height << "\n255\n";
  std::string bytes = header.str();
  bytes.append(reinterpret_cast<const char*>(pixels.data()), pixels.size());
  std::ostringstream y;
  y << "# hmap traversability costmap: map_server's scale mode reads back the cost 0..100; unknown cells are lethal\n"
    << "image: " << pgm.filename().string() << "\n"
    << "mode: scale\n"
    << "resolution: " << shortest(layers.cell_size) << "\n"
    << "origin: [" << decimal_multiple(layers.i_min, layers.cell_size) << ", "
    << decimal_multiple(layers.j_min, layers.cell_size) << ", 0.0]\n"
    << "negate: 0\n"
    << "occupied_thresh: 0.995\n"
    << "free_thresh: 0.005\n";
  // The YAML says where the image lies: it is the pair's record, removed first and written last,
  // so that a killed export never leaves an old origin beside a new image.
  write_files_with_record({{pgm, bytes}}, yaml, y.str());
}

}  // namespace hmap
