#pragma once
// HVoxel ray tracing and free-space computation (section III-C, Alg. 3, Fig. 3).

#include <array>
#include <span>
#include <vector>

#include "hmap/maps/scan_hvoxels.hpp"

namespace hmap {

/// The free HVoxels one scan leaves in one cell: disjoint intervals, each counting its rays.
struct FreeCell {
  static constexpr int kMaxIntervals = 6;
  CellKey key;
  std::uint32_t n = 0;
  std::array<FreeHVoxel, kMaxIntervals> intervals{};

  [[nodiscard]] std::span<const FreeHVoxel> hvoxels() const { return {intervals.data(), n}; }
  /// Unites [lo, hi] (carrying `rays` rays) with the intervals it overlaps. When all slots are
  /// taken and it overlaps none, it joins the nearest interval if closer than `join_gap`, else
  /// it is dropped: leaving space unknown is safer than calling a gap free.
  void add(float lo, float hi, float rays, float join_gap);
};

/// Casts one ray per HVoxel of a scan from the sensor origin and accumulates the free HVoxels.
class FreeSpaceTracer {
 public:
  explicit FreeSpaceTracer(const MapParams& params);

  /// Alg. 3: for every HVoxel with ρ >= n_th, the cells between the sensor's cell and the
  /// HVoxel's cell (ProjectLineTo2D, an exact grid traversal; the HVoxel's own cell excluded)
  /// get the free interval swept between the line models to z_max and to z_min over the cell.
  void trace(const ScanHVoxels& scan);

  [[nodiscard]] const std::vector<FreeCell>& cells() const { return cells_; }
  /// Free cell index + 1 of each window cell of the last trace (0: none).
  [[nodiscard]] const std::vector<std::uint32_t>& cell_of_window() const { return slot_of_window_; }
  [[nodiscard]] std::size_t rays() const { return rays_; }

 private:
  MapParams params_;
  std::vector<std::uint32_t> slot_of_window_;
  std::vector<std::size_t> used_windows_;
  std::vector<FreeCell> cells_;
  std::vector<Eigen::Vector2f> ray_dz_;  // per HVoxel ray of the current cell: (z_min, z_max) − z_s
  std::size_t rays_ = 0;
};

}  // namespace hmap
