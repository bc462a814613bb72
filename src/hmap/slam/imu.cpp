#include "hmap/slam/imu.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "hmap/core/error.hpp"

namespace hmap::slam {

namespace {

constexpr double kGravity = 9.80665;  // [m/s²] standard gravity

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

}  // namespace

Eigen::Matrix3d imu_mounting(const SlamParams& p) {
  return (Eigen::AngleAxisd(p.imu_yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(p.imu_pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(p.imu_roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

ImuAttitudeFilter::ImuAttitudeFilter(ImuSamples samples, const Params& params)
    : samples_(std::move(samples)), params_(params.slam), R_sensor_imu_(imu_mounting(params.slam)) {
  validate(params);
  if (samples_.empty()) throw Error("IMU: no samples");
  for (std::size_t k = 0; k < samples_.size(); ++k) {
    const ImuSample& s = samples_[k];
    const bool finite = std::isfinite(s.t) && s.gyro.allFinite() && s.accel.allFinite() &&
                        (!s.orientation || s.orientation->coeffs().allFinite());
    if (!finite) throw Error("IMU sample " + std::to_string(k) + " holds a value that is not finite");
    if (k > 0 && !(s.t > samples_[k - 1].t)) {
      throw Error("IMU sample " + std::to_string(k) + ": stamps must increase");
    }
  }
}

Eigen::Vector3d ImuAttitudeFilter::rate_at(double t) const {
  // The last sample at or before t holds its rate (zero-order hold); before the first, the first.
  const auto it = std::upper_bound(samples_.begin(), samples_.end(), t,
                                   [](double v, const ImuSample& s) { return v < s.t; });
  return it == samples_.begin() ? samples_.front().gyro : std::prev(it)->gyro;
}

void ImuAttitudeFilter::start() {
  if (!started_) {
    // The first sample's gravity (or its own orientation) starts the filter: the first whose
    // |accel| is within the gate of g, so one jolt (or a glitch) at the start cannot set the tilt
    // (a sample at 20 g started a simulated run 87 degrees off); none within it: the first.
    std::size_t first = 0;
    for (std::size_t k = 0; k < samples_.size(); ++k) {
      const ImuSample& s = samples_[k];
      if (s.orientation || std::abs(s.accel.norm() - kGravity) <= params_.imu_accel_gate * kGravity) {
        first = k;
        break;
      }
    }
    const ImuSample& s0 = samples_[first];
    if (s0.orientation) {
      R_world_imu_ = s0.orientation->normalized().toRotationMatrix();
    } else if (s0.accel.norm() > 1e-6) {
      R_world_imu_ = Eigen::Quaterniond::FromTwoVectors(s0.accel.normalized(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    }
    now_ = s0.t;
    next_ = first + 1;
    started_ = true;
  }
}

void ImuAttitudeFilter::advance_to(double t) {
  start();
  const double tau = params_.imu_gravity_time_constant;
  const auto propagate = [&](const Eigen::Vector3d& rate, double dt) {
    const Eigen::Matrix3d dR = exp_so3(rate * dt);
    R_world_imu_ = R_world_imu_ * dR;
    R_gyro_ = R_gyro_ * dR;
  };
  while (next_ < samples_.size() && samples_[next_].t <= t) {
    const ImuSample& s = samples_[next_];
    const double dt = s.t - now_;
    if (dt > 0.0) propagate(samples_[next_ - 1].gyro, dt);
    now_ = s.t;
    if (s.orientation) {
      R_world_imu_ = s.orientation->normalized().toRotationMatrix();
    } else {
      // f = g·up + Rᵀ·a_world, a_world = ω_z·z × V for a velocity V turning with the heading.
      const double wz = (R_world_imu_ * s.gyro).z();
      const Eigen::Vector3d a_world = wz * Eigen::Vector3d::UnitZ().cross(v_world_);
      if (dt > 0.0) v_world_ = Eigen::AngleAxisd(wz * dt, Eigen::Vector3d::UnitZ()) * v_world_;
      const Eigen::Vector3d gravity = s.accel - R_world_imu_.transpose() * a_world;
      const double a = gravity.norm();
      if (dt > 0.0 && std::abs(a - kGravity) <= params_.imu_accel_gate * kGravity && a > 1e-6) {
        // Turn the predicted up (Rᵀ·z, IMU frame) toward the measured one by dt / (τ + dt).
        const Eigen::Vector3d up_pred = R_world_imu_.transpose() * Eigen::Vector3d::UnitZ();
        const Eigen::Vector3d up_meas = gravity / a;
        const Eigen::Vector3d axis = up_pred.cross(up_meas);
        const double angle = std::atan2(axis.norm(), up_pred.dot(up_meas));
        if (axis.norm() > 1e-12) {
          // Until τ's worth of samples is in, a running mean (one sample alone is as noisy as it is).
          ++corrections_;
          const double gain = std::max(dt / (tau + dt), 1.0 / static_cast<double>(corrections_ + 1));
          // R' = R·Exp(φ) has up R'ᵀz = Exp(−φ)·up_pred: φ = −gain·angle·axis turns it toward up_meas.
          R_world_imu_ = R_world_imu_ * exp_so3(-gain * angle * axis.normalized());
        }
      }
    }
    ++applied_since_scan_;
    ++next_;
  }
  if (t > now_) {
    propagate(samples_[next_ - 1].gyro, t - now_);
    now_ = t;
  }
}

void ImuAttitudeFilter::set_body_velocity(const Eigen::Vector3d& v_sensor) {
  start();
  v_world_ = R_world_imu_ * (R_sensor_imu_.transpose() * v_sensor);
}

ImuPrior ImuAttitudeFilter::prior_for_scan(double t, std::span<const float> times_s, const Eigen::Vector3d& v_sensor) {
  set_body_velocity(v_sensor);
  const auto hi = std::max_element(times_s.begin(), times_s.end());
  return prior_at(t, hi == times_s.end() ? 0.0 : static_cast<double>(*hi));
}

ImuPrior ImuAttitudeFilter::prior_at(double t, double sweep) {
  if (scanned_ && t < now_) throw Error("IMU prior asked for a stamp before the previous scan's");
  applied_since_scan_ = 0;
  advance_to(t);
  ImuPrior prior;
  prior.samples = applied_since_scan_;
  prior.up_sensor = (R_sensor_imu_ * R_world_imu_.transpose() * Eigen::Vector3d::UnitZ()).normalized();
  if (scanned_) {
    prior.R_previous_current = R_sensor_imu_ * (R_gyro_at_last_scan_.transpose() * R_gyro_) * R_sensor_imu_.transpose();
    prior.has_rotation = true;
  }
  // The mean rate over the sweep: the samples inside it, or the rate held at t.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  if (sweep > 0.0) {
    auto it = std::lower_bound(samples_.begin(), samples_.end(), t,
                               [](const ImuSample& s, double v) { return s.t < v; });
    for (; it != samples_.end() && it->t <= t + sweep; ++it) {
      sum += it->gyro;
      ++n;
    }
  }
  prior.angular_velocity_sensor = R_sensor_imu_ * (n > 0 ? Eigen::Vector3d(sum / static_cast<double>(n)) : rate_at(t));
  R_gyro_at_last_scan_ = R_gyro_;
  scanned_ = true;
  return prior;
}

}  // namespace hmap::slam
