#include "hmap/eval/map_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include <nanoflann.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"

namespace hmap {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kMaxToleranceVoxels = 10;
/// z indices are clamped to ±2^52 so a corrupt HVoxel's range length still fits in 64 bits.
constexpr double kMaxZIndex = 4503599627370496.0;

using ZIndex = std::int64_t;

/// Vertical voxels [lo, hi] of one column, both ends included.
struct ZRange {
  ZIndex lo;
  ZIndex hi;
};

using TruthColumns = std::unordered_map<CellKey, std::vector<ZIndex>, CellKeyHash>;

/// Index l of the vertical voxel [l·h, (l+1)·h) holding z.
ZIndex z_index(double z, double voxel_height) {
  // Clamped first (a height of 3e38 m is the top voxel), so only NaN is refused.
  return checked_floor<ZIndex>(std::clamp(std::floor(z / voxel_height), -kMaxZIndex, kMaxZIndex), "map evaluation: the voxel of height");
}

/// Sorts the ranges and unites those that overlap or touch.
void unite(std::vector<ZRange>& ranges) {
  std::sort(ranges.begin(), ranges.end(), [](const ZRange& a, const ZRange& b) { return a.lo < b.lo; });
  std::size_t out = 0;
  for (const ZRange& r : ranges) {
    if (out > 0 && r.lo <= ranges[out - 1].hi + 1) {
      ranges[out - 1].hi = std::max(ranges[out - 1].hi, r.hi);
    } else {
      ranges[out++] = r;
    }
  }
  ranges.resize(out);
}

/// Appends the voxels each HVoxel of `column` overlaps: l from ⌊z_min/h⌋ to ⌊z_max/h⌋.
void append_map_ranges(const ColumnView& column, double voxel_height, std::vector<ZRange>& ranges) {
  for (const HVoxel& v : column) {
    if (!std::isfinite(v.z_min) || !std::isfinite(v.z_max) || v.z_min > v.z_max) {
      throw Error("map evaluation: the map holds an HVoxel with a non-finite or reversed interval [" +
                  std::to_string(v.z_min) + ", " + std::to_string(v.z_max) + "]");
    }
    ranges.push_back({z_index(v.z_min, voxel_height), z_index(v.z_max, voxel_height)});
  }
}

/// The united voxel ranges of the map columns within `k` cells of `key` (Chebyshev).
void map_ranges_near(const HMap& map, const CellKey& key, int k, double voxel_height,
                     std::vector<ZRange>& ranges) {
  ranges.clear();
  for (int di = -k; di <= k; ++di) {
    for (int dj = -k; dj <= k; ++dj) {
      append_map_ranges(map.column(CellKey{key.i + di, key.j + dj}), voxel_height, ranges);
    }
  }
  unite(ranges);
}

/// Truth voxels by column, each column's z indices sorted and unique.
TruthColumns voxelize_truth(const HMap& map, const PointCloud& points_truth, double voxel_height) {
  TruthColumns columns;
  for (std::size_t n = 0; n < points_truth.size(); ++n) {
    const Point3f& p = points_truth[n];
    const auto key = map.key_of(p.x(), p.y());
    if (!p.allFinite() || !key) {
      throw Error("map evaluation: truth point " + std::to_string(n) +
                  " is not finite or lies beyond the map's cell keys");
    }
    columns[*key].push_back(z_index(p.z(), voxel_height));
  }
  for (auto& [key, zs] : columns) {
    std::sort(zs.begin(), zs.end());
    zs.erase(std::unique(zs.begin(), zs.end()), zs.end());
  }
  return columns;
}

/// Number of voxels in both united range lists.
std::uint64_t intersection_size(const std::vector<ZRange>& a, const std::vector<ZRange>& b) {
  std::uint64_t count = 0;
  std::size_t i = 0;
  std::size_t j = 0;
  while (i < a.size() && j < b.size()) {
    const ZIndex lo = std::max(a[i].lo, b[j].lo);
    const ZIndex hi = std::min(a[i].hi, b[j].hi);
    if (lo <= hi) count += static_cast<std::uint64_t>(hi - lo) + 1;
    if (a[i].hi < b[j].hi) ++i; else ++j;
  }
  return count;
}

void finish(OccupancyScores& s) {
  s.precision = s.map_voxels > 0 ? static_cast<double>(s.map_voxels_matched) / static_cast<double>(s.map_voxels) : 0.0;
  s.recall = s.truth_voxels > 0 ? static_cast<double>(s.truth_voxels_recalled) / static_cast<double>(s.truth_voxels) : 0.0;
  s.f_score = s.precision + s.recall > 0.0 ? 2.0 * s.precision * s.recall / (s.precision + s.recall) : 0.0;
}

OccupancyScores occupancy_from_columns(const HMap& map, const TruthColumns& truth, double voxel_height, int k) {
  OccupancyScores s;
  s.tolerance_voxels = k;
  std::vector<ZRange> ranges;
  std::vector<ZRange> near;

  // Recall: a truth voxel counts if a map voxel lies within k on each axis.
  for (const auto& [key, zs] : truth) {
    map_ranges_near(map, key, k, voxel_height, ranges);
    s.truth_voxels += zs.size();
    for (const ZIndex z : zs) {
      // First range ending at or above z − k; ranges are disjoint and sorted, so their hi grow.
      const auto it = std::lower_bound(ranges.begin(), ranges.end(), z - k,
                                       [](const ZRange& r, ZIndex v) { return r.hi < v; });
      if (it != ranges.end() && it->lo <= z + k) ++s.truth_voxels_recalled;
    }
  }

  // Precision: every voxel an HVoxel overlaps, matched if a truth voxel lies within k.
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    ranges.clear();
    append_map_ranges(column, voxel_height, ranges);
    unite(ranges);
    for (const ZRange& r : ranges) s.map_voxels += static_cast<std::uint64_t>(r.hi - r.lo) + 1;
    near.clear();
    for (int di = -k; di <= k; ++di) {
      for (int dj = -k; dj <= k; ++dj) {
        const auto it = truth.find(CellKey{key.i + di, key.j + dj});
        if (it == truth.end()) continue;
        for (const ZIndex z : it->second) near.push_back({z - k, z + k});
      }
    }
    unite(near);
    s.map_voxels_matched += intersection_size(ranges, near);
  });
  finish(s);
  return s;
}

