#pragma once
// What a point cloud reader saw in a file, beside the points it returned.

#include <cstddef>

namespace hmap {

/// Counts from one read. `points_read` counts every point record in the file; the returned cloud
/// holds `points_read - non_finite_dropped` points (NaN or infinite coordinates are dropped, as
/// organized clouds mark invalid pixels with NaN).
struct CloudReadStats {
  std::size_t points_read = 0;
  std::size_t non_finite_dropped = 0;

  /// Sums the counts of several reads (a whole sequence of scans).
  CloudReadStats& operator+=(const CloudReadStats& other) {
    points_read += other.points_read;
    non_finite_dropped += other.non_finite_dropped;
    return *this;
  }
};

}  // namespace hmap
