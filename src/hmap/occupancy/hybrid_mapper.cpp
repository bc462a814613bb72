#include "hmap/occupancy/hybrid_mapper.hpp"

#include <utility>

namespace hmap {

HybridMapper::HybridMapper(const Params& params)
    : mapper_(params),
      ground_(params.ground),
      grid_(params.map.cell_size, params.occupancy.clamp_min, params.occupancy.clamp_max),
      occupancy_(params) {}

HybridMapper::HybridMapper(HMap map, OccupancyGrid grid, std::vector<GroundPatch> patches)
    : mapper_(std::move(map)),
      ground_(mapper_.map().params().ground, mapper_.map().params().ground.expansion_distance / 2.0,
              std::move(patches)),
      grid_(std::move(grid)),
      occupancy_(mapper_.map().params()) {}

HybridScanStats HybridMapper::integrate(std::span<const Point3f> points_sensor, const Pose& T_map_sensor) {
  HybridScanStats stats;
  // Section III: the HMAP.
  stats.map = mapper_.integrate(points_sensor, T_map_sensor);
  // Alg. 4: the ground tree grows around the sensor, over the part of the map this scan reaches.
  const Params& params = mapper_.map().params();
  stats.ground = ground_.update(mapper_.map(), T_map_sensor.translation(), params.map.max_range);
  // eq. (3)-(4): the 2D grid along the rays of this scan's HVoxels.
  stats.occupancy = occupancy_.update(mapper_.last_scan(), ground_.model(), grid_);
  return stats;
}

}  // namespace hmap
