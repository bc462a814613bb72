#include "hmap/core/params.hpp"

#include <charconv>
#include <cmath>
#include <limits>
#include <sstream>
#include <type_traits>

#include "hmap/core/error.hpp"

namespace hmap {

Params outdoor_preset() { return Params{}; }

Params indoor_preset() {
  Params p;
  p.map.cell_size = 0.05;
  p.map.point_distance_threshold = 0.15;
  p.map.min_range = 0.8;
  p.map.max_range = 5.0;
  p.map.min_hvoxel_height = 0.05;
  p.ground.elevation_threshold = 0.05;
  p.ground.expansion_distance = 0.4;
  p.occupancy.ground_distance = 0.03;
  p.occupancy.free_ray_height = 0.06;
  return p;
}

Params preset(std::string_view name) {
  if (name == "indoor") return indoor_preset();
  if (name == "outdoor") return outdoor_preset();
  throw Error("unknown preset '" + std::string(name) + "' (expected indoor or outdoor)");
}

namespace {

ParamRef ref(std::string name, std::string unit, std::string description, double& field) {
  return {std::move(name), std::move(unit), std::move(description), [&field] { return field; },
          [&field](double v) { field = v; }};
}

/// `v` rounded to an integer of type Int; hmap::Error naming the parameter when it is not finite
/// or out of Int's range (a cast would wrap: 4294967696 would silently become 400).
template <typename Int>
Int checked_integer(const std::string& name, double v) {
  const double r = std::round(v);
  // [lowest, 2^digits): both bounds exact in a double, so the cast below is defined.
  if (!(r >= static_cast<double>(std::numeric_limits<Int>::lowest()) &&
        r < std::ldexp(1.0, std::numeric_limits<Int>::digits))) {
    char number[32];
    const auto end = std::to_chars(number, number + sizeof number, v).ptr;  // shortest exact
    std::ostringstream message;
    message << "parameter " << name << " = " << std::string_view(number, static_cast<std::size_t>(end - number))
            << " must be an integer in [" << +std::numeric_limits<Int>::lowest() << ", "
            << +std::numeric_limits<Int>::max() << "]";
    throw Error(message.str());
  }
  return static_cast<Int>(r);
}

template <typename Int>
ParamRef ref_int(std::string name, std::string unit, std::string description, Int& field) {
  return {name, std::move(unit), std::move(description), [&field] { return static_cast<double>(field); },
          [&field, name](double v) { field = checked_integer<Int>(name, v); }};
}

}  // namespace

std::vector<ParamRef> param_refs(Params& p) {
  std::vector<ParamRef> r;
  auto& m = p.map;
  r.push_back(ref("map.cell_size", "m", "edge of a square grid cell", m.cell_size));
  r.push_back(ref("map.point_distance_threshold", "m", "z gap that splits a height cluster (Alg. 2)",
                  m.point_distance_threshold));
  r.push_back(ref("map.min_range", "m", "points closer to the sensor are dropped", m.min_range));
  r.push_back(ref("map.max_range", "m", "points farther from the sensor are dropped", m.max_range));
  r.push_back(ref("map.density_gain", "-", "K_m of eq. (1)", m.density_gain));
  r.push_back(ref("map.density_normalization", "m^3", "K_n of eq. (1)", m.density_normalization));
  r.push_back(ref("map.density_min_points", "-", "d_min of eq. (1)", m.density_min_points));
  r.push_back(ref("map.min_hvoxel_height", "m", "floor of the height h in eq. (1)",
                  m.min_hvoxel_height));
  r.push_back(ref("map.density_threshold", "-", "n_th: HVoxels below it cast no ray and are removed",
                  m.density_threshold));
  r.push_back({"map.free_space", "enum", "0 = ray tracing and extrusion, 1 = none",
               [&m] { return static_cast<double>(m.free_space); },
               [&m](double v) {
                 m.free_space = static_cast<FreeSpaceMode>(
                     checked_integer<std::underlying_type_t<FreeSpaceMode>>("map.free_space", v));
               }});
  r.push_back(ref("map.free_unite_gap", "m", "free bands of one cell closer than this unite",
                  m.free_unite_gap));
  auto& g = p.ground;
  r.push_back(ref_int("ground.iterations", "-", "K, RRT iterations of Alg. 4", g.iterations));
  r.push_back(ref("ground.normal_threshold", "-", "N_th: 1 - |n1.n2| allowed between patches",
                  g.normal_threshold));
  r.push_back(ref("ground.elevation_threshold", "m", "E_th: height step allowed between patches",
                  g.elevation_threshold));
  r.push_back(ref("ground.expansion_distance", "m", "d_n, node expansion distance of eq. (2)",
                  g.expansion_distance));
  r.push_back(ref("ground.top_noise", "m", "sigma of the HVoxel tops on a flat floor, allowed in a patch's RMS",
                  g.top_noise));
  r.push_back(ref_int("ground.seed", "-", "random seed of the patch exploration", g.seed));
  auto& o = p.occupancy;
  r.push_back(ref("occupancy.sigma", "m", "sigma of the obstacle term of eq. (4)", o.sigma));
  r.push_back(ref("occupancy.ground_gain", "-", "K_g of eq. (4)", o.ground_gain));
  r.push_back(ref("occupancy.ground_distance", "m", "d_pth of eq. (4)", o.ground_distance));
  r.push_back(ref("occupancy.z_plus", "m", "z+, upper detection limit above the ground", o.z_plus));
  r.push_back(ref("occupancy.z_minus", "m", "z-, lower detection limit below the ground", o.z_minus));
  r.push_back(ref("occupancy.clamp_min", "-", "lowest occupancy probability kept", o.clamp_min));
  r.push_back(ref("occupancy.clamp_max", "-", "highest occupancy probability kept", o.clamp_max));
  r.push_back(ref("occupancy.ground_reach", "m", "farthest an HVoxel may be from a ground patch to be judged",
                  o.ground_reach));
  r.push_back(ref("occupancy.free_ray_height", "m", "a ray frees the cells it crosses at most this high above the ground",
                  o.free_ray_height));
  auto& s = p.slam;
  r.push_back(ref_int("slam.interpolation_window", "cells", "IDW window of eq. (12)",
                      s.interpolation_window));
  r.push_back(ref("slam.idw_power", "-", "p of eq. (12)", s.idw_power));
  r.push_back(ref_int("slam.max_iterations", "-", "Gauss-Newton iterations per scan",
                      s.max_iterations));
  r.push_back(ref("slam.idw_weight", "-", "weight of an IDW-interpolated neighbour (eq. 12)",
                  s.idw_weight));
  r.push_back(ref("slam.min_match_height", "m", "thinner scan HVoxels do not take part in matching",
                  s.min_match_height));
  r.push_back(ref("slam.min_layer_height", "m", "intervals are widened to this for the IoU (eq. 9)",
                  s.min_layer_height));
  r.push_back(ref("slam.robust_scale", "-", "Cauchy scale on the residual 1 - M_H; 0 = off",
                  s.robust_scale));
  r.push_back(ref("slam.convergence_translation", "m", "a smaller Gauss-Newton step ends the match",
                  s.convergence_translation));
  r.push_back(ref("slam.convergence_rotation", "rad", "a smaller Gauss-Newton step ends the match",
                  s.convergence_rotation));
  r.push_back(ref("slam.degeneracy_ratio", "-", "curvature ratio of eq. (5) under which a match is degenerate",
                  s.degeneracy_ratio));
  r.push_back(ref_int("slam.max_hvoxels", "-", "HVoxels matched per scan at most; 0 = all",
                      s.max_hvoxels));
  r.push_back(ref("slam.coarse_trigger_ratio", "-",
                  "a match scoring under this times the running mean is retried by a coarse search; 0 = never",
                  s.coarse_trigger_ratio));
  r.push_back(ref("slam.coarse_translation", "m", "half-width of the coarse search in x and y",
                  s.coarse_translation));
  r.push_back(ref("slam.coarse_rotation", "rad", "half-width of the coarse search in yaw",
                  s.coarse_rotation));
  r.push_back(ref("slam.surface_max_height", "m", "HVoxels at most this tall count as horizontal surfaces (attitude fit)",
                  s.surface_max_height));
  r.push_back(ref("slam.attitude_gate", "m", "farthest a scan surface is paired with the map's (attitude fit)",
                  s.attitude_gate));
  r.push_back(ref_int("slam.attitude_iterations", "-", "Gauss-Newton iterations of the attitude fit; 0 = off",
                      s.attitude_iterations));
  r.push_back(ref("slam.attitude_min_surfaces", "-", "fewer surface pairs: the attitude keeps its guess",
                  s.attitude_min_surfaces));
  r.push_back(ref("slam.attitude_min_lever", "m", "RMS lever arm under which roll or pitch is not observable",
                  s.attitude_min_lever));
  r.push_back(ref("slam.level_prior", "-", "pull of the attitude fit toward a level floor (fraction of the map's)",
                  s.level_prior));
  r.push_back(ref("slam.max_floor_tilt", "rad", "steepest plane taken for a scan's floor",
                  s.max_floor_tilt));
  r.push_back(ref("slam.imu_gravity_time_constant", "s",
                  "time constant of the IMU's complementary filter (accelerometer gravity vs gyro)",
                  s.imu_gravity_time_constant));
  r.push_back(ref("slam.imu_accel_gate", "-",
                  "|accel| farther than this fraction of g from g: the sample does not correct the tilt",
                  s.imu_accel_gate));
  r.push_back(ref("slam.imu_tilt_weight", "-",
                  "pull of the attitude fit toward the IMU's gravity (fraction of the map pairs' tilt information)",
                  s.imu_tilt_weight));
  r.push_back(ref("slam.imu_roll", "rad", "IMU mounting in the sensor frame, roll of R_sensor_imu", s.imu_roll));
  r.push_back(ref("slam.imu_pitch", "rad", "IMU mounting in the sensor frame, pitch of R_sensor_imu", s.imu_pitch));
  r.push_back(ref("slam.imu_yaw", "rad", "IMU mounting in the sensor frame, yaw of R_sensor_imu", s.imu_yaw));
  r.push_back(ref_int("slam.deskew", "-", "1: points with a time are moved to the scan's reference time; 0: off",
                      s.deskew));
  return r;
}

namespace {

void require(bool ok, const char* name, double value, const char* domain) {
  if (ok) return;
  std::ostringstream msg;
  msg << "parameter " << name << " = " << value << " is invalid: must be " << domain;
  throw Error(msg.str());
}

}  // namespace

void validate(const Params& p) {
  // Every scalar must be a finite number first.
  Params copy = p;
  for (const auto& r : param_refs(copy)) {
    require(std::isfinite(r.get()), r.name.c_str(), r.get(), "a finite number");
  }
  const auto& m = p.map;
  require(m.cell_size >= 1e-3 && m.cell_size <= 100.0, "map.cell_size", m.cell_size,
          "between 0.001 and 100 m");
  require(m.point_distance_threshold >= 0.0, "map.point_distance_threshold",
          m.point_distance_threshold, ">= 0");
  require(m.min_range >= 0.0, "map.min_range", m.min_range, ">= 0");
  require(m.max_range > m.min_range, "map.max_range", m.max_range, "> map.min_range");
  // The scan is binned into a dense window of (2·max_range/cell)^2 cells: keep it in memory.
  const double half_cells = std::ceil(m.max_range / m.cell_size);
  require(half_cells <= 2048.0, "map.max_range", m.max_range,
          "at most 2048 cells from the sensor (max_range / cell_size <= 2048)");
  require(m.density_gain > 0.0, "map.density_gain", m.density_gain, "> 0");
  require(m.density_normalization > 0.0, "map.density_normalization", m.density_normalization,
          "> 0");
  require(m.density_min_points >= 0.0, "map.density_min_points", m.density_min_points, ">= 0");
  require(m.min_hvoxel_height > 0.0, "map.min_hvoxel_height", m.min_hvoxel_height, "> 0");
  require(m.density_threshold >= 0.0 && m.density_threshold <= m.density_gain,
          "map.density_threshold", m.density_threshold, "in [0, K_m]");
  require(m.free_space == FreeSpaceMode::kRayTracing || m.free_space == FreeSpaceMode::kNone,
          "map.free_space", static_cast<double>(m.free_space), "0 or 1");
  require(m.free_unite_gap >= 0.0, "map.free_unite_gap", m.free_unite_gap, ">= 0");
  const auto& g = p.ground;
  require(g.iterations >= 0, "ground.iterations", g.iterations, ">= 0");
  require(g.normal_threshold >= 0.0 && g.normal_threshold <= 1.0, "ground.normal_threshold",
          g.normal_threshold, "in [0, 1]");
  require(g.elevation_threshold >= 0.0, "ground.elevation_threshold", g.elevation_threshold, ">= 0");
  require(g.top_noise >= 0.0, "ground.top_noise", g.top_noise, ">= 0");
  require(g.expansion_distance > 0.0, "ground.expansion_distance", g.expansion_distance, "> 0");
  const auto& o = p.occupancy;
  require(o.sigma > 0.0, "occupancy.sigma", o.sigma, "> 0");
  require(o.ground_gain >= 0.0 && o.ground_gain <= 0.5, "occupancy.ground_gain", o.ground_gain,
          "in [0, 0.5]");
  require(o.ground_distance > 0.0, "occupancy.ground_distance", o.ground_distance, "> 0");
  require(o.z_plus > o.z_minus, "occupancy.z_plus", o.z_plus, "> occupancy.z_minus");
  require(o.clamp_min > 0.0 && o.clamp_min < 0.5, "occupancy.clamp_min", o.clamp_min,
          "in (0, 0.5)");
  require(o.clamp_max > 0.5 && o.clamp_max < 1.0, "occupancy.clamp_max", o.clamp_max,
          "in (0.5, 1)");
  require(o.ground_reach > 0.0, "occupancy.ground_reach", o.ground_reach, "> 0");
  require(o.free_ray_height >= 0.0 && o.free_ray_height <= 1000.0, "occupancy.free_ray_height", o.free_ray_height,
          "in [0, 1000]");
  const auto& s = p.slam;
  require(s.interpolation_window >= 1 && s.interpolation_window <= 9 && s.interpolation_window % 2 == 1,
          "slam.interpolation_window", s.interpolation_window, "an odd number in [1, 9]");
  require(s.idw_power > 0.0, "slam.idw_power", s.idw_power, "> 0");
  require(s.max_iterations >= 1, "slam.max_iterations", s.max_iterations, ">= 1");
  require(s.idw_weight >= 0.0 && s.idw_weight <= 1.0, "slam.idw_weight", s.idw_weight, "in [0, 1]");
  require(s.min_match_height >= 0.0, "slam.min_match_height", s.min_match_height, ">= 0");
  require(s.min_layer_height > 0.0, "slam.min_layer_height", s.min_layer_height, "> 0");
  require(s.robust_scale >= 0.0, "slam.robust_scale", s.robust_scale, ">= 0");
  require(s.convergence_translation > 0.0, "slam.convergence_translation", s.convergence_translation, "> 0");
  require(s.convergence_rotation > 0.0, "slam.convergence_rotation", s.convergence_rotation, "> 0");
  require(s.degeneracy_ratio >= 0.0 && s.degeneracy_ratio < 1.0, "slam.degeneracy_ratio", s.degeneracy_ratio,
          "in [0, 1)");
  require(s.max_hvoxels >= 0, "slam.max_hvoxels", s.max_hvoxels, ">= 0");
  require(s.coarse_trigger_ratio >= 0.0 && s.coarse_trigger_ratio <= 1.0, "slam.coarse_trigger_ratio",
          s.coarse_trigger_ratio, "in [0, 1]");
  require(s.coarse_translation >= 0.0, "slam.coarse_translation", s.coarse_translation, ">= 0");
  require(s.coarse_rotation >= 0.0, "slam.coarse_rotation", s.coarse_rotation, ">= 0");
  require(s.surface_max_height > 0.0 && s.surface_max_height <= 5.0, "slam.surface_max_height", s.surface_max_height,
          "in (0, 5]");
  require(s.attitude_gate > 0.0 && s.attitude_gate <= 10.0, "slam.attitude_gate", s.attitude_gate, "in (0, 10]");
  require(s.attitude_iterations >= 0 && s.attitude_iterations <= 100, "slam.attitude_iterations",
          s.attitude_iterations, "in [0, 100]");
  require(s.attitude_min_surfaces >= 3.0 && s.attitude_min_surfaces <= 1e6, "slam.attitude_min_surfaces",
          s.attitude_min_surfaces, "in [3, 1e6]");
  require(s.attitude_min_lever > 0.0 && s.attitude_min_lever <= 100.0, "slam.attitude_min_lever",
          s.attitude_min_lever, "in (0, 100]");
  require(s.level_prior >= 0.0 && s.level_prior <= 100.0, "slam.level_prior", s.level_prior, "in [0, 100]");
  require(s.max_floor_tilt >= 0.0 && s.max_floor_tilt <= 1.2, "slam.max_floor_tilt", s.max_floor_tilt,
          "in [0, 1.2]");
  require(s.imu_gravity_time_constant > 0.0 && s.imu_gravity_time_constant <= 1000.0,
          "slam.imu_gravity_time_constant", s.imu_gravity_time_constant, "in (0, 1000]");
  require(s.imu_accel_gate >= 0.0 && s.imu_accel_gate <= 10.0, "slam.imu_accel_gate", s.imu_accel_gate,
          "in [0, 10]");
  require(s.imu_tilt_weight >= 0.0 && s.imu_tilt_weight <= 1e6, "slam.imu_tilt_weight", s.imu_tilt_weight,
          "in [0, 1e6]");
  constexpr double kPi = 3.14159265358979323846;
  require(std::abs(s.imu_roll) <= kPi, "slam.imu_roll", s.imu_roll, "in [-pi, pi]");
  require(std::abs(s.imu_pitch) <= 0.5 * kPi, "slam.imu_pitch", s.imu_pitch, "in [-pi/2, pi/2]");
  require(std::abs(s.imu_yaw) <= kPi, "slam.imu_yaw", s.imu_yaw, "in [-pi, pi]");
  require(s.deskew == 0 || s.deskew == 1, "slam.deskew", s.deskew, "0 or 1");
}

}  // namespace hmap
