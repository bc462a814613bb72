#pragma once
// Writers of PLY files for looking at maps and clouds in MeshLab or CloudCompare.
//
// Both write binary_little_endian PLY with vertices `float x, y, z, uchar red, green, blue`,
// coloured by height (blue low, through cyan, green and yellow, to red high) over the z range of
// what is drawn, atomically (readers see the old file or the complete new one).

#include <filesystem>

#include "hmap/core/types.hpp"
#include "hmap/maps/hmap.hpp"

namespace hmap {

/// Each HVoxel of `map` as a closed box over its cell: x, y the cell's extent, z from z_min to
/// z_max (at least 0.1 · cell_size thick, centred, so flat HVoxels stay visible); 8 vertices and
/// 6 quads (`element face`, `property list uchar int vertex_indices`) wound counter-clockwise seen
/// from outside. Box k owns vertices [8k, 8k + 8) and faces [6k, 6k + 6); the order is fixed (tiles
/// by key, cells by HMap::local_index, HVoxels upwards), so equal maps give equal files. Throws
/// hmap::Error when the file cannot be written or the map has more HVoxels than int indices allow.
void write_hvoxel_boxes_ply(const std::filesystem::path& path, const HMap& map);

/// `points` as PLY vertices, in order; non-finite points are written as they are, grey.
/// Throws hmap::Error when the file cannot be written.
void write_points_ply(const std::filesystem::path& path, const PointCloud& points);

}  // namespace hmap
