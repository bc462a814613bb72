#include "hmap/pvox/measure.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

namespace hmap::pvox {

std::optional<double> measure_plane(const VoxelMap& map, const FaceQuery& face) {
  std::vector<std::pair<double, double>> values;  // (coordinate, weight)
  const double max_sigma = face.max_spread * map.edge();
  map.for_each([&](const VoxelKey& key, const Voxel& v) {
    if (v.hits < face.min_points) return;
    const VoxelMoments m = VoxelMap::moments(v, map.centre(key));
    if (!face.region.contains(m.mean)) return;
    const double spread = m.covariance(face.axis, face.axis);
    if (!(spread <= max_sigma * max_sigma)) return;
    // Flat voxels weigh most: one that also holds points of a neighbouring face (an edge voxel)
    // spreads along the axis and has a biased mean.
    const double floor_sigma = 0.05 * map.edge();
    values.emplace_back(m.mean[face.axis], static_cast<double>(v.hits) / (spread + floor_sigma * floor_sigma));
  });
  if (values.empty()) return std::nullopt;
  std::sort(values.begin(), values.end());
  double total = 0.0;
  for (const auto& [x, w] : values) total += w;
  double acc = 0.0;
  for (const auto& [x, w] : values) {
    acc += w;
    if (acc >= 0.5 * total) return x;
  }
  return values.back().first;
}

std::optional<double> measure_extent(const VoxelMap& map, const FaceQuery& face, int along, int side) {
  const int third = 3 - face.axis - along;
  // Per row (key on the third axis): the outermost voxel along `along` and its end estimate.
  std::map<std::int32_t, std::pair<std::int32_t, double>> rows;
  map.for_each([&](const VoxelKey& key, const Voxel& v) {
    if (v.hits < face.min_points) return;
    const VoxelMoments m = VoxelMap::moments(v, map.centre(key));
    if (!face.region.contains(m.mean)) return;
    const std::int32_t k[3] = {key.i, key.j, key.k};
    const std::int32_t rank = side < 0 ? -k[along] : k[along];
    const double end = m.mean[along] + (side < 0 ? -1.0 : 1.0) * std::sqrt(3.0 * m.covariance(along, along));
    auto [it, inserted] = rows.try_emplace(k[third], rank, end);
    if (!inserted && rank > it->second.first) it->second = {rank, end};
  });
  if (rows.empty()) return std::nullopt;
  std::vector<double> ends;
  ends.reserve(rows.size());
  for (const auto& [row, best] : rows) ends.push_back(best.second);
  std::nth_element(ends.begin(), ends.begin() + static_cast<std::ptrdiff_t>(ends.size() / 2), ends.end());
  return ends[ends.size() / 2];
}

}  // namespace hmap::pvox
