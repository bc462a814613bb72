#pragma once
// Depth images: 16-bit grayscale PNG files (Kinect, 7-Scenes, TUM RGB-D) and their back-projection
// through a pinhole camera into points of the optical camera frame (x right, y down, z forward).

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap {

/// A 16-bit depth image, row-major from the top row, in the sensor's raw units.
struct DepthImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint16_t> pixels;  ///< width · height values

  [[nodiscard]] std::uint16_t at(int u, int v) const {
    return pixels[static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u)];
  }
};

/// A pinhole depth camera.
struct DepthCamera {
  double fx = 585.0;  ///< focal length along image columns [px] (7-Scenes Kinect)
  double fy = 585.0;  ///< focal length along image rows [px]
  double cx = 320.0;  ///< principal point, column [px]
  double cy = 240.0;  ///< principal point, row [px]
  double depth_scale = 0.001;  ///< metres per raw depth unit (mm: 0.001; TUM RGB-D: 1/5000)
  /// Raw values meaning "no measurement": 0 always, and this one (65535 in 7-Scenes).
  std::uint16_t invalid_value = 65535;
};

/// Reads a 16-bit grayscale PNG (libpng; any bit-exact 16-bit gray image, interlaced or not).
/// Throws InputError naming the file and the byte where libpng stopped for a truncated or corrupt
/// file, and for another pixel format ("expected 16-bit grayscale"). A header claiming more pixels
/// than the compressed data could hold is refused before anything is allocated.
[[nodiscard]] DepthImage read_depth_png(const std::filesystem::path& path);

/// Writes `image` as a 16-bit grayscale PNG, replacing `path` atomically. Throws hmap::Error.
void write_depth_png(const std::filesystem::path& path, const DepthImage& image);

/// Reads pinhole intrinsics: either a 3×3 camera matrix (7-Scenes camera-intrinsics.txt: fx 0 cx /
/// 0 fy cy / 0 0 1) or the four numbers fx fy cx cy, separated by whitespace or commas. The depth
/// scale and invalid value of `base` are kept. Throws InputError for another count, a non-number or
/// a focal length that is not positive.
[[nodiscard]] DepthCamera read_intrinsics(const std::filesystem::path& path, const DepthCamera& base = {});

/// Back-projects every valid pixel: (x, y, z) = ((u − cx)·d/fx, (v − cy)·d/fy, d), d = raw · scale,
/// into `points_cam` (cleared first, capacity reused). Pixels at 0 or `invalid_value` are skipped
/// and counted in stats.non_finite_dropped; stats.points_read counts every pixel.
void depth_to_points(const DepthImage& image, const DepthCamera& camera, PointCloud& points_cam,
                     CloudReadStats* stats = nullptr);

}  // namespace hmap
