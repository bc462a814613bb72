#include "hmap/baseline/elevation_occupancy.hpp"

#include <cmath>

namespace hmap {

HMap as_hmap(const ElevationMap& map) {
  HMap out(map.params());
  map.for_each_cell([&](const CellKey& key, const ElevationCell& c) {
    HVoxel v{c.elevation, c.elevation, static_cast<float>(c.points), 0.0F};
    update_density(v, map.params().map);  // eq. (1)
    out.column_for_update(key).push_back(v);
  });
  return out;
}

ElevationRole elevation_role(double elevation, double ground_z, const OccupancyParams& p) {
  const double above = elevation - ground_z;
  if (above > p.ground_distance) return ElevationRole::kObstacle;
  if (above < -p.ground_distance) return ElevationRole::kDrop;
  return ElevationRole::kGround;
}

OccupancyGrid occupancy_from_elevation(const ElevationMap& map, const GroundModel& ground, const Params& params,
                                       double max_ground_distance) {
  const OccupancyParams& op = params.occupancy;
  OccupancyGrid grid(map.cell_size(), op.clamp_min, op.clamp_max);
  map.for_each_cell([&](const CellKey& key, const ElevationCell& c) {
    const Eigen::Vector2d xy = map.cell_center(key);
    const GroundPatch* patch = ground.nearest(xy.x(), xy.y());
    if (patch == nullptr || (patch->center.head<2>() - xy).norm() > max_ground_distance) return;
    const double g = patch->height_at(xy.x(), xy.y());
    const bool free = elevation_role(c.elevation, g, op) == ElevationRole::kGround;
    grid.update(key, free ? grid.clamp_min_log_odds() : grid.clamp_max_log_odds());
  });
  return grid;
}

}  // namespace hmap
