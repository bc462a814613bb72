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

/// A grid of PlanMoments at one cell size, sparse.
class WallGrid {
 public:
  explicit WallGrid(double cell_size);

  void clear() { cells_.clear(); }
  [[nodiscard]] bool empty() const { return cells_.empty(); }
  [[nodiscard]] std::size_t size() const { return cells_.size(); }
  [[nodiscard]] double cell_size() const { return cell_; }

  /// Adds plan positions (already in the grid's frame). Non-finite ones are skipped.
  void add(std::span<const Eigen::Vector2d> points);
  /// Adds points given in another frame: p_grid = R(yaw)·p + (x, y).
  void add(std::span<const Eigen::Vector2d> points, const PlanarPose& pose);

  /// The cell of a plan position.
  [[nodiscard]] CellKey key_of(double x, double y) const;
  /// The moments of a cell; nullptr when nothing fell in it.
  [[nodiscard]] const PlanMoments* at(const CellKey& key) const;
  /// The cells with their moments, in no particular order.
  [[nodiscard]] const auto& cells() const { return cells_; }
  /// The lower corner of a cell [m].
  [[nodiscard]] Eigen::Vector2d corner(const CellKey& key) const { return {key.i * cell_, key.j * cell_}; }

 private:
  static std::uint64_t pack(const CellKey& k) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.i)) << 32) | static_cast<std::uint32_t>(k.j);
  }
  double cell_;
  std::unordered_map<std::uint64_t, PlanMoments> cells_;
};

/// A line through the moments of a map cell and its eight neighbours.
struct PlanLine {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  ///< [m] their centroid
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX();  ///< unit, across the line
  double count = 0.0;                                 ///< points behind it
  double thickness = 0.0;                             ///< [m] RMS spread across the line
};

/// The line fitted to the moments of `key` and its eight neighbours, when they hold at least
/// `min_points` points spread along a line (RMS across it at most `max_thickness` and under a
/// quarter of the spread along it); nullopt for a corner, a pole or too few points.
[[nodiscard]] std::optional<PlanLine> line_around(const WallGrid& grid, const CellKey& key, double min_points,
                                                  double max_thickness);

/// What the refinement did on one scan.
struct WallRefinement {
  PlanarPose pose;             ///< the refined pose (the guess when not applied)
  bool applied = false;        ///< the refinement moved the pose
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

  /// The plan positions, in the level frame T_level_sensor puts them in, of the points of
  /// `points_sensor` that lie in an HVoxel at least slam.wall_min_height tall of their cell in
  /// `scan_level` (built from the same points at T_level_sensor; `cell_of_window` is its
  /// ScanHVoxelizer's): walls, cars, trunks; not floors, kerbs or ceilings. Points out of
  /// map.min_range..max_range or not finite are left out, as the HVoxelizer left them.
  void collect(std::span<const Point3f> points_sensor, const Pose& T_level_sensor, const ScanHVoxels& scan_level,
               const std::vector<std::uint32_t>& cell_of_window, std::vector<Eigen::Vector2d>& out) const;

  /// Moves `guess` so that the centroids of `scan` (the scan's wall points binned in its level
  /// frame) lie on the lines of `map`. Steps are taken only along the directions the pairs
  /// constrain; the result is kept only when at least slam.wall_min_pairs pairs held and it moved
  /// under a cell and slam.wall_max_rotation from the guess.
  [[nodiscard]] WallRefinement refine(const WallGrid& scan, const WallGrid& map, const PlanarPose& guess) const;

 private:
  Params params_;
};

}  // namespace hmap::slam
