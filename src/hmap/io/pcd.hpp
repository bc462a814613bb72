#pragma once
// Reader for the Point Cloud Library's PCD format (v0.7; v0.6 and files without VERSION too).

#include <filesystem>
#include <vector>

#include "hmap/core/budget.hpp"
#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap {

/// Reads the x, y, z fields of a PCD file with DATA ascii, binary or binary_compressed (LZF).
/// Fields may come in any order and have any COUNT; x, y, z must have COUNT 1 and TYPE F (SIZE 4
/// or 8), I or U (SIZE 1, 2, 4 or 8). Points with a NaN or infinite coordinate (the invalid pixels
/// of organized clouds) are dropped and counted in `stats`. Throws InputError naming the file and
/// the line or byte for a header that contradicts itself or the file size, and for truncated data.
/// VIEWPOINT tx ty tz qw qx qy qz, the sensor's pose in the cloud's frame, is applied to the points
/// (PCL keeps it beside them as sensor_origin_ / sensor_orientation_); a quaternion whose norm is
/// not 1 is refused.
/// `times_s` given: filled with each kept point's time in seconds from the scan's reference when
/// the file has a field t, time or timestamp (COUNT 1; units as point_times_to_seconds detects
/// them), left empty when it has none. A time that is not finite is refused.
/// `budget` given: binary_compressed data's decompressed bytes and the points made from them (up
/// to 88 times the file's size) are checked against it before they are allocated (hmap::Error).
[[nodiscard]] PointCloud read_pcd(const std::filesystem::path& path, CloudReadStats* stats = nullptr,
                                  std::vector<float>* times_s = nullptr, const MemoryBudget* budget = nullptr);

}  // namespace hmap
