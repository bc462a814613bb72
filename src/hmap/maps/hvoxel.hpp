#pragma once
// The HVoxel of the paper: a vertical interval of one grid cell with its point count and its
// normalised density (section III-B, eq. 1).

#include <cmath>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"

namespace hmap {

/// A height voxel: occupied space between z_min and z_max inside one grid cell.
struct HVoxel {
  float z_min;    ///< [m] lowest point of the cluster
  float z_max;    ///< [m] highest point of the cluster
  float count;    ///< |v|, number of points (fractional after extrusion removes part of it)
  float density;  ///< ρ(v) of eq. (1), in [0, K_m]

  [[nodiscard]] float height() const { return z_max - z_min; }
  [[nodiscard]] Interval interval() const { return {z_min, z_max}; }
  friend bool operator==(const HVoxel&, const HVoxel&) = default;
};

/// A free-space HVoxel of one scan (Alg. 3): the union of the ray bands that crossed a cell.
struct FreeHVoxel {
  float z_min;  ///< [m]
  float z_max;  ///< [m]
  float rays;   ///< |v_f|, number of HVoxel rays united into it
};

/// eq. (1): ρ = K_m / (1 + exp(−K_n (|v| − d_min) / V)), V = h·A, with h floored at
/// `min_hvoxel_height` so a single point (h = 0) has a finite volume.
[[nodiscard]] inline float hvoxel_density(double count, double height, const MapParams& p) {
  const double h = std::max(height, p.min_hvoxel_height);
  const double volume = h * p.cell_size * p.cell_size;
  const double x = p.density_normalization * (count - p.density_min_points) / volume;
  return static_cast<float>(p.density_gain / (1.0 + std::exp(-x)));
}

/// Sets `v.density` from its count and height.
inline void update_density(HVoxel& v, const MapParams& p) {
  v.density = hvoxel_density(v.count, v.height(), p);
}

}  // namespace hmap
