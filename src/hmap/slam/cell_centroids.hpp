#pragma once
// Where in its cell the map's surface lies (slam.hvoxel_centroids = 2): the plan centroid of the
// points of the tall HVoxels merged into each cell. The HMAP keeps a cell's heights, not where in
// the cell its points were; the SLAM keeps this beside it, so that a scan matched at its points'
// centroids (ScanHVoxels::centroids) meets a map on the same footing.

#include <Eigen/Core>
#include <unordered_map>

#include "hmap/maps/scan_hvoxels.hpp"

namespace hmap::slam {

class CellCentroids {
 public:
  /// Throws hmap::Error for a cell size that is not positive and finite.
  explicit CellCentroids(double cell_size);

  /// Adds the HVoxels of `scan` at least `min_height` tall, each its plan centroid
  /// (ScanHVoxels::centroids) weighted by its points, moved into the map by the planar pose
  /// (x, y, yaw). A scan without centroids adds nothing.
  void add(const ScanHVoxels& scan, double x, double y, double yaw, float min_height);

  /// Adds `weight` points at (x, y) in the map frame to the cell they lie in.
  void add(double x, double y, double weight);

  /// The offset [m] of the cell's centroid from the cell's centre, or nullptr for a cell nothing
  /// tall was merged into.
  [[nodiscard]] const Eigen::Vector2f* offset(const CellKey& key) const {
    const auto it = cells_.find(key);
    return it == cells_.end() ? nullptr : &it->second.offset;
  }

  [[nodiscard]] std::size_t size() const { return cells_.size(); }
  [[nodiscard]] double cell_size() const { return cell_; }

 private:
  struct Cell {
    Eigen::Vector3d sums = Eigen::Vector3d::Zero();  // Σ n·x, Σ n·y, Σ n (map frame)
    Eigen::Vector2f offset = Eigen::Vector2f::Zero();
  };
  double cell_;
  std::unordered_map<CellKey, Cell, CellKeyHash> cells_;
};

}  // namespace hmap::slam
