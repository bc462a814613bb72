#pragma once
// Scan-by-scan PVOX map building (the seed's Fig. 2 and 5): predict the pose from the commanded
// motion, measure it by aligning the scan to the map (or take a given measurement), fuse, set the
// voxel edge from the posterior σ, and register the scan into the global map at the posterior mean.

#include <Eigen/Core>
#include <optional>

#include "hmap/core/types.hpp"
#include "hmap/pvox/align.hpp"
#include "hmap/pvox/filter.hpp"
#include "hmap/pvox/voxel_map.hpp"

namespace hmap::pvox {

struct PvoxParams {
  FilterParams filter;
  ProbabilityModel probability;
  InsertParams insert;
  AlignParams align;
  double k_sigma = 6.0;     ///< [-] edge = k · σ of the posterior position (seed: 95.4451 mm² → 58.61 mm)
  double fixed_edge = 0.0;  ///< [m] when positive, the edge is this and does not follow σ
  MemoryBudget budget;      ///< the voxel map refuses to grow beyond it (VoxelMap::set_budget)

  /// Throws hmap::Error for a non-positive k or a negative or non-finite fixed edge.
  void validate() const;
};

/// Where one registration put the scan, and why.
struct RegistrationResult {
  Pose T_map_sensor = Pose::Identity();                    ///< the posterior mean pose used
  Eigen::Vector2d prior_mean = Eigen::Vector2d::Zero();    ///< [m] after the prediction
  Eigen::Vector2d prior_variance = Eigen::Vector2d::Zero();       ///< [m²]
  std::optional<Eigen::Vector2d> measurement;             ///< [m] the position fused, if any
  bool measured_by_alignment = false;
  AlignResult align;                                       ///< when measured by alignment
  Eigen::Vector2d posterior_variance = Eigen::Vector2d::Zero();   ///< [m²]
  double edge = 0.0;                                       ///< [m] voxel edge after this scan
  InsertStats insert;
};

class PvoxMapper {
 public:
  explicit PvoxMapper(const PvoxParams& params);

  /// Registers one scan. `motion` is the commanded move T_previous_current (for the first scan:
  /// the initial pose T_map_sensor, whose x, y seed the filter). `measured_xy` is the measured
  /// position; without it the scan is aligned to the map (the first scan, with an empty map,
  /// is measured at its initial position).
  RegistrationResult add_scan(const PointCloud& points_sensor, const Pose& motion,
                              const std::optional<Eigen::Vector2d>& measured_xy = std::nullopt);

  [[nodiscard]] const VoxelMap& map() const { return map_; }
  [[nodiscard]] const std::optional<PlanarFilter>& filter() const { return filter_; }
  [[nodiscard]] const PvoxParams& params() const { return params_; }
  [[nodiscard]] std::size_t scans() const { return scans_; }
  /// The edge the parameters give for a position σ [m].
  [[nodiscard]] double edge_for(double sigma) const;

 private:
  PvoxParams params_;
  VoxelMap map_;
  std::optional<PlanarFilter> filter_;
  Pose T_map_previous_ = Pose::Identity();
  std::size_t scans_ = 0;
};

}  // namespace hmap::pvox
