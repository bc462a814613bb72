#pragma once
// The HVoxel metric M_H of section IV-C: the IoU of a scan HVoxel with a map column (eq. 9), an
// IDW-interpolated HVoxel where a neighbour has none in the layer (eq. 12), and the bilinear
// interpolation of the four neighbouring cells with its gradient (eq. 10-11).

#include <array>
#include <span>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"
#include "hmap/maps/hmap.hpp"

namespace hmap::slam {

/// `v` widened about its centre to at least `min_height` [m]: a one-point HVoxel has no height, and
/// the IoU of two zero-length intervals is undefined.
[[nodiscard]] inline Interval widened(const Interval& v, float min_height) {
  const float h = v.z_max - v.z_min;
  if (h >= min_height) return v;
  const float pad = 0.5F * (min_height - h);
  return {v.z_min - pad, v.z_max + pad};
}

/// What one map column holds inside the layer of a scan HVoxel.
struct LayerMatch {
  bool present = false;  ///< at least one map HVoxel overlaps the layer
  float iou = 0.0F;      ///< eq. (9): Σ|v ∩ v_i| / Σ|v ∪ v_i| over those HVoxels; 0 when none
  Interval hull;         ///< [min z_min, max z_max] of those HVoxels (for eq. 12)
};

/// eq. (9) for the (already widened) `layer` against the HVoxels of one column; each map HVoxel
/// is widened to `min_height` too.
[[nodiscard]] LayerMatch match_layer(const Interval& layer, std::span<const HVoxel> column, float min_height);

/// IoU of two intervals (already widened): |a ∩ b| / |a ∪ b|.
[[nodiscard]] float interval_iou(const Interval& a, const Interval& b);

/// The value of M_H and its gradient at one map position (eq. 10, 11).
struct MetricSample {
  float value = 0.0F;
  Eigen::Vector2f gradient = Eigen::Vector2f::Zero();  ///< [1/m] ∂M_H/∂x, ∂M_H/∂y
};

/// eq. (10)-(11): bilinear interpolation of F at (a, b) ∈ [0, 1]² between the cell centres, F[0] =
/// F00 = F(x0, y0), F[1] = F10 = F(x1, y0), F[2] = F01 = F(x0, y1), F[3] = F11 = F(x1, y1); the
/// gradient is in units of 1/m for a cell of `cell_size` metres.
/// Inline: evaluated once per scan HVoxel per Gauss-Newton step.
[[nodiscard]] inline MetricSample bilinear(const std::array<float, 4>& F, float a, float b, float cell_size) {
  // F[0] = F00 (x0, y0), F[1] = F10 (x1, y0), F[2] = F01 (x0, y1), F[3] = F11 (x1, y1).
  MetricSample s;
  s.value = b * (a * F[3] + (1.0F - a) * F[2]) + (1.0F - b) * (a * F[1] + (1.0F - a) * F[0]);  // eq. (10)
  // eq. (11), with the paper's ∂/∂y typo fixed (differences along y, weighted along x) and the
  // cell size made explicit so the gradient is per metre.
  s.gradient.x() = (b * (F[3] - F[2]) + (1.0F - b) * (F[1] - F[0])) / cell_size;
  s.gradient.y() = (a * (F[3] - F[1]) + (1.0F - a) * (F[2] - F[0])) / cell_size;
  return s;
}

/// The map around one scan, read without hashing: a dense grid of tile pointers covering the
/// square of `half` cells about a centre; cells outside it are looked up in the map.
class LocalMapView {
 public:
  LocalMapView() = default;
  /// Covers the cells within `half_cells` of `center`. Reuses its buffer across calls.
  void reset(const HMap& map, const CellKey& center, std::int32_t half_cells);
  /// The HVoxels of a cell (empty when nothing was stored there).
  /// Inline: the metric reads up to 16 columns per scan HVoxel whose cells change.
  [[nodiscard]] std::span<const HVoxel> column(const CellKey& key) const {
    const CellKey t = HMap::tile_of(key);
    const std::int32_t ti = t.i - tile_min_.i;
    const std::int32_t tj = t.j - tile_min_.j;
    if (ti >= 0 && tj >= 0 && ti < tiles_wide_ && tj < tiles_wide_) {
      const HMap::Tile* tile =
          tiles_[static_cast<std::size_t>(ti) * static_cast<std::size_t>(tiles_wide_) + static_cast<std::size_t>(tj)];
      return tile != nullptr ? tile->column(HMap::local_index(key)).hvoxels() : std::span<const HVoxel>{};
    }
    return map_ != nullptr ? map_->column(key).hvoxels() : std::span<const HVoxel>{};
  }
  [[nodiscard]] const HMap* map() const { return map_; }

 private:
  const HMap* map_ = nullptr;
  CellKey tile_min_;
  std::int32_t tiles_wide_ = 0;
  std::vector<const HMap::Tile*> tiles_;  // the tiles of the square, row by row, or nullptr
};

/// The F values of the four cells around a map position for one scan HVoxel's layer: eq. (9) where
/// the cell has HVoxels in the layer, else eq. (12)'s IDW HVoxel from the window around the cell
/// (its IoU scaled by `slam.idw_weight`), else 0.
class LayerInterpolator {
 public:
  explicit LayerInterpolator(const Params& params);
  /// F00, F10, F01, F11 of the cells (i0, j0), (i0+1, j0), (i0, j0+1), (i0+1, j0+1).
  [[nodiscard]] std::array<float, 4> corner_values(const LocalMapView& view, const Interval& layer,
                                                   const CellKey& base) const;

 private:
  int half_window_;
  float min_height_;
  float idw_weight_;
  std::vector<float> idw_weight_of_offset_;  // 1/d^p by (di, dj) offset in the window, 0 at the centre
};

}  // namespace hmap::slam