void check_voxel_height(double voxel_height) {
  if (!(voxel_height > 0.0) || !std::isfinite(voxel_height)) {
    throw Error("map evaluation: voxel_height must be a positive finite number of metres, got " +
                std::to_string(voxel_height));
  }
}

void check_tolerance(int k) {
  if (k < 0 || k > kMaxToleranceVoxels) {
    throw Error("map evaluation: tolerance_voxels must be in [0, " + std::to_string(kMaxToleranceVoxels) +
                "], got " + std::to_string(k));
  }
}

/// nanoflann's view of a PointCloud.
struct CloudAdaptor {
  const PointCloud* points;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return points->size(); }
  [[nodiscard]] float kdtree_get_pt(std::uint32_t idx, std::size_t dim) const {
    return (*points)[idx][static_cast<Eigen::Index>(dim)];
  }
  template <class BBox>
  bool kdtree_get_bbox(BBox& /*bb*/) const {
    return false;  // let nanoflann compute it
  }
};
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>,
                                                   CloudAdaptor, 3>;

/// Distance [m] from every query point to its nearest neighbour in `targets` (not empty).
std::vector<double> nearest_distances(const PointCloud& queries, const PointCloud& targets) {
  const CloudAdaptor adaptor{&targets};
  const KdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  std::vector<double> distances(queries.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.size(), 1024),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t q = range.begin(); q != range.end(); ++q) {
                        std::uint32_t index = 0;
                        float distance_sq = 0.0F;
                        tree.knnSearch(queries[q].data(), 1, &index, &distance_sq);
                        distances[q] = std::sqrt(static_cast<double>(distance_sq));
                      }
                    });
  return distances;
}

void check_cloud(const PointCloud& points, const char* name) {
  if (points.size() >= std::numeric_limits<std::uint32_t>::max()) {
    throw Error(std::string("chamfer distance: the ") + name + " cloud has too many points for the kd-tree");
  }
  for (std::size_t n = 0; n < points.size(); ++n) {
    if (!points[n].allFinite()) {
      throw Error(std::string("chamfer distance: ") + name + " point " + std::to_string(n) + " is not finite");
    }
  }
}

}  // namespace

OccupancyScores occupancy_scores(const HMap& map, const PointCloud& points_truth, double voxel_height,
                                 int tolerance_voxels) {
  check_voxel_height(voxel_height);
  check_tolerance(tolerance_voxels);
  return occupancy_from_columns(map, voxelize_truth(map, points_truth, voxel_height), voxel_height,
                                tolerance_voxels);
}

