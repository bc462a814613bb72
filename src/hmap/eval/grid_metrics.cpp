#include "hmap/eval/grid_metrics.hpp"

#include <cmath>
#include <limits>
#include <vector>

namespace hmap {

TrueTraversability true_traversability(const PointCloud& truth, const PointCloud& ground_points,
                                       const TraversabilityTruthParams& p) {
  using Lowest = std::unordered_map<CellKey, float, CellKeyHash>;
  Lowest lowest;
  Lowest lowest_ground;
  std::unordered_map<CellKey, std::vector<float>, CellKeyHash> heights;
  const auto key_of = [&](const Point3f& q) {
    return CellKey{static_cast<std::int32_t>(std::floor(q.x() / p.cell_size)),
                   static_cast<std::int32_t>(std::floor(q.y() / p.cell_size))};
  };
  const auto keep_lowest = [](Lowest& m, const CellKey& key, float z) {
    auto [it, fresh] = m.try_emplace(key, z);
    if (!fresh) it->second = std::min(it->second, z);
  };
  for (const Point3f& q : truth) {
    if (!q.allFinite()) continue;
    const CellKey key = key_of(q);
    keep_lowest(lowest, key, q.z());
    heights[key].push_back(q.z());
  }
  for (const Point3f& q : ground_points) {
    if (q.allFinite()) keep_lowest(lowest_ground, key_of(q), q.z());
  }
  const int w = p.ground_window;
  const auto lowest_around = [w](const Lowest& m, const CellKey& key) {
    float z = std::numeric_limits<float>::infinity();
    for (int di = -w; di <= w; ++di) {
      for (int dj = -w; dj <= w; ++dj) {
        if (const auto it = m.find({key.i + di, key.j + dj}); it != m.end()) z = std::min(z, it->second);
      }
    }
    return z;
  };
  TrueTraversability out;
  out.reserve(heights.size());
  for (const auto& [key, zs] : heights) {
    float ground = lowest_around(lowest_ground, key);
    if (!std::isfinite(ground)) ground = lowest_around(lowest, key);
    TrueCell t;
    bool above = false;
    for (const float z : zs) {
      const double h = z - ground;
      t.blocked = t.blocked || (h > p.step && h <= p.robot_height);
      above = above || (h > p.robot_height && z <= p.overhang_cut);
    }
    t.overhang = above && !t.blocked;
    out.emplace(key, t);
  }
  return out;
}

GridScores score_grid(const OccupancyGrid& grid, const TrueTraversability& truth,
                      const std::function<bool(const CellKey&)>& in_scope, const GridReading& reading) {
  GridScores s;
  for (const auto& [key, t] : truth) {
    if (in_scope && !in_scope(key)) continue;
    const auto known = grid.probability_at(key);
    if (!known) continue;
    const double prob = *known;
    const CellClass decided = reading.classify(prob);
    if (decided == CellClass::kUndecided) continue;
    const bool says_blocked = decided == CellClass::kOccupied;
    ++s.compared;
    s.correct += says_blocked == t.blocked ? 1 : 0;
    if (t.blocked) {
      ++s.blocked;
      s.blocked_found += says_blocked ? 1 : 0;
    } else {
      ++s.free;
      s.free_found += says_blocked ? 0 : 1;
    }
    if (t.overhang) {
      ++s.overhang;
      s.overhang_free += says_blocked ? 0 : 1;
    }
  }
  return s;
}

}  // namespace hmap
