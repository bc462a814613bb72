#pragma once
// Sub-cell refinement of the planar pose (x, y, yaw) against the vertical surfaces the map has
// seen. The HVoxel match of eq. (5) compares binned columns: a wall is somewhere in its cell, and
// a scan taken a few centimetres and a few tenths of a degree from the last one bins mostly into
// the same cells, so that the IoU's minimum leans toward the pose the map was built from
// (balm_os0, the scanner held still: every scan matched within 0.03 deg of the first while it
// turned by -0.1 to -0.4 deg, which Open3D ICP and the reference both see). Here the walls keep
// their place inside the cells: each column of the map holds the moments (count, mean, 2x2
// scatter) of the plan positions of the points that fell in its tall HVoxels, the scan's cells
// the same in the level frame, and a few Gauss-Newton steps bring the scan cells' centroids onto
// the lines fitted to the map's moments around them (point-to-line in the plane).

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"
#include "hmap/maps/scan_hvoxels.hpp"
#include "hmap/slam/scan_matcher.hpp"

namespace hmap::slam {

/// Moments of plan positions per cell: count, sum and scatter about the cell's corner (floats
/// relative to the cell keep their precision far from the origin).
struct PlanMoments {
  float n = 0.0F;
  float sx = 0.0F, sy = 0.0F;              ///< [m] Σ (x − x0), Σ (y − y0)
  float sxx = 0.0F, sxy = 0.0F, syy = 0.0F;  ///< [m²]
};

/// A cell of a WallGrid: the map cell (i, j) and the height band k (z in [k·band, (k+1)·band)).
struct WallKey {
  std::int32_t i = 0;
  std::int32_t j = 0;
  std::int32_t k = 0;
  friend bool operator==(const WallKey&, const WallKey&) = default;
};

/// The map's CellKeyHash of (i, j), with the band mixed in.
struct WallKeyHash {
  std::size_t operator()(const WallKey& key) const noexcept {
    return CellKeyHash{}(CellKey{key.i, key.j}) ^
           static_cast<std::size_t>(static_cast<std::uint64_t>(static_cast<std::uint32_t>(key.k)) * 0x9E3779B97F4A7C15ULL);
  }
};

/// A grid of PlanMoments per map cell and height band, sparse. The bands keep a slanted or
/// stepped surface's plan position at the heights it was seen at: a scan that sees a car's back
/// or a balcony lower down than the map's earlier scans did is compared with the same heights.
class WallGrid {
 public:
  /// Throws hmap::Error unless both are positive and finite.
  WallGrid(double cell_size, double band_height);

  void clear() { cells_.clear(); }
  [[nodiscard]] bool empty() const { return cells_.empty(); }
  [[nodiscard]] std::size_t size() const { return cells_.size(); }
  [[nodiscard]] double cell_size() const { return cell_; }
  [[nodiscard]] double band_height() const { return band_; }

  /// Adds points (already in the grid's frame; z picks the band). Non-finite ones are skipped.
  void add(std::span<const Eigen::Vector3d> points);
  /// Adds points given in another, level frame: (x, y) turned by R(yaw) and moved by (x, y); z kept.
  void add(std::span<const Eigen::Vector3d> points, const PlanarPose& pose);

  /// The cell and band of a position.
  [[nodiscard]] WallKey key_of(double x, double y, double z) const;
  /// The moments of a cell and band; nullptr when nothing fell in it.
  [[nodiscard]] const PlanMoments* at(const WallKey& key) const;
  /// The cells with their moments, in no particular order.
  [[nodiscard]] const auto& cells() const { return cells_; }
  /// The lower corner of a cell in the plane [m].
  [[nodiscard]] Eigen::Vector2d corner(const WallKey& key) const { return {key.i * cell_, key.j * cell_}; }

 private:
  double cell_;
  double band_;
  std::unordered_map<WallKey, PlanMoments, WallKeyHash> cells_;
};

/// A line through the moments of a grid cell and its eight neighbours in the same band.
struct PlanLine {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  ///< [m] their centroid
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX();  ///< unit, across the line
  double count = 0.0;                                 ///< points behind it
  double thickness = 0.0;                             ///< [m] RMS spread across the line
};

/// The line fitted to the moments of `key` and its eight neighbours (same band), when they hold
/// at least `min_points` points spread along a line (RMS across it at most `max_thickness` and
/// under a quarter of the spread along it); nullopt for a corner, a pole or too few points.
[[nodiscard]] std::optional<PlanLine> line_around(const WallGrid& grid, const WallKey& key, double min_points,
                                                  double max_thickness);

/// What the refinement did on one scan.
struct WallRefinement {
  PlanarPose pose;             ///< the refined pose (the guess when not applied)
  bool applied = false;        ///< the refinement moved the pose
  PlanarPose change;           ///< pose − guess, component by component (zero when not applied)
  int iterations = 0;
  std::size_t pairs = 0;       ///< scan cells paired with a map line at the last iteration
  double rms = 0.0;            ///< [m] RMS distance of those pairs to their lines
  /// Why it was not applied: empty when it was.
  const char* skipped_because = "";
  /// Eigenvalues of the normal equations per pair with yaw scaled by the pairs' RMS radius
  /// [1], ascending: a corridor has one near zero (the axis along it is kept from the guess).
  Eigen::Vector3d eigenvalues = Eigen::Vector3d::Zero();
};

/// Refines a planar pose against a WallGrid. Holds its buffers.
class WallRefiner {
 public:
  /// Throws hmap::Error for invalid parameters.
  explicit WallRefiner(const Params& params);

  /// The positions, in the level frame T_level_sensor puts them in, of the points of
  /// `points_sensor` that lie in an HVoxel at least slam.wall_min_height tall of their cell in
  /// `scan_level` (built from the same points at T_level_sensor; `cell_of_window` is its
  /// ScanHVoxelizer's): walls, cars, trunks; not floors, kerbs or ceilings. Points out of
  /// map.min_range..max_range or not finite are left out, as the HVoxelizer left them.
  void collect(std::span<const Point3f> points_sensor, const Pose& T_level_sensor, const ScanHVoxels& scan_level,
               const std::vector<std::uint32_t>& cell_of_window, std::vector<Eigen::Vector3d>& out) const;

  /// Moves `guess` so that the centroids of `scan` (the scan's wall points binned in its level
  /// frame) lie on the lines of `map`. Steps are taken only along the directions the pairs
  /// constrain (eigenvalues at least slam.degeneracy_ratio of the largest); the result is kept only when at least slam.wall_min_pairs pairs held and it moved
  /// under a cell and slam.wall_max_rotation from the guess.
  [[nodiscard]] WallRefinement refine(const WallGrid& scan, const WallGrid& map, const PlanarPose& guess) const;

 private:
  Params params_;
};

}  // namespace hmap::slam