ChamferScores chamfer_scores(const PointCloud& points_map, const PointCloud& points_truth, double threshold_m) {
  if (!(threshold_m >= 0.0) || !std::isfinite(threshold_m)) {
    throw Error("chamfer distance: the threshold must be a finite number of metres >= 0, got " +
                std::to_string(threshold_m));
  }
  check_cloud(points_map, "map");
  check_cloud(points_truth, "truth");
  ChamferScores s;
  s.map_points = points_map.size();
  s.truth_points = points_truth.size();
  s.threshold_m = threshold_m;
  if (points_map.empty() || points_truth.empty()) {
    s.accuracy_m = s.completeness_m = s.chamfer_m = kNaN;
    return s;
  }
  // Mean and fraction within the threshold; summed serially so the result is deterministic.
  const auto summarise = [threshold_m](const std::vector<double>& distances, double& mean, double& within) {
    double sum = 0.0;
    std::size_t close = 0;
    for (const double d : distances) {
      sum += d;
      if (d <= threshold_m) ++close;
    }
    mean = sum / static_cast<double>(distances.size());
    within = static_cast<double>(close) / static_cast<double>(distances.size());
  };
  summarise(nearest_distances(points_map, points_truth), s.accuracy_m, s.accuracy_within);
  summarise(nearest_distances(points_truth, points_map), s.completeness_m, s.completeness_within);
  s.chamfer_m = 0.5 * (s.accuracy_m + s.completeness_m);
  return s;
}

RecoveredPoints recover_points_capped(const HMap& map, double z_step, std::size_t max_points_per_hvoxel) {
  if (!(z_step > 0.0) || !std::isfinite(z_step)) {
    throw Error("recover_points_capped: z_step must be a positive finite number of metres");
  }
  if (max_points_per_hvoxel < 2) {
    throw Error("recover_points_capped: max_points_per_hvoxel must be >= 2 (both ends of an HVoxel)");
  }
  RecoveredPoints out;
  const auto cap = static_cast<double>(max_points_per_hvoxel);
  map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d xy = map.cell_center(key);
    const auto x = static_cast<float>(xy.x());
    const auto y = static_cast<float>(xy.y());
    for (const HVoxel& v : column) {
      const double h = v.height();
      if (!std::isfinite(h) || h < 0.0) {
        throw Error("map evaluation: the map holds an HVoxel with a non-finite or reversed interval");
      }
      // Same samples as recover_points: z_min + k·z_step for k = 0..⌊h/z_step⌋, then z_max if missed.
      const double steps = std::floor(h / z_step);
      if (steps + 2.0 <= cap) {
        const long last = checked_count<long>(steps, static_cast<long>(std::min<std::size_t>(max_points_per_hvoxel, std::numeric_limits<long>::max())), "an HVoxel's samples");
        for (long k = 0; k <= last; ++k) {
          out.points_map.emplace_back(x, y, static_cast<float>(v.z_min + static_cast<double>(k) * z_step));
        }
        if (steps * z_step < h) out.points_map.emplace_back(x, y, v.z_max);
      } else {
        ++out.capped_hvoxels;
        const double step = h / (cap - 1.0);
        for (std::size_t k = 0; k + 1 < max_points_per_hvoxel; ++k) {
          out.points_map.emplace_back(x, y, static_cast<float>(v.z_min + static_cast<double>(k) * step));
        }
        out.points_map.emplace_back(x, y, v.z_max);
      }
    }
  });
  return out;
}

MapMetrics evaluate_map(const HMap& map, const PointCloud& points_truth, const MapEvalParams& params) {
  if (!(params.voxel_height >= 0.0) || !std::isfinite(params.voxel_height)) {
    throw Error("map evaluation: voxel_height must be >= 0 m (0: the cell size), got " +
                std::to_string(params.voxel_height));
  }
  if (!(params.distance_threshold >= 0.0) || !std::isfinite(params.distance_threshold)) {
    throw Error("map evaluation: distance_threshold must be >= 0 m (0: the cell size), got " +
                std::to_string(params.distance_threshold));
  }
  check_tolerance(params.tolerance_voxels);

  MapMetrics m;
  m.cell_size_m = map.cell_size();
  m.voxel_height_m = params.voxel_height > 0.0 ? params.voxel_height : map.cell_size();
  m.map_empty = map.empty();
  m.truth_empty = points_truth.empty();

  // Occupied-space precision / recall at the map's resolution.
  const TruthColumns truth = voxelize_truth(map, points_truth, m.voxel_height_m);
  m.exact = occupancy_from_columns(map, truth, m.voxel_height_m, 0);
  m.tolerant = occupancy_from_columns(map, truth, m.voxel_height_m, params.tolerance_voxels);

  // Chamfer distance between the height-upsampled map and the truth.
  RecoveredPoints recovered = recover_points_capped(map, m.voxel_height_m, params.max_points_per_hvoxel);
  m.hvoxels_capped = recovered.capped_hvoxels;
  const double threshold = params.distance_threshold > 0.0 ? params.distance_threshold : map.cell_size();
  m.chamfer = chamfer_scores(recovered.points_map, points_truth, threshold);
  return m;
}

}  // namespace hmap
