#pragma once
// The ground height of the traversability layers as a GeoTIFF that QGIS, GDAL and grid_map users
// open: one Float32 band, north up, NaN where there is no ground, in the map's own frame (no
// coordinate reference system: the map frame is local).

#include <filesystem>

#include "hmap/occupancy/traversability.hpp"

namespace hmap {

/// Writes layers.ground_z to `path` atomically (built in GDAL's memory file system, then written
/// as one file). The geotransform puts pixel (0, 0)'s top-left corner at (i_min·cell,
/// (j_min + height)·cell). Throws hmap::Error for empty layers or a GDAL failure.
void write_ground_geotiff(const std::filesystem::path& path, const TraversabilityLayers& layers);

}  // namespace hmap
