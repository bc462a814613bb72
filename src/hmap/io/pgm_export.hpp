#pragma once
// The 2D occupancy grid as ROS map_server / Nav2 read it: OUT.pgm + OUT.yaml.

#include <cstdint>
#include <filesystem>
#include <string>

#include "hmap/occupancy/grid_reading.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"
#include "hmap/occupancy/traversability.hpp"

namespace hmap {

/// Thresholds written into the YAML (how map_server reads the pixels: 0 occupied, 254 free, 205
/// unknown, with map_server's defaults) and the reading that decides each cell's pixel.
struct PgmExportParams {
  double occupied_thresh = 0.65;  ///< [-] YAML: a pixel's p above it is occupied
  double free_thresh = 0.196;     ///< [-] YAML: a pixel's p below it is free (254 reads 0.004, 205 0.196)
  GridReading reading;            ///< which cells are written 0, 254 or 205 (GridReading::for_map for a map's grid)
};

/// Writes `stem`.pgm (binary P5, the first row the northernmost, one pixel per cell over the
/// observed cells' bounding box) and `stem`.yaml (image, mode trinary, resolution, origin of the
/// lower-left pixel, negate 0, occupied_thresh, free_thresh) as one set (write_files_with_record:
/// whenever the .yaml exists, the .pgm beside it is the one written with it). `stem` may end in
/// .pgm or .yaml, or have no extension. Throws hmap::Error for an empty grid.
void write_pgm_map(const std::filesystem::path& stem, const OccupancyGrid& grid, const PgmExportParams& params = {});

/// The traversability cost as a Nav2 costmap-style map: `stem`.pgm with pixel 255 − round(2.55 ·
/// cost) (negate 0, so map_server reads p = cost / 100) and `stem`.yaml with mode: scale,
/// occupied_thresh 0.995, free_thresh 0.005, so map_server's scale mode gives back the cost:
/// 0 → 0 (free), 100 → 100 (lethal), between 1..99 within one unit. A PGM has no alpha channel,
/// so unknown cells are written lethal (the YAML says so). Written as one set, as write_pgm_map. Throws hmap::Error for empty layers.
void write_costmap_pgm(const std::filesystem::path& stem, const TraversabilityLayers& layers);

/// `index` · `cell` as the shortest exact decimal of the product of the integer and the shortest
/// decimal of `cell` ("0.1" · −219 = "-21.9", where the double product prints as
/// -21.900000000000002): the origin a YAML reader gets is the one a person would write.
[[nodiscard]] std::string decimal_multiple(std::int64_t index, double cell);

/// `stem` without a trailing .pgm or .yaml: the name write_pgm_map gives its two files.
[[nodiscard]] std::filesystem::path pgm_stem(const std::filesystem::path& stem);

}  // namespace hmap
