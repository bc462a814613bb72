#pragma once
// The HVoxel representation R of one scan: Alg. 1 (2D data indexing) and Alg. 2 (height
// clustering and HVoxel generation), in the map frame.

#include <array>
#include <functional>
#include <span>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"
#include "hmap/maps/hvoxel.hpp"

namespace hmap {

/// The square of cells around the sensor that a scan can reach: max_range / cell cells each side.
/// Scan-local arrays are dense over it, so binning and ray bookkeeping need no hashing.
struct ScanWindow {
  CellKey center;
  std::int32_t half = 0;   ///< cells from the centre to the edge
  std::int32_t width = 1;  ///< 2·half + 1

  [[nodiscard]] std::size_t cells() const { return static_cast<std::size_t>(width) * width; }
  [[nodiscard]] bool contains(const CellKey& k) const {
    return std::abs(static_cast<long>(k.i) - center.i) <= half &&
           std::abs(static_cast<long>(k.j) - center.j) <= half;
  }
  /// Dense index of a cell the window contains.
  [[nodiscard]] std::size_t index(const CellKey& k) const {
    return static_cast<std::size_t>(k.i - center.i + half) * width +
           static_cast<std::size_t>(k.j - center.j + half);
  }
  /// The cell of a dense index.
  [[nodiscard]] CellKey key_of(std::size_t index) const {
    return {static_cast<std::int32_t>(index / static_cast<std::size_t>(width)) - half + center.i,
            static_cast<std::int32_t>(index % static_cast<std::size_t>(width)) - half + center.j};
  }
};

/// One cell of R: its HVoxels are hvoxels[first, first + count), sorted by height.
struct ScanCell {
  CellKey key;
  std::uint32_t first = 0;
  std::uint32_t count = 0;
};

/// How the walls of one scan lean in the frame it was binned in: where that frame's z is not
/// gravity's, a wall's points at height z lie z·δ aside (δ = dx/dz, dy/dz), and each wall tells
/// the component of δ along its normal. Summed over walls (HVoxels at least kMinHeight tall whose
/// points spread in plan along one direction at least twice as far as across it, along it at any
/// one height by kMinSpread of the cell, and that lean by no more than kMaxLean), each weighed by
/// its information S/σ² (S: the points' Σ(z − z̄)², σ²: their scatter across the wall about the
/// fitted lean, no less than kFlatness²). A wall that a cell's edge cuts reads low: each side
/// keeps its own points (half the lean at the edge).
struct WallLean {
  static constexpr double kMinHeight = 1.0;   ///< [m] a wall's HVoxel, at least
  static constexpr std::size_t kMinPoints = 10;
  /// [m] a wall's scatter about its fitted lean, at least: a sensor's range noise and a wall's
  /// own unevenness (the fitted scatter of a wall cut by a cell's edge is smaller, and biased).
  static constexpr double kFlatness = 0.02;
  /// A wall's points at one height (the lean taken out) spread along it by a standard deviation
  /// of at least this share of the cell (a wall across 70 % of it), so that one column of beams
  /// at one azimuth is not taken for a wall.
  static constexpr double kMinSpread = 0.2;
  /// A surface leaning by more than this (dx/dz, 11 deg) is not a wall: a slope, a windscreen.
  static constexpr double kMaxLean = 0.2;
  Eigen::Matrix2d information = Eigen::Matrix2d::Zero();  ///< Σ (S/σ²) n nᵀ [1/(m/m)²]
  Eigen::Vector2d weighted = Eigen::Vector2d::Zero();     ///< Σ (S/σ²) n (n · L)
  std::size_t walls = 0;
  /// δ by least squares over the walls; along a direction they hold under 1e-3 of the best-held
  /// one (all facing one way), zero.
  [[nodiscard]] Eigen::Vector2d lean() const;
  /// The smaller eigenvalue of `information`: 1/σ² of δ along its worst-held direction.
  [[nodiscard]] double weakest() const;
};

/// R: the HVoxels of one scan in the map frame, with what happened to its points.
struct ScanHVoxels {
  Eigen::Vector3d origin_map = Eigen::Vector3d::Zero();  ///< sensor origin [m]
  ScanWindow window;
  std::vector<ScanCell> cells;
  std::vector<HVoxel> hvoxels;
  /// Per HVoxel (same index), the plan centroid (x, y) of the points it was made of, in the map
  /// frame; empty unless the builder keeps them (ScanHVoxelizer::keep_centroids). Within its cell,
  /// where the cell's centre is only within half a cell of the surface.
  std::vector<Eigen::Vector2f> centroids;
  /// The walls' lean in this frame; zero unless the builder measures it (keep_wall_lean).
  WallLean wall_lean;
  std::size_t points_in = 0;
  std::size_t points_kept = 0;
  std::size_t dropped_non_finite = 0;  ///< NaN or infinite coordinates
  std::size_t dropped_range = 0;       ///< closer than min_range or farther than max_range

