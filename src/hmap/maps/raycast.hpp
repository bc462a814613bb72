#pragma once
// Rays cast through an HMAP: where a ray from a point first meets an HVoxel. Exact for the
// column model: the ray is walked cell by cell in the plane (Amanatides and Woo), and in each
// cell its height interval is tested against the column's HVoxels, so no step can skip a thin
// one (a floor seen edge-on, a cable).

#include <optional>

#include <Eigen/Core>

#include "hmap/core/types.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/maps/hvoxel.hpp"

namespace hmap {

/// Where a ray first met an HVoxel.
struct RayHit {
  double range = 0.0;                            ///< [m] along the ray from its origin
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< origin + range · direction
  CellKey cell;                                  ///< the column it met
  HVoxel hvoxel{};                               ///< the HVoxel it met
};

/// The first HVoxel the ray origin + t · direction meets for t in [0, max_range] (direction need
/// not be unit length: it is normalised; ranges are in metres). An origin inside an HVoxel meets it
/// at range 0. A point on a cell border belongs to the cell HMap::key_of gives it, and an HVoxel
/// holds its bounds (as HMap::occupied). nullopt when nothing is met. Throws hmap::Error for a
/// non-finite origin or direction, a zero direction, or max_range not in [0, 1e6] m.
[[nodiscard]] std::optional<RayHit> raycast(const HMap& map, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                            double max_range);

}  // namespace hmap
