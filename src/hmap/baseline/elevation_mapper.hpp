#pragma once
// Scan integration into the 2.5D elevation map of pipeline [9], fused as ANYbotics
// elevation_mapping does: per scan, each cell's measurement is the highest point of the scan in
// it; it updates the cell's (height, variance) by a 1D Kalman filter, except that a measurement
// far above the estimate replaces it (the map keeps the higher surface). See docs/BASELINE.md.

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "hmap/baseline/elevation_map.hpp"
#include "hmap/maps/scan_hvoxels.hpp"

namespace hmap {

/// The height measurement model and the fusion rule of the elevation map.
struct ElevationParams {
  double sigma_base = 0.02;             ///< σ0 [m]: height noise of a point at zero range
  double sigma_per_metre = 0.002;       ///< k [m/m]: σ(r) = σ0 + k·r, r the point's range [m]
  double mahalanobis_threshold = 2.5;   ///< [-] measurements farther than this many σ of the
                                        ///< innovation are not fused (elevation_mapping's default)
  double multi_height_noise = 9e-7;     ///< [m²] added to a cell's variance when a measurement far
                                        ///< below it is rejected (elevation_mapping's default)
  double max_height_above_sensor = std::numeric_limits<double>::infinity();
                                        ///< [m] points higher above the sensor origin (map z) are
                                        ///< dropped: elevation_mapping's ignore_points_above,
                                        ///< keeps ceilings out of an indoor map
};

/// Throws hmap::Error naming the first field out of its domain.
void validate(const ElevationParams& params);

/// σ(r)² [m²]: the variance of a height measured at range `range` [m].
[[nodiscard]] inline double measurement_variance(double range, const ElevationParams& p) {
  const double sigma = p.sigma_base + p.sigma_per_metre * range;
  return sigma * sigma;
}

/// What one measurement did to a cell.
enum class ElevationFusion : std::uint8_t {
  kInitialized,    ///< the cell was unknown: it takes the measurement and its variance
  kFused,          ///< 1D Kalman update
  kReplaced,       ///< higher than the estimate by more than the threshold: replaces it
  kRejectedLower,  ///< lower than the estimate by more than the threshold: variance inflated only
};

/// Fuses one height measurement `z` [m] of variance `variance` [m²] into (elevation, variance) of
/// `cell`. With d = z − h and s = threshold·sqrt(σ_h² + σ_z²):
///   unknown cell: h = z, σ_h² = σ_z²;   d > s: h = z, σ_h² = σ_z² (the higher surface wins);
///   d < −s: σ_h² += multi_height_noise;  else h = (σ_z² h + σ_h² z) / (σ_h² + σ_z²),
///   σ_h² = σ_h² σ_z² / (σ_h² + σ_z²).
/// Leaves `points` and `lowest` alone.
ElevationFusion fuse_measurement(ElevationCell& cell, double z, double variance, const ElevationParams& params);

/// What one call of ElevationMapper::integrate did.
struct ElevationScanStats {
  std::size_t points_in = 0;
  std::size_t points_kept = 0;
  std::size_t dropped_non_finite = 0;  ///< NaN or infinite coordinates
  std::size_t dropped_range = 0;       ///< closer than min_range or farther than max_range
  std::size_t dropped_height = 0;      ///< higher above the sensor than max_height_above_sensor
  std::size_t cells = 0;               ///< cells measured by the scan
  std::size_t initialized = 0;         ///< of them: observed for the first time
  std::size_t fused = 0;               ///< Kalman updates
  std::size_t replaced = 0;            ///< higher surface took over
  std::size_t rejected_lower = 0;      ///< far lower measurements rejected
};

class ElevationMapper {
 public:
  /// A new, empty map with the cell size and range limits of params.map. Throws hmap::Error for
  /// invalid parameters.
  explicit ElevationMapper(const Params& params, const ElevationParams& elevation = {});
  /// Continues an existing map.
  ElevationMapper(ElevationMap map, const ElevationParams& elevation);

  /// Integrates one scan taken at T_map_sensor: points are dropped and counted as by
  /// hmap::Mapper (non-finite, outside [min_range, max_range] from the sensor), transformed to the
  /// map frame, binned by cell; each cell's highest point is fused by fuse_measurement with the
  /// variance σ(r)² of its range. Nothing is allocated per point once warm.
  ElevationScanStats integrate(std::span<const Point3f> points_sensor, const Pose& T_map_sensor);

  [[nodiscard]] const ElevationMap& map() const { return map_; }
  [[nodiscard]] ElevationMap& map() { return map_; }
  [[nodiscard]] const ElevationParams& elevation_params() const { return elevation_; }

 private:
  // The scan's measurement of one window cell.
  struct Bin {
    float z_max;
    float r2_of_max;  // [m²] squared range of the highest point
    float z_min;
    std::uint32_t points;  // 0: the cell holds no point of this scan
  };

  ElevationMap map_;
  ElevationParams elevation_;
  ScanWindow window_;
  std::vector<Bin> bins_;           // dense over the window
  std::vector<std::uint32_t> used_;  // window cells holding points in this scan
  std::vector<std::uint32_t> point_window_;  // per point: its window cell, or a drop code
  std::vector<float> point_z_;               // per point: map z [m]
  std::vector<float> point_r2_;              // per point: squared range [m²]
};

}  // namespace hmap
