#pragma once
// Measuring a map the way the seed's experimenter did with a ruler, for axis-aligned faces:
// where a face lies (its plane) and where it ends (its extent), from the voxels' point moments,
// so that lengths are resolved below the voxel edge.

#include <Eigen/Geometry>
#include <optional>

#include "hmap/pvox/voxel_map.hpp"

namespace hmap::pvox {

/// An axis-aligned face to measure: its normal axis (0 = x, 1 = y, 2 = z) and the box of the map
/// where its voxels are looked for.
struct FaceQuery {
  int axis = 0;
  Eigen::AlignedBox3d region;      ///< [m] voxels whose mean lies inside take part
  std::uint32_t min_points = 3;    ///< voxels with fewer points are ignored
  double max_spread = 0.4;         ///< [edges] σ of a voxel's points along `axis` must be below this
};

/// The plane of the face: the weighted median, over the voxels in the region whose points spread
/// along `axis` by σ ≤ max_spread·edge, of their mean's coordinate on `axis`; the weight of a voxel
/// is n / (σ² + (0.05·edge)²), so flat voxels count most and edge voxels (which also hold points of
/// a neighbouring face, and have a biased mean) little. Nothing without voxels.
[[nodiscard]] std::optional<double> measure_plane(const VoxelMap& map, const FaceQuery& face);

/// Where the face ends along `along` (another axis) on the side `side` (−1: low end, +1: high end):
/// per row of voxels (same key on the third axis), the outermost voxel's points taken as uniform
/// over their extent, so the end is mean ± √3·σ along `along`; the median over rows. Any voxel in
/// the region counts (no flatness test: the end voxels of a face touch other faces).
[[nodiscard]] std::optional<double> measure_extent(const VoxelMap& map, const FaceQuery& face, int along, int side);

}  // namespace hmap::pvox
