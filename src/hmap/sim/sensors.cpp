#include "hmap/sim/sensors.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include "hmap/core/checked.hpp"
#include "hmap/core/error.hpp"

namespace hmap::sim {
namespace {

void check(bool ok, const std::string& message) {
  if (!ok) throw Error(message);
}

void check_ranges(const char* sensor, double min_range, double max_range, double dropout) {
  check(min_range >= 0.0 && max_range > min_range && std::isfinite(max_range),
        std::string(sensor) + ": need 0 <= min_range < max_range < inf");
  check(dropout >= 0.0 && dropout <= 1.0, std::string(sensor) + ": dropout_probability must be in [0, 1]");
}

/// Casts one ray and, for a return that survives dropout and the range gate, appends the measured
/// point. `direction_sensor` is scaled so that the measured quantity (range or depth) is the
/// distance along it; the noise σ is given for that quantity.
struct RayCaster {
  const Scene& scene;
  const Pose& T_world_sensor;
  double min_range;
  double max_range;
  double dropout_probability;
  std::mt19937_64& rng;
  SimulatedScan& out;
  std::uniform_real_distribution<double> unit{0.0, 1.0};
  std::normal_distribution<double> normal{0.0, 1.0};

  template <typename SigmaOf>
  void cast(const Eigen::Vector3d& direction_sensor, double t_seconds, std::uint16_t channel, SigmaOf&& sigma_of) {
    ++out.rays;
    const double scale = direction_sensor.norm();  // metres of ray per unit of the measured quantity
    const Eigen::Vector3d direction_world = T_world_sensor.linear() * direction_sensor;
    // A return slightly beyond max_range may measure inside it; noise is small against 0.5 m.
    const auto hit = scene.intersect(T_world_sensor.translation(), direction_world, t_seconds,
                                     (max_range + 0.5) * scale);
    if (!hit) {
      ++out.no_return;
      return;
    }
    const double truth = hit->distance / scale;
    const bool dropped = unit(rng) < dropout_probability;
    const double measured = truth + sigma_of(truth) * normal(rng);
    if (dropped) {
      ++out.dropped;
      return;
    }
    if (measured < min_range || measured > max_range) {
      ++out.out_of_range;
      return;
    }
    out.points_sensor.push_back((measured * direction_sensor).cast<float>());
    out.channel.push_back(channel);
    out.primitive.push_back(hit->primitive);
    out.kind.push_back(hit->kind);
  }
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Spinning lidar

SpinningLidarParams SpinningLidarParams::vlp16() {
  SpinningLidarParams p;
  for (int i = 0; i < 16; ++i) p.elevations_deg.push_back(-15.0 + 2.0 * i);
  return p;
}

SpinningLidarParams SpinningLidarParams::os0_64() {
  SpinningLidarParams p;
  for (int i = 0; i < 64; ++i) p.elevations_deg.push_back(-45.0 + 90.0 * i / 63.0);
  p.azimuth_step_deg = 360.0 / 1024.0;
  p.min_range = 0.3;
  p.max_range = 50.0;
  p.range_sigma = 0.015;
  return p;
}

SpinningLidarParams SpinningLidarParams::hdl64e() {
  SpinningLidarParams p;
  for (int i = 0; i < 32; ++i) p.elevations_deg.push_back(2.0 - i / 3.0);     // +2° .. −8.33°
  for (int i = 0; i < 32; ++i) p.elevations_deg.push_back(-8.83 - i * 0.5);  // −8.83° .. −24.33°
  p.azimuth_step_deg = 0.17;
  p.min_range = 0.9;
  p.max_range = 120.0;
  p.range_sigma = 0.02;
  return p;
}

SpinningLidar::SpinningLidar(SpinningLidarParams params) : params_(std::move(params)), rng_(params_.seed) {
  check(!params_.elevations_deg.empty(), "SpinningLidar: needs at least one ring");
  check(params_.azimuth_step_deg > 0.0 && params_.azimuth_step_deg <= 360.0,
        "SpinningLidar: azimuth_step_deg must be in (0, 360]");
  check(params_.range_sigma >= 0.0, "SpinningLidar: range_sigma must not be negative");
  check_ranges("SpinningLidar", params_.min_range, params_.max_range, params_.dropout_probability);
  const int columns = checked_count<int>(std::round(360.0 / params_.azimuth_step_deg), 1 << 22, "SpinningLidar: the columns of a sweep");
  directions_sensor_.reserve(static_cast<std::size_t>(columns) * params_.elevations_deg.size());
  for (int c = 0; c < columns; ++c) {
    const double azimuth = c * params_.azimuth_step_deg * kRadiansPerDegree;
    for (const double elevation_deg : params_.elevations_deg) {
      const double e = elevation_deg * kRadiansPerDegree;
      directions_sensor_.emplace_back(std::cos(e) * std::cos(azimuth), std::cos(e) * std::sin(azimuth), std::sin(e));
    }
  }
}

SimulatedScan SpinningLidar::scan(const Scene& scene, const Pose& T_world_sensor, double t_seconds) {
  SimulatedScan out;
  out.points_sensor.reserve(directions_sensor_.size());
  RayCaster caster{scene, T_world_sensor, params_.min_range, params_.max_range, params_.dropout_probability, rng_, out};
  const double sigma = params_.range_sigma;
  const std::size_t rings = params_.elevations_deg.size();
  for (std::size_t i = 0; i < directions_sensor_.size(); ++i) {
    caster.cast(directions_sensor_[i], t_seconds, static_cast<std::uint16_t>(i % rings), [sigma](double) { return sigma; });
  }
  return out;
}

SimulatedScan SpinningLidar::sweep(const Scene& scene, const std::function<Pose(double)>& T_world_sensor_at,
                                  double t0) {
  check(params_.sweep_period >= 0.0 && std::isfinite(params_.sweep_period),
        "SpinningLidar: sweep_period must be finite and not negative");
  SimulatedScan out;
  out.points_sensor.reserve(directions_sensor_.size());
  const double sigma = params_.range_sigma;
  const std::size_t rings = params_.elevations_deg.size();
  const std::size_t columns = directions_sensor_.size() / rings;
  for (std::size_t c = 0; c < columns; ++c) {
    const double tau = static_cast<double>(c) / static_cast<double>(columns) * params_.sweep_period;
    const Pose T_world_sensor = T_world_sensor_at(t0 + tau);
    RayCaster caster{scene, T_world_sensor, params_.min_range, params_.max_range, params_.dropout_probability, rng_, out};
    for (std::size_t r = 0; r < rings; ++r) {
      caster.cast(directions_sensor_[c * rings + r], t0 + tau, static_cast<std::uint16_t>(r),
                  [sigma](double) { return sigma; });
    }
    out.time.resize(out.points_sensor.size(), static_cast<float>(tau));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Depth camera

DepthCamera::DepthCamera(DepthCameraParams params) : params_(params), rng_(params_.seed) {
  check(params_.width > 0 && params_.height > 0, "DepthCamera: width and height must be positive");
  check(params_.horizontal_fov_deg > 0.0 && params_.horizontal_fov_deg < 180.0 && params_.vertical_fov_deg > 0.0 &&
            params_.vertical_fov_deg < 180.0,
        "DepthCamera: fields of view must be in (0, 180) degrees");
  check(params_.sigma_base >= 0.0 && params_.sigma_quadratic >= 0.0, "DepthCamera: noise terms must not be negative");
  check_ranges("DepthCamera", params_.min_range, params_.max_range, params_.dropout_probability);
  // Pinhole in the optical frame (x right, y down, z forward), turned into x forward, y left, z up.
  const double fx = 0.5 * params_.width / std::tan(0.5 * params_.horizontal_fov_deg * kRadiansPerDegree);
  const double fy = 0.5 * params_.height / std::tan(0.5 * params_.vertical_fov_deg * kRadiansPerDegree);
  const double cx = 0.5 * params_.width;
  const double cy = 0.5 * params_.height;
  rays_sensor_.reserve(static_cast<std::size_t>(params_.width) * static_cast<std::size_t>(params_.height));
  for (int v = 0; v < params_.height; ++v) {
    for (int u = 0; u < params_.width; ++u) {
      const double x_optical = (u + 0.5 - cx) / fx;
      const double y_optical = (v + 0.5 - cy) / fy;
      rays_sensor_.emplace_back(1.0, -x_optical, -y_optical);
    }
  }
}

SimulatedScan DepthCamera::scan(const Scene& scene, const Pose& T_world_sensor, double t_seconds) {
  SimulatedScan out;
  out.points_sensor.reserve(rays_sensor_.size());
  RayCaster caster{scene, T_world_sensor, params_.min_range, params_.max_range, params_.dropout_probability, rng_, out};
  const auto sigma_of = [this](double depth) {
    const double excess = depth - params_.sigma_offset;
    return params_.sigma_base + params_.sigma_quadratic * excess * excess;
  };
  const auto width = static_cast<std::size_t>(params_.width);
  for (std::size_t i = 0; i < rays_sensor_.size(); ++i) {
    caster.cast(rays_sensor_[i], t_seconds, static_cast<std::uint16_t>(i / width), sigma_of);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Line scanner on a sweeping unit

LineScannerParams LineScannerParams::utm30lx_yawing() {
  LineScannerParams p;
  p.sweep = SweepMode::kYaw;
  p.sweep_min_deg = 0.0;
  p.sweep_max_deg = 180.0;
  p.sweep_steps = 181;
  return p;
}

LineScanner::LineScanner(LineScannerParams params) : params_(params), rng_(params_.seed) {
  check(params_.field_of_view_deg > 0.0 && params_.field_of_view_deg <= 360.0,
        "LineScanner: field_of_view_deg must be in (0, 360]");
  check(params_.angular_step_deg > 0.0, "LineScanner: angular_step_deg must be positive");
  check(params_.sweep_steps >= 1, "LineScanner: sweep_steps must be at least 1");
  check(params_.sweep_steps <= 65535, "LineScanner: at most 65535 sweep steps");
  check(params_.line_period >= 0.0 && params_.range_sigma >= 0.0,
        "LineScanner: line_period and range_sigma must not be negative");
  check_ranges("LineScanner", params_.min_range, params_.max_range, params_.dropout_probability);
  const int beams =
      checked_count<int>(std::floor(params_.field_of_view_deg / params_.angular_step_deg + 1e-9), 1 << 22, "LineScanner: the beams of a line") + 1;
  for (int k = 0; k < params_.sweep_steps; ++k) {
    const double w = params_.sweep_steps == 1 ? 0.0 : static_cast<double>(k) / (params_.sweep_steps - 1);
    const double sweep = (params_.sweep_min_deg + w * (params_.sweep_max_deg - params_.sweep_min_deg)) * kRadiansPerDegree;
    const Eigen::Matrix3d R_base_scanner =
        params_.sweep == SweepMode::kTilt ? Eigen::AngleAxisd(sweep, Eigen::Vector3d::UnitY()).toRotationMatrix()
                                          : Eigen::AngleAxisd(sweep, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (int i = 0; i < beams; ++i) {
      const double a = (-0.5 * params_.field_of_view_deg + i * params_.angular_step_deg) * kRadiansPerDegree;
      const Eigen::Vector3d beam = params_.sweep == SweepMode::kTilt ? Eigen::Vector3d(std::cos(a), std::sin(a), 0.0)
                                                                     : Eigen::Vector3d(std::cos(a), 0.0, std::sin(a));
      directions_base_.push_back(R_base_scanner * beam);
    }
  }
}

SimulatedScan LineScanner::scan(const Scene& scene, const Pose& T_world_sensor, double t_seconds) {
  SimulatedScan out;
  out.points_sensor.reserve(directions_base_.size());
  RayCaster caster{scene, T_world_sensor, params_.min_range, params_.max_range, params_.dropout_probability, rng_, out};
  const double sigma = params_.range_sigma;
  const std::size_t beams = directions_base_.size() / static_cast<std::size_t>(params_.sweep_steps);
  for (std::size_t i = 0; i < directions_base_.size(); ++i) {
    const std::size_t step = i / beams;
    caster.cast(directions_base_[i], t_seconds + static_cast<double>(step) * params_.line_period,
                static_cast<std::uint16_t>(step), [sigma](double) { return sigma; });
  }
  return out;
}

}  // namespace hmap::sim