  [[nodiscard]] std::span<const HVoxel> hvoxels_of(const ScanCell& c) const {
    return {hvoxels.data() + c.first, c.count};
  }
};

/// Builds R scan after scan, reusing its buffers: nothing is allocated per point once warm.
class ScanHVoxelizer {
 public:
  explicit ScanHVoxelizer(const MapParams& params);

  /// Alg. 1 + Alg. 2: transforms points_sensor by T_map_sensor, bins them by cell, clusters each
  /// cell's heights with the point-distance threshold and makes one HVoxel per cluster (eq. 1).
  void build(std::span<const Point3f> points_sensor, const Pose& T_map_sensor, ScanHVoxels& out);
  /// build(), with `alongside(out)` run on another core while the centroids are summed: it may
  /// read out's cells and HVoxels (final by then), not its centroids or wall lean.
  void build(std::span<const Point3f> points_sensor, const Pose& T_map_sensor, ScanHVoxels& out,
             const std::function<void(const ScanHVoxels&)>& alongside);

  /// Whether build() also fills ScanHVoxels::centroids (off by default: the mapper has no use for
  /// them). On, it keeps each point's plan position while binning and sums them per HVoxel after
  /// clustering.
  void keep_centroids(bool on) { keep_centroids_ = on; }
  /// Whether build() also fills ScanHVoxels::wall_lean (needs keep_centroids: it reads the same
  /// per-point plan positions).
  void keep_wall_lean(bool on) { keep_wall_lean_ = on; }

  /// Scan cell index + 1 of each window cell of the last build (0: no point there).
  [[nodiscard]] const std::vector<std::uint32_t>& cell_of_window() const { return cell_of_window_; }

  /// The height gap that splits the cluster of `out`'s cell `c` (a scan this builder made):
  /// map.point_distance_threshold, grown with the cell's distance from the sensor by
  /// map.ring_gap_slope (at most map.ring_gap_max, or the threshold when that is more). The mapper merges the
  /// cell's HVoxels into the map with the same gap (III-D).
  [[nodiscard]] float cell_gap(const ScanHVoxels& out, std::size_t c) const;

 private:
  void index_points(std::span<const Point3f> points_sensor, const Pose& T_map_sensor,
                    ScanHVoxels& out);                 // Alg. 1
  void cluster_heights(ScanHVoxels& out);              // Alg. 2
  void sum_centroids(ScanHVoxels& out);                // ScanHVoxels::centroids
  void sum_wall_lean(ScanHVoxels& out);                // ScanHVoxels::wall_lean

  MapParams params_;
  ScanWindow window_;
  std::vector<std::uint32_t> cell_of_window_;  // dense over the window
  std::vector<std::size_t> used_windows_;      // window cells set in the last build, to reset
  std::vector<std::uint32_t> point_window_;    // per point: its window cell, or a drop code
  std::vector<std::uint32_t> point_cell_;      // per kept point: its scan cell
  std::vector<float> point_z_;                 // per kept point: map z
  std::vector<Eigen::Vector2f> point_xy_;      // per kept point, with keep_centroids_: map x, y − the origin's
  std::vector<Eigen::Vector3d> centroid_sums_;  // per HVoxel: Σx, Σy (from the origin), n
  bool keep_centroids_ = false;
  bool keep_wall_lean_ = false;
  bool ring_gap_ = false;  // map.ring_gap_slope widens the gap of some cell of the window
  std::vector<std::array<double, 9>> moments_;  // per HVoxel with keep_wall_lean_: Σx Σy Σz Σxx Σxy Σyy Σxz Σyz Σzz
  std::vector<std::uint32_t> cell_offset_;     // counting sort of heights by cell (index_points counts)
  std::vector<float> sorted_z_;
  std::vector<std::uint32_t> cluster_count_;   // prefix sums of the clusters per cell
  // eq. (1)'s density of an HVoxel of n points no taller than min_hvoxel_height (V = h_min·A):
  // most of a scan's HVoxels, each of which cost an exp().
  std::array<float, 64> thin_density_{};
};

}  // namespace hmap
