#pragma once
// Pictures of PVOX maps: top view, isometric view (the seed's Figures 12–13) and the probability
// gradient ("vector field") on a horizontal slice.

#include <Eigen/Geometry>
#include <optional>

#include "hmap/io/png.hpp"
#include "hmap/pvox/voxel_map.hpp"

namespace hmap::render {

struct PvoxView {
  double threshold = 0.5;                       ///< voxels with p above it are drawn
  std::optional<Eigen::AlignedBox3d> clip;      ///< only voxels whose centre lies inside (cut walls, ceiling)
  int max_pixels = 1200;                        ///< of the longer side
};

/// The view of the map's bulk: clipped to the 2nd–98th percentile box of the occupied voxels when
/// there are more than 100 (a few far returns would otherwise shrink everything to dots).
[[nodiscard]] PvoxView bulk_view(const pvox::VoxelMap& map);

/// Top view: per pixel the highest occupied voxel, coloured by height, darker for lower p; a
/// scale bar (draw_legend_and_scale) in a panel to the right of the map.
[[nodiscard]] RgbImage render_pvox_top(const pvox::VoxelMap& map, const PvoxView& view);
/// Isometric view from the south-west, 35° up: each occupied voxel a shaded cube, height-coloured.
[[nodiscard]] RgbImage render_pvox_iso(const pvox::VoxelMap& map, const PvoxView& view);
/// The field on the plane z = `z`: p as grey (black 0, white 1; unknown 0.5 mid-grey), and arrows
/// of −∇p (away from obstacles, towards free space) every `arrow_step_px` pixels, length ∝ |∇p|;
/// a scale bar as the top view. (The isometric view has none: its scale changes across it.)
[[nodiscard]] RgbImage render_pvox_gradient(const pvox::VoxelMap& map, const PvoxView& view, double z, int arrow_step_px = 14);

}  // namespace hmap::render
