#include "hmap/sim/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <variant>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/sim/city.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/imu_sim.hpp"
#include "hmap/sim/sensors.hpp"
#include "hmap/sim/trajectory.hpp"

namespace hmap::sim {

std::vector<std::string> sensor_names() { return {"vlp16", "hdl64", "os0-64", "kinect", "utm30lx-tilt", "utm30lx-yaw"}; }

bool is_spinning_lidar(const std::string& name) { return name == "vlp16" || name == "hdl64" || name == "os0-64"; }

std::string sensor_names_text() {
  std::string text;
  for (const std::string& n : sensor_names()) text += (text.empty() ? "" : ", ") + n;
  return text;
}

AnySensor make_sensor(const std::string& name, std::uint64_t seed, SensorNoise noise) {
  const bool noise_free = noise == SensorNoise::kNone;
  if (is_spinning_lidar(name)) {
    auto p = name == "vlp16" ? SpinningLidarParams::vlp16()
             : name == "hdl64" ? SpinningLidarParams::hdl64e()
                               : SpinningLidarParams::os0_64();
    p.seed = seed;
    if (noise_free) p.range_sigma = 0.0, p.dropout_probability = 0.0;
    return SpinningLidar(p);
  }
  if (name == "kinect") {
    auto p = DepthCameraParams::kinect_one();
    p.seed = seed;
    if (noise_free) p.sigma_base = 0.0, p.sigma_quadratic = 0.0, p.dropout_probability = 0.0;
    return DepthCamera(p);
  }
  if (name == "utm30lx-tilt" || name == "utm30lx-yaw") {
    auto p = name == "utm30lx-tilt" ? LineScannerParams::utm30lx_tilting() : LineScannerParams::utm30lx_yawing();
    p.seed = seed;
    if (noise_free) p.range_sigma = 0.0, p.dropout_probability = 0.0;
    return LineScanner(p);
  }
  throw Error("unknown sensor '" + name + "' (known: " + sensor_names_text() + ")");
}

namespace {

double sensor_reach(const AnySensor& s) {
  return std::visit([](const auto& x) { return x.params().max_range; }, s);
}

SimulatedScan scan_with(AnySensor& s, const Scene& scene, const Pose& T, double t) {
  return std::visit([&](auto& x) { return x.scan(scene, T, t); }, s);
}

/// The scripted path of a scene, for a sensor mounted at `height` above the floor.
Trajectory path_for(const SimulationSpec& spec, double height) {
  if (spec.scene == "city") {
    CarPathParams p;
    p.sensor_height = height;
    if (spec.city_route == SimulationSpec::CityRoute::kLoop) return car_path(city_loop_route(CityParams{}, 1000.0 * spec.route_km), p);
    return car_path(city_car_route(CityParams{}, 1000.0 * spec.route_km, p.turn_radius), p);
  }
  if (spec.scene == "parking") {
    CarPathParams p;
    p.sensor_height = height;
    const auto route = spec.long_route ? parking_long_car_route() : parking_car_route();
    return car_path(route, p);
  }
  if (spec.scene == "boxes") {
    // Along the enclosure's axis, as the seed's scanner on its stand.
    DiffDriveParams p;
    p.speed = 0.2;
    p.sensor_height = height;
    p.floor_z = -1.0;
    const std::vector<Eigen::Vector2d> route = {{0.0, 0.35}, {0.0, 1.6}};
    return diff_drive_path(route, p);
  }
  DiffDriveParams p;
  p.sensor_height = height;
  const auto route = office_robot_route();
  return diff_drive_path(route, p);
}

}  // namespace

void check_city(const SimulationSpec& spec) {
  if (spec.scene != "city") return;
  check_route_km(spec.route_km);
  // The dense sample of a whole town is tens of millions of points, most far from any route.
  if (spec.truth) throw Error("the city's drive has no truth (truth.ply, truth_seen.ply): set truth = false");
}

void check_route_km(double route_km) {
  if (!(route_km >= 0.1 && route_km <= 20.0)) throw Error("--route-km must be in [0.1, 20] km (got " + format("%g", route_km) + ")");
}

double path_length(const PoseList& poses) {
  double length = 0.0;
  for (std::size_t k = 1; k < poses.size(); ++k) length += (poses[k].translation() - poses[k - 1].translation()).norm();
  return length;
}

double recording_bytes(std::size_t points_done, std::size_t done, std::size_t frames) {
  if (done == 0) return 0.0;
  return static_cast<double>(points_done) / static_cast<double>(done) * static_cast<double>(frames) * (16.0 + 12.0);
}

SimulatedRecording simulate(const SimulationSpec& spec, const SimulationProgress& progress, const FrameSink& sink) {
  check_city(spec);  // before the town is built
  return simulate(spec, make_scene(spec.scene), progress, sink);
}

SimulatedRecording simulate(const SimulationSpec& spec, const Scene& scene, const SimulationProgress& progress,
                            const FrameSink& sink) {
  if (spec.stride == 0) throw Error("--stride must be at least 1");
  check_city(spec);
  if (!(spec.truth_spacing >= 0.005)) throw Error("--truth-spacing must be at least 0.005 m");
  if (spec.sweep && !is_spinning_lidar(spec.sensor)) {
    throw Error("--sweep needs a spinning lidar (--sensor vlp16, hdl64 or os0-64), not '" + spec.sensor + "'");
  }
  AnySensor sensor = make_sensor(spec.sensor, spec.seed, SensorNoise::kModelled);
  AnySensor exact = make_sensor(spec.sensor, spec.seed, SensorNoise::kNone);
  // Spinning lidars on a car roof, the others on a robot at about 0.5 m (the Kinect at 0.8 m).
  const bool outdoor = is_spinning_lidar(spec.sensor);
  const double height = outdoor ? 1.73 : spec.sensor == "kinect" ? 0.8 : 0.5;
  Trajectory path = path_for(spec, height);
  if (spec.mount_yaw != 0.0) {
    if (!(std::abs(spec.mount_yaw) <= std::numbers::pi)) {
      throw Error(format("--mount-yaw must be within [-180, 180] deg (got %g deg)", spec.mount_yaw * 180.0 / std::numbers::pi));
    }
    // Turned about its axis, a spinning lidar sees the same scene; a camera or a line scanner
    // would look somewhere else.
    if (!outdoor) throw Error("--mount-yaw turns a spinning lidar (vlp16, hdl64, os0-64), not '" + spec.sensor + "'");
    const Eigen::AngleAxisd turn(spec.mount_yaw, Eigen::Vector3d::UnitZ());
    for (Pose& T : path.T_world_sensor) T = T * turn;
  }

  SimulatedRecording rec;
  for (std::size_t k = 0; k < path.T_world_sensor.size(); k += spec.stride) {
    if (spec.frames > 0 && rec.T_world_sensor.size() == spec.frames) break;
    rec.T_world_sensor.push_back(path.T_world_sensor[k]);
    rec.times.push_back(path.times[k]);
  }
  if (rec.T_world_sensor.empty()) throw Error("the path of scene '" + spec.scene + "' has no frame");
  const std::size_t n = rec.T_world_sensor.size();
  const double t_end = rec.times.back();
  const auto T_world_sensor_at = [&path](double t) { return pose_at(path, t); };
  for (std::size_t k = 0; k < n; ++k) {
    // A sweep starts at the frame's time, so the frame's true pose is the one its times count from.
    SimulatedScan s = spec.sweep ? std::get<SpinningLidar>(sensor).sweep(scene, T_world_sensor_at, rec.times[k])
                                      : scan_with(sensor, scene, rec.T_world_sensor[k], rec.times[k]);
    rec.points += s.points_sensor.size();
    if (sink) {
      sink(k, s.points_sensor, spec.sweep ? s.time : std::vector<float>{});
    } else {
      rec.scans.push_back(std::move(s.points_sensor));
      if (spec.sweep) rec.point_times.push_back(std::move(s.time));
    }
    if (spec.truth) {
      // What the sensor could see of the scene as it stands at the end (moving objects gone).
      const SimulatedScan e = scan_with(exact, scene, rec.T_world_sensor[k], t_end);
      for (const Point3f& p : e.points_sensor) rec.truth_seen.push_back((rec.T_world_sensor[k] * p.cast<double>()).cast<float>());
    }
    if (progress) progress(k + 1, n, rec.points);
  }
  if (spec.imu_rate > 0.0) {
    // An IMU on the sensor over the whole path, on a smooth interpolation of its frames.
    if (!(spec.imu_rate >= 10.0 && spec.imu_rate <= 2000.0)) throw Error("--imu-rate must be in [10, 2000] Hz");
    ImuSimParams imu;
    imu.rate = spec.imu_rate;
    imu.seed = spec.seed;
    // 2 ms inside the path's ends: the derivatives there would see the clamped pose outside it.
    const double t0 = path.times.front() + 0.002;
    const double t1 = std::min(rec.times.back(), path.times.back() - 0.002);
    if (t1 > t0) rec.imu = simulate_imu([&](double t) { return pose_at(path, t); }, t0, t1, imu);
  }
  OdometryNoiseParams noise;
  noise.seed = spec.seed;
  rec.odometry = noisy_odometry(rec.T_world_sensor, noise);
  if (!spec.truth) return rec;
  // The dense sample, kept within reach of the path: anchors every 2 m along it, and the reach
  // widened by that spacing so no point near the path is lost between anchors.
  std::vector<Eigen::Vector3d> anchors;
  for (const Pose& T : rec.T_world_sensor) {
    if (anchors.empty() || (T.translation() - anchors.back()).norm() >= 2.0) anchors.push_back(T.translation());
  }
  const double reach = std::min(sensor_reach(sensor), spec.truth_reach) + 2.0;
  std::mt19937_64 rng(spec.seed);
  const Scene::KindedSample truth = scene.sample_surface_kinds(spec.truth_spacing, rng, t_end);
  for (std::size_t q = 0; q < truth.points.size(); ++q) {
    const Point3f& p = truth.points[q];
    for (const Eigen::Vector3d& a : anchors) {
      if ((p.cast<double>() - a).squaredNorm() <= reach * reach) {
        rec.truth_surface.push_back(p);
        if (truth.kinds[q] == SurfaceKind::kGround) rec.truth_ground.push_back(p);
        break;
      }
    }
  }
  return rec;
}

}  // namespace hmap::sim
