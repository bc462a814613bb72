#include "hmap/sim/imu_sim.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"

namespace hmap::sim {

ImuSamples simulate_imu(const std::function<Pose(double)>& T_world_sensor_at, double t0, double t1,
                        const ImuSimParams& params) {
  if (!(params.rate > 0.0) || !(t1 >= t0)) throw Error("simulate_imu: need rate > 0 and t1 >= t0");
  constexpr double kGravity = 9.80665;
  constexpr double h = 1e-3;  // [s] central-difference step
  std::mt19937_64 rng(params.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto noise = [&](double sigma) {
    Eigen::Vector3d v;  // drawn x, y, z in this order (a constructor's argument order is unspecified)
    for (int i = 0; i < 3; ++i) v(i) = sigma * normal(rng);
    return v;
  };
  ImuSamples out;
  const auto n = static_cast<std::size_t>(
                     checked_count<std::int64_t>(std::floor((t1 - t0) * params.rate + 1e-9), std::int64_t{1} << 27, "the IMU samples")) +
                 1;
  out.reserve(n);
  const Eigen::Matrix3d& R_si = params.R_sensor_imu;
  for (std::size_t k = 0; k < n; ++k) {
    const double t = t0 + static_cast<double>(k) / params.rate;
    const Pose Tm = T_world_sensor_at(t - h);
    const Pose T = T_world_sensor_at(t);
    const Pose Tp = T_world_sensor_at(t + h);
    // Body rate: log(R(t−h)ᵀ·R(t+h)) / 2h, in the sensor frame, then the IMU's.
    const Eigen::AngleAxisd aa(Tm.linear().transpose() * Tp.linear());
    const Eigen::Vector3d w_sensor = aa.angle() * aa.axis() / (2.0 * h);
    const Eigen::Vector3d a_world = (Tp.translation() - 2.0 * T.translation() + Tm.translation()) / (h * h);
    const Eigen::Vector3d f_sensor = T.linear().transpose() * (a_world + Eigen::Vector3d(0.0, 0.0, kGravity));
    ImuSample s;
    s.t = t;
    s.gyro = R_si.transpose() * w_sensor + params.gyro_bias + noise(params.gyro_sigma);
    s.accel = R_si.transpose() * f_sensor + noise(params.accel_sigma);
    out.push_back(s);
  }
  return out;
}

}  // namespace hmap::sim
