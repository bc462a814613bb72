#pragma once
// The hybrid HMAP of section IV: the height-voxel map, the ground patches under it and the 2D
// occupancy grid, all updated scan after scan.

#include <span>
#include <vector>

#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/mapper.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"
#include "hmap/occupancy/occupancy_update.hpp"

namespace hmap {

/// What one call of HybridMapper::integrate did.
struct HybridScanStats {
  ScanStats map;                   ///< section III on the HMAP
  GroundResult ground;             ///< Alg. 4 iterations of this scan (patches left empty)
  OccupancyUpdateStats occupancy;  ///< eq. (3)-(4) on the 2D grid
};

class HybridMapper {
 public:
  /// A new, empty map. Throws hmap::Error for invalid parameters.
  explicit HybridMapper(const Params& params);
  /// Continues a map saved earlier with its grid and ground patches (parameters from the map).
  HybridMapper(HMap map, OccupancyGrid grid, std::vector<GroundPatch> patches);

  /// Integrates one scan taken at T_map_sensor: the HMAP update (section III), K more
  /// iterations of the ground tree around the sensor (Alg. 4), then the 2D grid along the rays
  /// of the scan's HVoxels judged against that ground (eq. 3-4).
  HybridScanStats integrate(std::span<const Point3f> points_sensor, const Pose& T_map_sensor);

  [[nodiscard]] const HMap& map() const { return mapper_.map(); }
  [[nodiscard]] const Mapper& mapper() const { return mapper_; }
  [[nodiscard]] const OccupancyGrid& grid() const { return grid_; }
  [[nodiscard]] const GroundModel& ground() const { return ground_.model(); }
  [[nodiscard]] const std::vector<GroundPatch>& ground_patches() const { return ground_.patches(); }

 private:
  Mapper mapper_;
  GroundTracker ground_;
  OccupancyGrid grid_;
  OccupancyUpdater occupancy_;
};

}  // namespace hmap
