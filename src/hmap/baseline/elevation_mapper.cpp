#include "hmap/baseline/elevation_mapper.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"

namespace hmap {

void validate(const ElevationParams& p) {
  auto require = [](bool ok, const char* name, double value, const char* domain) {
    if (!ok) throw Error(std::string("elevation.") + name + " = " + std::to_string(value) + ": must be " + domain);
  };
  require(p.sigma_base > 0.0 && std::isfinite(p.sigma_base), "sigma_base", p.sigma_base, "> 0");
  require(p.sigma_per_metre >= 0.0 && std::isfinite(p.sigma_per_metre), "sigma_per_metre", p.sigma_per_metre, ">= 0");
  require(p.mahalanobis_threshold > 0.0, "mahalanobis_threshold", p.mahalanobis_threshold, "> 0");
  require(p.multi_height_noise >= 0.0 && std::isfinite(p.multi_height_noise), "multi_height_noise",
          p.multi_height_noise, ">= 0");
  require(!std::isnan(p.max_height_above_sensor), "max_height_above_sensor", p.max_height_above_sensor,
          "a number (infinity: no limit)");
}

ElevationFusion fuse_measurement(ElevationCell& cell, double z, double variance, const ElevationParams& params) {
  if (!cell.known()) {
    cell.elevation = static_cast<float>(z);
    cell.variance = static_cast<float>(variance);
    return ElevationFusion::kInitialized;
  }
  const double h = cell.elevation;
  const double var_h = cell.variance;
  // The innovation's standard deviation: elevation_mapping divides by σ_h alone, which makes a
  // converged cell jump to every noisy return; the textbook gate adds the measurement's variance.
  const double gate = params.mahalanobis_threshold * std::sqrt(var_h + variance);
  const double d = z - h;
  if (d > gate) {  // a higher surface (a table top over the floor): keep it, as elevation_mapping does
    cell.elevation = static_cast<float>(z);
    cell.variance = static_cast<float>(variance);
    return ElevationFusion::kReplaced;
  }
  if (d < -gate) {  // the floor under something seen before: more doubt, same height
    cell.variance = static_cast<float>(var_h + params.multi_height_noise);
    return ElevationFusion::kRejectedLower;
  }
  // 1D Kalman update.
  cell.elevation = static_cast<float>((variance * h + var_h * z) / (var_h + variance));
  cell.variance = static_cast<float>(var_h * variance / (var_h + variance));
  return ElevationFusion::kFused;
}

ElevationMapper::ElevationMapper(const Params& params, const ElevationParams& elevation)
    : ElevationMapper(ElevationMap(params), elevation) {}

ElevationMapper::ElevationMapper(ElevationMap map, const ElevationParams& elevation)
    : map_(std::move(map)), elevation_(elevation) {
  validate(elevation_);
  const MapParams& mp = map_.params().map;
  // validate() keeps max_range / cell_size <= 2048.
  window_.half = checked_count<std::int32_t>(mp.max_range / mp.cell_size, 1 << 20, "the scan window") + 1;
  window_.width = 2 * window_.half + 1;
  bins_.assign(window_.cells(), Bin{0.0F, 0.0F, 0.0F, 0});
}

ElevationScanStats ElevationMapper::integrate(std::span<const Point3f> points_sensor, const Pose& T_map_sensor) {
  if (!T_map_sensor.matrix().allFinite()) throw Error("scan pose is not finite");
  const MapParams& mp = map_.params().map;
  const double cell = mp.cell_size;
  const Eigen::Vector3d origin = T_map_sensor.translation();
  const double ci = std::floor(origin.x() / cell);
  const double cj = std::floor(origin.y() / cell);
  if (!(std::abs(ci) + window_.half < ElevationMap::kMaxKey && std::abs(cj) + window_.half < ElevationMap::kMaxKey)) {
    throw Error("scan pose is too far from the map origin (beyond 2^30 cells)");
  }
  window_.center = {checked_floor<std::int32_t>(ci, "the scan origin's cell"), checked_floor<std::int32_t>(cj, "the scan origin's cell")};

  ElevationScanStats stats;
  stats.points_in = points_sensor.size();
  const Eigen::Matrix3d R = T_map_sensor.linear();
  const auto min_r2 = static_cast<float>(mp.min_range * mp.min_range);
  const auto max_r2 = static_cast<float>(mp.max_range * mp.max_range);
  const double max_z = origin.z() + elevation_.max_height_above_sensor;

  // Transform and key the points in parallel: each gets its window cell (or a drop code), its
  // map height and its squared range.
  constexpr std::uint32_t kNonFinite = 0xFFFFFFFF;
  constexpr std::uint32_t kOutOfRange = 0xFFFFFFFE;
  constexpr std::uint32_t kTooHigh = 0xFFFFFFFD;
  const std::size_t n = points_sensor.size();
  point_window_.resize(n);
  point_z_.resize(n);
  point_r2_.resize(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 8192), [&](const auto& range) {
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      const Point3f& p_sensor = points_sensor[k];
      if (!p_sensor.allFinite()) {
        point_window_[k] = kNonFinite;
        continue;
      }
      const float r2 = p_sensor.squaredNorm();
      if (r2 < min_r2 || r2 > max_r2) {
        point_window_[k] = kOutOfRange;
        continue;
      }
      const Eigen::Vector3d p_map = R * p_sensor.cast<double>() + origin;
      if (p_map.z() > max_z) {
        point_window_[k] = kTooHigh;
        continue;
      }
      // The HMAP's keys: floor(x / cell), not x times 1 / cell, which can round across a border.
      const std::optional<std::int32_t> i = floor_to<std::int32_t>(p_map.x() / cell);
      const std::optional<std::int32_t> j = floor_to<std::int32_t>(p_map.y() / cell);
      // Outside the window only through rounding at the range limit, as in Mapper, or a pose
      // whose linear part is not a rotation (beyond an int32_t: nothing, no overflowing cast).
      point_window_[k] = i && j && window_.contains(CellKey{*i, *j}) ? static_cast<std::uint32_t>(window_.index(CellKey{*i, *j})) : kOutOfRange;
      point_z_[k] = static_cast<float>(p_map.z());
      point_r2_[k] = r2;
    }
  });

  // Bin: the highest point of the scan in each cell (and its lowest, and the count).
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t w = point_window_[k];
    if (w >= kTooHigh) {
      ++(w == kNonFinite ? stats.dropped_non_finite : w == kOutOfRange ? stats.dropped_range : stats.dropped_height);
      continue;
    }
    Bin& bin = bins_[w];
    const float z = point_z_[k];
    if (bin.points == 0) {
      used_.push_back(w);
      bin = {z, point_r2_[k], z, 1};
    } else {
      if (z > bin.z_max) {
        bin.z_max = z;
        bin.r2_of_max = point_r2_[k];
      }
      bin.z_min = std::min(bin.z_min, z);
      ++bin.points;
    }
    ++stats.points_kept;
  }

  // Fuse: one measurement per cell.
  constexpr std::uint32_t kMaxCount = std::numeric_limits<std::uint32_t>::max();
  stats.cells = used_.size();
  ElevationMap::Tile* tile = nullptr;
  CellKey last_tile;
  for (const std::uint32_t w : used_) {
    Bin& bin = bins_[w];
    const CellKey key = window_.key_of(w);
    const CellKey tile_key = ElevationMap::tile_of(key);
    if (tile == nullptr || !(tile_key == last_tile)) {  // a scan's cells come in runs along its rings
      tile = &map_.tile_for_update(tile_key);
      last_tile = tile_key;
    }
    ElevationCell& c = tile->cells[ElevationMap::local_index(key)];
    switch (fuse_measurement(c, bin.z_max, measurement_variance(std::sqrt(static_cast<double>(bin.r2_of_max)), elevation_), elevation_)) {
      case ElevationFusion::kInitialized: ++stats.initialized; break;
      case ElevationFusion::kFused: ++stats.fused; break;
      case ElevationFusion::kReplaced: ++stats.replaced; break;
      case ElevationFusion::kRejectedLower: ++stats.rejected_lower; break;
    }
    c.lowest = c.known() ? std::min(c.lowest, bin.z_min) : bin.z_min;
    c.points = c.points > kMaxCount - bin.points ? kMaxCount : c.points + bin.points;
    bin.points = 0;
  }
  used_.clear();
  return stats;
}

}  // namespace hmap
