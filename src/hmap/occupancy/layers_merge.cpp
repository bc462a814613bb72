#include "hmap/occupancy/layers_merge.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "hmap/core/error.hpp"

namespace hmap {

void add_evidence(OccupancyGrid& into, const OccupancyGrid& from) {
  if (std::abs(into.cell_size() - from.cell_size()) > 1e-9 * into.cell_size()) {
    throw Error("occupancy grids of different cell sizes cannot be combined");
  }
  from.for_each_cell([&](const CellKey& key, float l) {
    const auto had = into.log_odds_at(key);
    into.set(key, had ? *had + l : l);
  });
}

OccupancyGrid shifted_grid(const OccupancyGrid& grid, const PlanarShift& shift) {
  if (!(std::isfinite(shift.x) && std::isfinite(shift.y) && std::isfinite(shift.yaw))) {
    throw Error("moving a 2D grid: the shift must be finite");
  }
  OccupancyGrid out(grid.cell_size(), probability(grid.clamp_min_log_odds()), probability(grid.clamp_max_log_odds()));
  const double s = grid.cell_size();
  const double c = std::cos(shift.yaw);
  const double sn = std::sin(shift.yaw);
  const double edge = OccupancyGrid::kTileSize * s;
  const auto key = [&](double x, double y) -> CellKey {
    const double fi = std::floor(x / s);
    const double fj = std::floor(y / s);
    if (!(std::abs(fi) < HMap::kMaxKey && std::abs(fj) < HMap::kMaxKey)) {
      throw Error("moving a 2D grid: the shift takes its cells beyond the key range");
    }
    return {static_cast<std::int32_t>(fi), static_cast<std::int32_t>(fj)};
  };
  grid.for_each_tile([&](const CellKey& tile_key, const OccupancyGrid::Tile& tile) {
    const double x0 = tile_key.i * edge;
    const double y0 = tile_key.j * edge;
    const Eigen::AlignedBox2d moved = moved_square_bounds(x0, y0, edge, shift);
    const double lo_x = moved.min().x(), lo_y = moved.min().y(), hi_x = moved.max().x(), hi_y = moved.max().y();
    const CellKey lo = key(lo_x - s, lo_y - s);
    const CellKey hi = key(hi_x + s, hi_y + s);
    for (std::int32_t i = lo.i; i <= hi.i; ++i) {
      for (std::int32_t j = lo.j; j <= hi.j; ++j) {
        const double bx = (i + 0.5) * s - shift.x;
        const double by = (j + 0.5) * s - shift.y;
        const CellKey source = key(c * bx + sn * by, -sn * bx + c * by);
        if (source.i >> OccupancyGrid::kTileBits != tile_key.i || source.j >> OccupancyGrid::kTileBits != tile_key.j) continue;
        const int local = ((source.i & (OccupancyGrid::kTileSize - 1)) << OccupancyGrid::kTileBits) |
                          (source.j & (OccupancyGrid::kTileSize - 1));
        const float l = tile.log_odds[static_cast<std::size_t>(local)];
        if (!std::isnan(l)) out.set({i, j}, l);
      }
    }
  });
  return out;
}

std::size_t join_ground(std::vector<GroundPatch>& into, std::span<const GroundPatch> from) {
  // The patches of `into` bucketed by a grid of the largest patch's size: a centre lies inside a
  // patch only if the patch sits in its bucket or a neighbouring one.
  double bucket = 0.0;
  for (const GroundPatch& p : into) bucket = std::max(bucket, 2.0 * p.half_size);
  const std::size_t base = into.size();
  std::unordered_map<CellKey, std::vector<std::size_t>, CellKeyHash> buckets;
  const auto bucket_of = [&](const Eigen::Vector3d& c) {
    return CellKey{static_cast<std::int32_t>(std::floor(c.x() / bucket)), static_cast<std::int32_t>(std::floor(c.y() / bucket))};
  };
  if (bucket > 0.0) {
    for (std::size_t k = 0; k < base; ++k) buckets[bucket_of(into[k].center)].push_back(k);
  }
  const auto covered = [&](const Eigen::Vector3d& c) {
    if (bucket <= 0.0) return false;
    const CellKey b = bucket_of(c);
    for (int di = -1; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        const auto it = buckets.find({b.i + di, b.j + dj});
        if (it == buckets.end()) continue;
        for (const std::size_t k : it->second) {
          const GroundPatch& p = into[k];
          if (std::abs(c.x() - p.center.x()) <= p.half_size && std::abs(c.y() - p.center.y()) <= p.half_size) return true;
        }
      }
    }
    return false;
  };
  std::vector<int> new_index(from.size(), -1);
  for (std::size_t k = 0; k < from.size(); ++k) {
    const GroundPatch& p = from[k];
    if (covered(p.center)) continue;
    GroundPatch q = p;
    q.parent = p.parent >= 0 && static_cast<std::size_t>(p.parent) < k ? new_index[static_cast<std::size_t>(p.parent)] : -1;
    new_index[k] = static_cast<int>(into.size());
    into.push_back(q);
  }
  return into.size() - base;
}

std::vector<GroundPatch> shifted_ground(std::span<const GroundPatch> patches, const PlanarShift& shift) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(shift.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d t(shift.x, shift.y, shift.z);
  std::vector<GroundPatch> out(patches.begin(), patches.end());
  for (GroundPatch& p : out) {
    p.center = R * p.center + t;
    p.normal = R * p.normal;
  }
  return out;
}

}  // namespace hmap
