#pragma once
// Motion within a sweep (issue 16, as KISS-ICP corrects it): a spinning lidar takes its points
// over the whole sweep while it moves; each point is moved to where the sensor was at the scan's
// reference time, assuming the velocity of the last two poses (or the IMU's rotation rate) held
// during the sweep.

#include <Eigen/Core>
#include <span>

#include "hmap/core/types.hpp"

namespace hmap::slam {

/// A body-frame velocity: the sensor moves by Exp(τ·[ω, v]) in τ seconds, in its own frame.
struct Twist {
  Eigen::Vector3d angular = Eigen::Vector3d::Zero();  ///< [rad/s]
  Eigen::Vector3d linear = Eigen::Vector3d::Zero();   ///< [m/s]
};

/// The SE(3) exponential of a twist times τ [s]: T_ref_τ, the sensor at τ in the frame at 0.
[[nodiscard]] Pose exp_twist(const Twist& xi, double tau);
/// The constant body velocity that moves `T_a` onto `T_b` in `dt` seconds (SE(3) log / dt).
[[nodiscard]] Twist twist_between(const Pose& T_a, const Pose& T_b, double dt);

/// Moves each point taken at time times_s[i] [s] into the sensor frame at `reference_s` (same clock):
/// p_ref = Exp((τ - reference)·ξ)·p_τ. `points_out` is resized to the input (no other allocation).
/// Throws hmap::Error when the two spans differ in size.
void deskew(std::span<const Point3f> points_sensor, std::span<const float> times_s, const Twist& velocity,
            PointCloud& points_out, double reference_s = 0.0);

}  // namespace hmap::slam
