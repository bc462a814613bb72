#include "hmap/occupancy/occupancy_grid.hpp"

#include <algorithm>
#include <cstdint>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap {

OccupancyGrid::OccupancyGrid(double cell_size, double clamp_min, double clamp_max)
    : cell_size_(cell_size), l_min_(0.0F), l_max_(0.0F) {
  if (!(cell_size > 0.0)) throw Error("occupancy grid: cell size must be > 0");
  if (!(clamp_min > 0.0 && clamp_min < 0.5 && clamp_max > 0.5 && clamp_max < 1.0)) {
    throw Error("occupancy grid: clamping bounds must satisfy 0 < min < 0.5 < max < 1");
  }
  l_min_ = log_odds(clamp_min);
  l_max_ = log_odds(clamp_max);
}

void OccupancyGrid::update(const CellKey& key, float measurement_log_odds) {
  float& l = tiles_.find_or_create(tile_of(key)).log_odds[local_index(key)];
  const float previous = std::isnan(l) ? 0.0F : l;
  l = std::clamp(previous + measurement_log_odds, l_min_, l_max_);
}

void OccupancyGrid::set(const CellKey& key, float l) {
  if (!std::isfinite(l)) throw Error("occupancy grid: log-odds must be finite");
  tiles_.find_or_create(tile_of(key)).log_odds[local_index(key)] = std::clamp(l, l_min_, l_max_);
}

std::optional<float> OccupancyGrid::log_odds_at(const CellKey& key) const {
  const Tile* tile = tiles_.find(tile_of(key));
  if (tile == nullptr) return std::nullopt;
  const float l = tile->log_odds[local_index(key)];
  if (std::isnan(l)) return std::nullopt;
  return l;
}

std::optional<double> OccupancyGrid::probability_at(const CellKey& key) const {
  const auto l = log_odds_at(key);
  if (!l) return std::nullopt;
  return probability(*l);
}

std::size_t OccupancyGrid::known_cells() const {
  std::size_t n = 0;
  for_each_cell([&](const CellKey&, float) { ++n; });
  return n;
}

OccupancyGrid more_occupied(const OccupancyGrid& a, const OccupancyGrid& b) {
  if (std::abs(a.cell_size() - b.cell_size()) > 1e-9 * a.cell_size()) {
    throw Error("occupancy grids of different cell sizes cannot be combined");
  }
  OccupancyGrid out(a.cell_size(), probability(a.clamp_min_log_odds()), probability(a.clamp_max_log_odds()));
  a.for_each_cell([&](const CellKey& key, float l) { out.set(key, l); });
  b.for_each_cell([&](const CellKey& key, float l) {
    const auto kept = out.log_odds_at(key);
    if (!kept || l > *kept) out.set(key, l);
  });
  return out;
}

GridRaster raster(const OccupancyGrid& grid, std::size_t max_cells) {
  GridRaster r;
  r.cell_size = grid.cell_size();
  std::int64_t i_min = INT64_MAX, i_max = INT64_MIN, j_min = INT64_MAX, j_max = INT64_MIN;
  grid.for_each_cell([&](const CellKey& k, float) {
    i_min = std::min<std::int64_t>(i_min, k.i);
    i_max = std::max<std::int64_t>(i_max, k.i);
    j_min = std::min<std::int64_t>(j_min, k.j);
    j_max = std::max<std::int64_t>(j_max, k.j);
  });
  if (i_min > i_max) return r;
  const std::int64_t width = i_max - i_min + 1;
  const std::int64_t height = j_max - j_min + 1;
  if (static_cast<double>(width) * static_cast<double>(height) > static_cast<double>(max_cells)) {
    throw Error(format("the 2D grid's observed cells span %lld x %lld cells, more than the %zu cells a raster may hold",
                       static_cast<long long>(width), static_cast<long long>(height), max_cells));
  }
  r.i_min = static_cast<std::int32_t>(i_min);
  r.j_min = static_cast<std::int32_t>(j_min);
  r.width = static_cast<std::int32_t>(width);
  r.height = static_cast<std::int32_t>(height);
  r.probability.assign(static_cast<std::size_t>(width * height), std::numeric_limits<float>::quiet_NaN());
  grid.for_each_cell([&](const CellKey& k, float l) {
    const auto index = static_cast<std::size_t>((k.j - j_min) * width + (k.i - i_min));
    r.probability[index] = static_cast<float>(probability(l));
  });
  return r;
}

}  // namespace hmap
