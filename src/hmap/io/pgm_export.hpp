#pragma once
// The 2D occupancy grid as ROS map_server / Nav2 read it: OUT.pgm + OUT.yaml.

#include <filesystem>

#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// Thresholds written into the YAML and used to colour the picture (map_server's defaults).
struct PgmExportParams {
  double occupied_thresh = 0.65;  ///< [-] p above it: occupied (black, 0)
  double free_thresh = 0.196;     ///< [-] p below it: free (white, 254); between: unknown (205)
};

/// Writes `stem`.pgm (binary P5, the first row the northernmost, one pixel per cell over the
/// observed cells' bounding box) and `stem`.yaml (image, mode trinary, resolution, origin of the
/// lower-left pixel, negate 0, occupied_thresh, free_thresh), both atomically. `stem` may end in
/// .pgm or .yaml, or have no extension. Throws hmap::Error for an empty grid.
void write_pgm_map(const std::filesystem::path& stem, const OccupancyGrid& grid, const PgmExportParams& params = {});

/// `stem` without a trailing .pgm or .yaml: the name write_pgm_map gives its two files.
[[nodiscard]] std::filesystem::path pgm_stem(const std::filesystem::path& stem);

}  // namespace hmap
