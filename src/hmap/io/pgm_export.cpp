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
  write_file_atomic(pgm, bytes);
  std::ostringstream y;
  y << "image: " << pgm.filename().string() << "\n"
    << "mode: trinary\n"
    << "resolution: " << shortest(grid.cell_size()) << "\n"
    << "origin: [" << shortest(static_cast<double>(i_min) * grid.cell_size()) << ", "
    << shortest(static_cast<double>(j_min) * grid.cell_size()) << ", 0.0]\n"
    << "negate: 0\n"
    << "occupied_thresh: " << shortest(params.occupied_thresh) << "\n"
    << "free_thresh: " << shortest(params.free_thresh) << "\n";
  write_file_atomic(yaml, y.str());
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
  write_file_atomic(pgm, bytes);
  std::ostringstream y;
  y << "# hmap traversability costmap: map_server's scale mode reads back the cost 0..100; unknown cells are lethal\n"
    << "image: " << pgm.filename().string() << "\n"
    << "mode: scale\n"
    << "resolution: " << shortest(layers.cell_size) << "\n"
    << "origin: [" << shortest(static_cast<double>(layers.i_min) * layers.cell_size) << ", "
    << shortest(static_cast<double>(layers.j_min) * layers.cell_size) << ", 0.0]\n"
    << "negate: 0\n"
    << "occupied_thresh: 0.995\n"
    << "free_thresh: 0.005\n";
  write_file_atomic(yaml, y.str());
}

}  // namespace hmap
