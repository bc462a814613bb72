#include "hmap/baseline/octomap_projection.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>
#include <vector>

namespace hmap {

HMap octomap_as_hmap(const octomap::OcTree& tree, const Params& params) {
  HMap map(params);
  const double cell = params.map.cell_size;
  std::map<CellKey, std::vector<std::pair<float, float>>, bool (*)(const CellKey&, const CellKey&)> columns(
      [](const CellKey& a, const CellKey& b) { return a.i != b.i ? a.i < b.i : a.j < b.j; });
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const double size = it.getSize();
    const double half = size / 2.0;
    const int n = std::max(1, static_cast<int>(std::lround(size / cell)));
    for (int a = 0; a < n; ++a) {
      for (int b = 0; b < n; ++b) {
        const double x = it.getX() - half + (a + 0.5) * cell;
        const double y = it.getY() - half + (b + 0.5) * cell;
        const auto key = map.key_of(x, y);
        if (!key) continue;
        columns[*key].emplace_back(static_cast<float>(it.getZ() - half), static_cast<float>(it.getZ() + half));
      }
    }
  }
  for (auto& [key, spans] : columns) {
    std::sort(spans.begin(), spans.end());
    TileColumn column = map.column_for_update(key);
    std::pair<float, float> run = spans.front();
    const auto flush = [&] {
      const float count = std::round((run.second - run.first) / static_cast<float>(cell));
      column.push_back({run.first, run.second, count, 1.0F});
    };
    for (std::size_t k = 1; k < spans.size(); ++k) {
      if (spans[k].first <= run.second + 1e-4F) {
        run.second = std::max(run.second, spans[k].second);
      } else {
        flush();
        run = spans[k];
      }
    }
    flush();
  }
  return map;
}

OccupancyGrid project_octomap(const octomap::OcTree& tree, const GroundModel& ground, double cell_size,
                              const OccupancyParams& occupancy, const OctomapProjectionParams& p) {
  enum class Seen : std::uint8_t { kFree, kOccupied };
  std::unordered_map<CellKey, Seen, CellKeyHash> seen;
  std::unordered_map<CellKey, double, CellKeyHash> ground_of;  // NaN: no patch within reach
  const auto local_ground = [&](const CellKey& key) {
    auto [it, fresh] = ground_of.try_emplace(key, 0.0);
    if (fresh) {
      const double x = (key.i + 0.5) * cell_size;
      const double y = (key.j + 0.5) * cell_size;
      const GroundPatch* patch = ground.nearest(x, y);
      it->second = patch != nullptr && (patch->center.head<2>() - Eigen::Vector2d(x, y)).norm() <= p.ground_reach
                       ? patch->height_at(x, y)
                       : std::numeric_limits<double>::quiet_NaN();
    }
    return it->second;
  };
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    const bool occupied = tree.isNodeOccupied(*it);
    const double size = it.getSize();
    const double half = size / 2.0;
    // A pruned leaf covers several cells: each takes it (its centre height) against its own ground.
    const int n = std::max(1, static_cast<int>(std::lround(size / cell_size)));
    for (int a = 0; a < n; ++a) {
      for (int b = 0; b < n; ++b) {
        const double x = it.getX() - half + (a + 0.5) * cell_size;
        const double y = it.getY() - half + (b + 0.5) * cell_size;
        const CellKey key{static_cast<std::int32_t>(std::floor(x / cell_size)),
                          static_cast<std::int32_t>(std::floor(y / cell_size))};
        const double g = local_ground(key);
        if (std::isnan(g)) continue;
        const double h = it.getZ() - g;
        if (h < p.min_height || h > p.max_height) continue;
        auto [slot, fresh] = seen.try_emplace(key, occupied ? Seen::kOccupied : Seen::kFree);
        if (!fresh && occupied) slot->second = Seen::kOccupied;
      }
    }
  }
  OccupancyGrid grid(cell_size, occupancy.clamp_min, occupancy.clamp_max);
  for (const auto& [key, s] : seen) {
    grid.update(key, s == Seen::kOccupied ? grid.clamp_max_log_odds() : grid.clamp_min_log_odds());
  }
  return grid;
}

}  // namespace hmap
