#pragma once
// The recursive Bayesian filter of the PVOX seed: one 1D Kalman filter per planar axis, fusing the
// commanded motion (prediction) with a measured position (update), eq. (8)–(9).

#include <Eigen/Core>
#include <cstdint>

namespace hmap::pvox {

/// RBF or the seed's naive BRF.
enum class FilterKind : std::uint8_t {
  kRecursive,  ///< RBF: every posterior is the next prior (a Kalman filter)
  kNaive,      ///< BRF: updated at the first position only; later means follow the commands and the
               ///< first posterior variance is kept throughout (the seed's comparison filter)
};

struct FilterParams {
  double motion_variance = 2000e-6;       ///< [m²] of each commanded move, per axis (seed: 2000 mm²)
  double measurement_variance = 100e-6;   ///< [m²] of a measured position, per axis (seed: 100 mm²)
  double initial_variance = 2000e-6;      ///< [m²] of the first position before its measurement
  FilterKind kind = FilterKind::kRecursive;
};

/// A Gaussian belief over one coordinate.
struct AxisBelief {
  double mean = 0.0;      ///< [m]
  double variance = 0.0;  ///< [m²]
};

/// Prediction by a commanded move `u` [m] of variance `variance_u` [m²]: means add, variances add.
[[nodiscard]] AxisBelief predict(const AxisBelief& prior, double u, double variance_u);

/// Measurement update, the product of two Gaussians (the seed's eq. (8)–(9)):
///   μ' = (σ_z² μ + σ² z) / (σ² + σ_z²),   σ'² = σ² σ_z² / (σ² + σ_z²).
[[nodiscard]] AxisBelief fuse(const AxisBelief& prior, double z, double variance_z);

/// Two independent axis filters (x, y of the map frame).
class PlanarFilter {
 public:
  /// Throws hmap::Error for a non-positive or non-finite variance.
  PlanarFilter(const FilterParams& params, const Eigen::Vector2d& initial_xy);

  /// Moves the belief by the commanded displacement `u_xy` [m].
  void predict(const Eigen::Vector2d& u_xy);
  /// Fuses a measured position `z_xy` [m]. The naive filter ignores every measurement but the first.
  void update(const Eigen::Vector2d& z_xy);
  /// Whether update() would change the belief now (false for BRF after its first update).
  [[nodiscard]] bool wants_measurement() const;

  [[nodiscard]] Eigen::Vector2d mean() const { return {x_.mean, y_.mean}; }
  [[nodiscard]] Eigen::Vector2d variance() const { return {x_.variance, y_.variance}; }
  /// The larger of the two axis standard deviations [m]: what the voxel edge follows.
  [[nodiscard]] double sigma() const;
  [[nodiscard]] int updates() const { return updates_; }
  [[nodiscard]] const FilterParams& params() const { return params_; }

 private:
  FilterParams params_;
  AxisBelief x_;
  AxisBelief y_;
  int updates_ = 0;
};

}  // namespace hmap::pvox
