#include "hmap/occupancy/occupancy_grid.hpp"

#include <algorithm>

#include "hmap/core/error.hpp"

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

}  // namespace hmap
