#include "hmap/slam/hvoxel_metric.hpp"

#include <algorithm>
#include <cmath>

namespace hmap::slam {

float interval_iou(const Interval& a, const Interval& b) {
  const float inter = a.overlap(b);
  const float uni = a.height() + b.height() - inter;
  return uni > 0.0F ? inter / uni : 0.0F;
}

namespace {
// eq. (9), inlined into corner_values: it is called up to 16 times per scan HVoxel whose cells change.
inline LayerMatch match_layer_inline(const Interval& layer, std::span<const HVoxel> column, float min_height) {
  LayerMatch m;
  float inter_sum = 0.0F;
  float union_sum = 0.0F;
  for (const HVoxel& v : column) {
    const Interval w = widened(v.interval(), min_height);
    if (w.z_max < layer.z_min) continue;
    if (w.z_min > layer.z_max) break;  // sorted by height
    const float inter = layer.overlap(w);
    if (inter <= 0.0F) continue;
    inter_sum += inter;
    union_sum += layer.height() + w.height() - inter;
    if (!m.present) {
      m.hull = v.interval();
      m.present = true;
    } else {
      m.hull.z_min = std::min(m.hull.z_min, v.z_min);
      m.hull.z_max = std::max(m.hull.z_max, v.z_max);
    }
  }
  m.iou = union_sum > 0.0F ? inter_sum / union_sum : 0.0F;
  return m;
}
}  // namespace

LayerMatch match_layer(const Interval& layer, std::span<const HVoxel> column, float min_height) {
  return match_layer_inline(layer, column, min_height);
}

void LocalMapView::reset(const HMap& map, const CellKey& center, std::int32_t half_cells) {
  map_ = &map;
  tile_window<HMap::Tile>(center, half_cells, HMap::kTileBits, [&map](const CellKey& t) { return map.find_tile(t); }, tile_min_,
                          tiles_wide_, tiles_);
}

LayerInterpolator::LayerInterpolator(const Params& params)
    : half_window_(params.slam.interpolation_window / 2),
      min_height_(static_cast<float>(params.slam.min_layer_height)),
      idw_weight_(static_cast<float>(params.slam.idw_weight)) {
  const int w = 2 * half_window_ + 1;
  idw_weight_of_offset_.assign(static_cast<std::size_t>(w * w), 0.0F);
  for (int di = -half_window_; di <= half_window_; ++di) {
    for (int dj = -half_window_; dj <= half_window_; ++dj) {
      if (di == 0 && dj == 0) continue;
      const double d = params.map.cell_size * std::hypot(di, dj);  // ‖v − v_i‖ between cell centres [m]
      idw_weight_of_offset_[static_cast<std::size_t>((di + half_window_) * w + dj + half_window_)] =
          static_cast<float>(1.0 / std::pow(d, params.slam.idw_power));
    }
  }
}

std::array<float, 4> LayerInterpolator::corner_values(const LocalMapView& view, const Interval& layer,
                                                      const CellKey& base) const {
  std::array<float, 4> F{};
  std::array<LayerMatch, 4> corner;
  bool all_present = true;
  for (int c = 0; c < 4; ++c) {
    const CellKey k{base.i + (c & 1), base.j + (c >> 1)};
    corner[static_cast<std::size_t>(c)] = match_layer_inline(layer, view.column(k), min_height_);
    all_present = all_present && corner[static_cast<std::size_t>(c)].present;
    F[static_cast<std::size_t>(c)] = corner[static_cast<std::size_t>(c)].iou;
  }
  if (all_present || half_window_ == 0) return F;

  // eq. (12): the windows of the four corners together cover a (w+1)² block; read it once.
  constexpr int kMaxBlock = 10;  // interpolation_window <= 9
  const int h = half_window_;
  const int block = 2 * h + 2;
  // What eq. (12) needs of a cell: whether the layer is there, and its hull. No default member
  // initialisers, so that the 100-cell scratch is not cleared on every call (5 % of this function);
  // a cell is read only after it is written, as `read` says, and only block² of `read` is cleared.
  struct Hull {
    bool present;
    float z_min;
    float z_max;
  };
  std::array<Hull, kMaxBlock * kMaxBlock> cells;
  std::array<bool, kMaxBlock * kMaxBlock> read;
  std::fill_n(read.begin(), block * block, false);
  // The four corners sit at (h, h) .. (h + 1, h + 1) of the block: already read above.
  for (int c = 0; c < 4; ++c) {
    const auto idx = static_cast<std::size_t>(((c & 1) + h) * block + (c >> 1) + h);
    const LayerMatch& m = corner[static_cast<std::size_t>(c)];
    cells[idx] = {m.present, m.hull.z_min, m.hull.z_max};
    read[idx] = true;
  }
  const int w = 2 * h + 1;
  for (int c = 0; c < 4; ++c) {
    if (corner[static_cast<std::size_t>(c)].present) continue;
    const int ci = (c & 1) + h;  // corner position in the block
    const int cj = (c >> 1) + h;
    float weight_sum = 0.0F;
    float z_min = 0.0F;
    float z_max = 0.0F;
    for (int di = -h; di <= h; ++di) {
      for (int dj = -h; dj <= h; ++dj) {
        if (di == 0 && dj == 0) continue;
        const int bi = ci + di;
        const int bj = cj + dj;
        const auto idx = static_cast<std::size_t>(bi * block + bj);
        if (!read[idx]) {
          const LayerMatch m = match_layer_inline(layer, view.column({base.i - h + bi, base.j - h + bj}), min_height_);
          cells[idx] = {m.present, m.hull.z_min, m.hull.z_max};
          read[idx] = true;
        }
        if (!cells[idx].present) continue;
        const float wgt = idw_weight_of_offset_[static_cast<std::size_t>((di + h) * w + dj + h)];
        weight_sum += wgt;
        z_min += wgt * cells[idx].z_min;
        z_max += wgt * cells[idx].z_max;
      }
    }
    if (weight_sum <= 0.0F) continue;  // nothing in the layer around: F stays 0
    const Interval v_idw = widened({z_min / weight_sum, z_max / weight_sum}, min_height_);
    F[static_cast<std::size_t>(c)] = idw_weight_ * interval_iou(layer, v_idw);
  }
  return F;
}

}  // namespace hmap::slam
