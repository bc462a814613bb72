#include "hmap/maps/map_rebuild.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <utility>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/maps/map_merge.hpp"
#include "hmap/maps/mapper.hpp"

namespace hmap {

namespace {

bool finite_pose(const Pose& T) { return T.matrix().allFinite(); }

}  // namespace

void TileRuns::add(const TileSquare& s) {
  for (std::int32_t j = s.lo.j; j <= s.hi.j; ++j) rows_[j].emplace_back(s.lo.i, s.hi.i);
}

void TileRuns::finish() {
  for (auto& [j, runs] : rows_) {
    std::sort(runs.begin(), runs.end());
    std::size_t kept = 0;
    for (const auto& r : runs) {
      if (kept > 0 && r.first <= runs[kept - 1].second + 1) {
        runs[kept - 1].second = std::max(runs[kept - 1].second, r.second);
      } else {
        runs[kept++] = r;
      }
    }
    runs.resize(kept);
  }
}

bool TileRuns::overlaps(const TileSquare& s) const {
  for (std::int32_t j = s.lo.j; j <= s.hi.j; ++j) {
    if (overlaps(j, s.lo.i, s.hi.i)) return true;
  }
  return false;
}

bool TileRuns::overlaps(std::int32_t j, std::int32_t i0, std::int32_t i1) const {
  const auto row = rows_.find(j);
  if (row == rows_.end()) return false;
  const auto& runs = row->second;
  // The first run ending at or after i0: it overlaps [i0, i1] if it begins by i1.
  const auto it = std::lower_bound(runs.begin(), runs.end(), i0,
                                   [](const std::pair<std::int32_t, std::int32_t>& r, std::int32_t v) { return r.second < v; });
  return it != runs.end() && it->first <= i1;
}

double pose_displacement_bound(const Pose& a, const Pose& b, double max_range) {
  const Eigen::Matrix3d turn = b.linear() * a.linear().transpose();
  // The angle from the trace, clamped: rounding can put (trace − 1) / 2 just outside [−1, 1].
  const double c = std::clamp((turn.trace() - 1.0) / 2.0, -1.0, 1.0);
  return (b.translation() - a.translation()).norm() + std::acos(c) * max_range;
}

TileSquare scan_tile_square(const MapParams& params, const Pose& T_map_sensor) {
  const double cell = params.cell_size;
  const Eigen::Vector3d s = T_map_sensor.translation();
  const double gx = std::floor(s.x() / cell);
  const double gy = std::floor(s.y() / cell);
  constexpr double kKeyLimit = 1e9;  // as the scan's window (ScanHVoxelizer): within 10^9 cells
  if (!(std::abs(gx) <= kKeyLimit && std::abs(gy) <= kKeyLimit)) {
    throw Error(format("rebuilding the map: a scan's pose (%g, %g) m is beyond the map's key range", s.x(), s.y()));
  }
  const auto half = static_cast<std::int32_t>(std::ceil(params.max_range / cell)) + 2;
  const CellKey lo{static_cast<std::int32_t>(gx) - half, static_cast<std::int32_t>(gy) - half};
  const CellKey hi{static_cast<std::int32_t>(gx) + half, static_cast<std::int32_t>(gy) + half};
  return {HMap::tile_of(lo), HMap::tile_of(hi)};
}

TileRebuild rebuild_moved_tiles(const HMap& built, std::span<const Pose> T_built, std::span<const Pose> T_corrected,
                                double tolerance, const std::function<void(std::size_t, PointCloud&)>& scan,
                                const RebuiltScan& integrated) {
  if (T_built.size() != T_corrected.size()) {
    throw Error(format("rebuilding the map: %zu poses it was built at but %zu corrected ones", T_built.size(),
                       T_corrected.size()));
  }
  if (!(std::isfinite(tolerance) && tolerance >= 0.0)) {
    throw Error(format("rebuilding the map: the tolerance must be finite and >= 0 m (got %g)", tolerance));
  }
  const MapParams& p = built.params().map;
  const std::size_t n = T_built.size();
  TileRebuild out{HMap(built.params()), PoseList(T_built.begin(), T_built.end())};
  // Which scans moved, and the tiles they reached before or reach now.
  TileRuns& dirty = out.rebuilt;
  std::vector<TileSquare> square(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (!finite_pose(T_built[k]) || !finite_pose(T_corrected[k])) {
      throw Error(format("rebuilding the map: scan %zu's pose is not finite", k));
    }
    square[k] = scan_tile_square(p, T_built[k]);
    if (pose_displacement_bound(T_built[k], T_corrected[k], p.max_range) <= tolerance) continue;
    ++out.scans_moved;
    out.T_map_sensor[k] = T_corrected[k];
    dirty.add(square[k]);
    square[k] = scan_tile_square(p, T_corrected[k]);
    dirty.add(square[k]);
  }
  dirty.finish();
  // The rebuilt tiles, from every scan that reaches one, in order (a column's HVoxels depend on
  // the order of the scans that reach it).
  Mapper mapper(built.params());
  if (out.scans_moved > 0) {
    PointCloud points;
    for (std::size_t k = 0; k < n; ++k) {
      if (!dirty.overlaps(square[k])) continue;
      points.clear();
      scan(k, points);
      (void)mapper.integrate(points, out.T_map_sensor[k]);
      if (integrated) integrated(k, points, out.T_map_sensor[k]);
      ++out.scans_integrated;
    }
  }
  built.for_each_tile([&](const CellKey& tile_key, const HMap::Tile& tile) {
    if (dirty.contains(tile_key)) return;
    copy_tile(out.map, tile_key, tile);
    ++out.tiles_kept;
  });
  mapper.map().for_each_tile([&](const CellKey& tile_key, const HMap::Tile& tile) {
    if (!dirty.contains(tile_key)) return;
    copy_tile(out.map, tile_key, tile);
    ++out.tiles_rebuilt;
  });
  out.map.prune_empty_tiles();
  return out;
}

}  // namespace hmap
