#include "hmap/occupancy/occupancy_update.hpp"

#include <algorithm>
#include <cmath>

#include "hmap/maps/ray_trace.hpp"

namespace hmap {

HVoxelRole hvoxel_role(const HVoxel& v, double ground_z, const OccupancyParams& p) {
  if (v.z_min - ground_z > p.z_plus || v.z_max - ground_z < p.z_minus) return HVoxelRole::kIgnored;
  if (std::abs(v.z_max - ground_z) > p.ground_distance) return HVoxelRole::kObstacle;
  return HVoxelRole::kGround;
}

double inverse_sensor_model(HVoxelRole role, double density, double delta, const OccupancyParams& p) {
  switch (role) {
    case HVoxelRole::kObstacle:
      return std::max(density, 0.5) * std::exp(-(delta * delta) / (2.0 * p.sigma * p.sigma));
    case HVoxelRole::kGround:
      return p.ground_gain + (0.5 - p.ground_gain) / (1.0 + std::exp(-delta / p.ground_distance));
    case HVoxelRole::kIgnored:
      break;
  }
  return 0.5;
}

OccupancyUpdateStats update_occupancy(const ScanHVoxels& scan, const GroundModel& ground, const Params& params,
                                      OccupancyGrid& grid) {
  const OccupancyParams& op = params.occupancy;
  const double cell = params.map.cell_size;
  const double xs = scan.origin_map.x();
  const double ys = scan.origin_map.y();
  OccupancyUpdateStats stats;
  std::unordered_map<CellKey, double, CellKeyHash> p_of_cell;
  std::vector<std::pair<HVoxelRole, double>> judged;  // (role, density) of the current scan cell
  for (const ScanCell& target : scan.cells) {
    const double xt = (target.key.i + 0.5) * cell;
    const double yt = (target.key.j + 0.5) * cell;
    const auto ground_z = ground.ground_height(xt, yt);
    if (!ground_z) {
      ++stats.no_ground;
      continue;
    }
    judged.clear();
    for (const HVoxel& v : scan.hvoxels_of(target)) {
      const HVoxelRole role = hvoxel_role(v, *ground_z, op);
      if (role != HVoxelRole::kIgnored) judged.emplace_back(role, v.density);
    }
    if (judged.empty()) continue;  // only ceilings, crowns or pits here: no evidence for the grid
    ++stats.rays;
    const double length = std::hypot(xt - xs, yt - ys);
    traverse_2d(xs, ys, xt, yt, cell, [&](const CellKey& key, double t_in, double t_out) {
      // |c| − |v|: from the middle of the ray's stretch in this cell to the HVoxel's cell centre.
      const double delta = (0.5 * (t_in + t_out) - 1.0) * length;
      const double at_target = key == target.key ? 0.0 : delta;
      double p = 0.5;
      bool first = true;
      for (const auto& [role, density] : judged) {
        const double q = inverse_sensor_model(role, density, at_target, op);
        p = first ? q : std::max(p, q);
        first = false;
      }
      p = std::clamp(p, op.ground_gain, op.clamp_max);
      auto [it, fresh] = p_of_cell.try_emplace(key, p);
      if (!fresh) it->second = std::max(it->second, p);
      return true;
    });
  }
  for (const auto& [key, p] : p_of_cell) grid.update(key, log_odds(p));
  stats.cells = p_of_cell.size();
  return stats;
}

}  // namespace hmap

namespace hmap {

OccupancyGrid occupancy_from_map(const HMap& map, const GroundModel& ground, const Params& params,
                                 double max_ground_distance) {
  const OccupancyParams& op = params.occupancy;
  OccupancyGrid grid(map.cell_size(), op.clamp_min, op.clamp_max);
  map.for_each_column([&](const CellKey& key, const Column& column) {
    const Eigen::Vector2d xy = map.cell_center(key);
    const GroundPatch* patch = ground.nearest(xy.x(), xy.y());
    if (patch == nullptr || (patch->center.head<2>() - xy).norm() > max_ground_distance) return;
    const double g = patch->height_at(xy.x(), xy.y());
    bool obstacle = false;
    bool drivable = false;
    for (const HVoxel& v : column) {
      const HVoxelRole role = hvoxel_role(v, g, op);
      obstacle = obstacle || role == HVoxelRole::kObstacle;
      drivable = drivable || role == HVoxelRole::kGround;
    }
    if (obstacle) {
      grid.update(key, grid.clamp_max_log_odds());
    } else if (drivable) {
      grid.update(key, grid.clamp_min_log_odds());
    }
  });
  return grid;
}

}  // namespace hmap
