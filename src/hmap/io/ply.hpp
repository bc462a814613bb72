#pragma once
// Reader for the vertices of a PLY (Stanford polygon) file.

#include <filesystem>

#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap {

/// Reads x, y, z of `element vertex` from an ascii, binary_little_endian or binary_big_endian PLY
/// file. The coordinates may be of any scalar type (char ... double, int8 ... float64) and sit
/// anywhere among other vertex properties; elements before the vertices (lists included) are
/// skipped and the file after them is not read. Non-finite points are dropped and counted in
/// `stats`. Throws InputError naming the file and the line or byte of the problem.
[[nodiscard]] PointCloud read_ply(const std::filesystem::path& path, CloudReadStats* stats = nullptr);

}  // namespace hmap
