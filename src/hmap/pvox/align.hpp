#pragma once
// The position measurement of the filter: a point-to-plane alignment of a scan against the voxel
// map, solving for the planar translation (x, y) only (the seed's robot moves on a floor, its
// heading given). Each map voxel with enough points is a plane when the points of its 3×3×3
// neighbourhood are flat (its mean, and the eigenvector of their smallest covariance
// eigenvalue); each scan point is matched
// to the nearest such mean (kd-tree) and the robust (Huber) Gauss-Newton step minimises
// Σ w (nᵀ(p + t − μ))².

#include <Eigen/Core>
#include <cstdint>

#include "hmap/core/types.hpp"
#include "hmap/pvox/voxel_map.hpp"

namespace hmap::pvox {

struct AlignParams {
  int max_iterations = 40;
  double max_distance = 0.25;        ///< [m] correspondence gate of the first iteration
  double min_distance = 0.05;        ///< [m] the gate shrinks to this
  double convergence = 2e-5;         ///< [m] stop when a step is shorter
  double huber = 0.01;               ///< [m] Huber threshold of the point-to-plane residual
  std::size_t max_points = 8000;     ///< scan points used (evenly subsampled)
  std::uint32_t min_voxel_points = 2;  ///< a map voxel needs this many points to anchor a plane
  std::uint32_t min_plane_points = 10; ///< and its 3×3×3 neighbourhood this many to fit one
  double flatness = 0.1;             ///< [-] a plane needs λ_min ≤ flatness · λ_mid (of the 3×3×3 voxels' points)
  double max_offset = 0.5;           ///< [m] a larger correction is reported as not converged
};

struct AlignResult {
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();  ///< [m] to add to the guess's x, y
  bool valid = false;      ///< enough planes and correspondences, offset finite and within max_offset
  bool converged = false;  ///< the last step was below `convergence`
  int iterations = 0;
  std::size_t correspondences = 0;  ///< in the last iteration
  std::size_t planes = 0;           ///< map voxels used as planes
  double rms = 0.0;                 ///< [m] point-to-plane, last iteration
};

/// Aligns `points_sensor` taken at `T_map_sensor_guess` to `map`. Not converged (zero offset)
/// when the map has fewer than 3 planes or fewer than 10 correspondences.
[[nodiscard]] AlignResult align_xy(const VoxelMap& map, const PointCloud& points_sensor, const Pose& T_map_sensor_guess,
                                   const AlignParams& params = {});

}  // namespace hmap::pvox
