#include "hmap/core/params.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
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

Params room_preset() {
  Params p = outdoor_preset();
  p.map.cell_size = 0.1;
  p.map.max_range = 10.0;
  return p;
}

Params preset(std::string_view name) {
  if (name == "indoor") return indoor_preset();
  if (name == "room") return room_preset();
  if (name == "outdoor") return outdoor_preset();
  throw Error("unknown preset '" + std::string(name) + "' (expected indoor, room or outdoor)");
}

namespace {

/// The shortest text that reads back as `v` exactly; whole numbers below 2^64 in full (100000,
/// not 1e+05).
std::string number_text(double v) {
  if (v == std::floor(v) && std::abs(v) <= 18446744073709551616.0) {
    char whole[32];
    const int n = std::snprintf(whole, sizeof whole, "%.0f", v);  // at most 21 characters
    return {whole, static_cast<std::size_t>(n)};
  }
  char number[32];
  const auto end = std::to_chars(number, number + sizeof number, v).ptr;
  return {number, static_cast<std::size_t>(end - number)};
}

/// [lo, hi], (lo, hi], [lo, hi), (lo, hi).
constexpr ParamRange closed(double lo, double hi) { return {lo, hi, false, false}; }
constexpr ParamRange above(double lo, double hi) { return {lo, hi, true, false}; }
constexpr ParamRange below(double lo, double hi) { return {lo, hi, false, true}; }
constexpr ParamRange open(double lo, double hi) { return {lo, hi, true, true}; }

constexpr double kPi = 3.141592653589793;

ParamRef ref(std::string name, std::string unit, std::string description, double& field, ParamRange range) {
  return {std::move(name), std::move(unit), std::move(description), [&field] { return field; },
          [&field](double v) { field = v; }, range};
}

/// `v` rounded to an integer of type Int; hmap::Error naming the parameter when it is not finite
/// or out of Int's range (a cast would wrap: 4294967696 would silently become 400).
template <typename Int>
Int checked_integer(const std::string& name, double v) {
  const double r = std::round(v);
  // [lowest, 2^digits): both bounds exact in a double, so the cast below is defined.
  if (!(r >= static_cast<double>(std::numeric_limits<Int>::lowest()) &&
        r < std::ldexp(1.0, std::numeric_limits<Int>::digits))) {
    std::ostringstream message;
    message << "parameter " << name << " = " << number_text(v) << " must be an integer in ["
            << +std::numeric_limits<Int>::lowest() << ", " << +std::numeric_limits<Int>::max() << "]";
    throw Error(message.str());
  }
  return static_cast<Int>(r);
}

template <typename Int>
ParamRef ref_int(std::string name, std::string unit, std::string description, Int& field, ParamRange range) {
  return {name, std::move(unit), std::move(description), [&field] { return static_cast<double>(field); },
          [&field, name](double v) { field = checked_integer<Int>(name, v); }, range};
}

}  // namespace

std::string ParamRange::text() const {
  return (min_open ? "(" : "[") + number_text(min) + ", " + number_text(max) + (max_open ? ")" : "]");
}

// The ranges: what the method can use, and no more than what runs in bounded time and memory
// (ground.iterations and the coarse search are loops per scan; lengths are at most a few km).
std::vector<ParamRef> param_refs(Params& p) {
  std::vector<ParamRef> r;
  auto& m = p.map;
  r.push_back(ref("map.cell_size", "m", "edge of a square grid cell", m.cell_size, closed(0.001, 100.0)));
  r.push_back(ref("map.point_distance_threshold", "m", "z gap that splits a height cluster (Alg. 2)",
                  m.point_distance_threshold, closed(0.0, 100.0)));
  r.push_back(ref("map.ring_gap_slope", "m/m",
                  "the z gap grows by this per metre of a cell's distance from the sensor (at most "
                  "map.ring_gap_max): a spinning LiDAR's rings on a far wall; 0 = the fixed gap",
                  m.ring_gap_slope, closed(0.0, 1.0)));
  r.push_back(ref("map.ring_gap_max", "m",
                  "the most map.ring_gap_slope widens the z gap to (the threshold itself may be more); "
                  "a LiDAR's default range is where its rings lie this far apart on a wall",
                  m.ring_gap_max, closed(0.0, 100.0)));
  r.push_back(ref("map.min_range", "m", "points closer to the sensor are dropped", m.min_range, closed(0.0, 1000.0)));
  r.push_back(ref("map.max_range", "m", "points farther from the sensor are dropped", m.max_range,
                  above(0.0, 10000.0)));
  r.push_back(ref("map.density_gain", "-", "K_m of eq. (1)", m.density_gain, above(0.0, 1e6)));
  r.push_back(ref("map.density_normalization", "m^3", "K_n of eq. (1)", m.density_normalization, above(0.0, 1e6)));
  r.push_back(ref("map.density_min_points", "-", "d_min of eq. (1)", m.density_min_points, closed(0.0, 1e9)));
  r.push_back(ref("map.min_hvoxel_height", "m", "floor of the height h in eq. (1)",
                  m.min_hvoxel_height, above(0.0, 100.0)));
  r.push_back(ref("map.density_threshold", "-", "n_th: HVoxels below it cast no ray and are removed",
                  m.density_threshold, closed(0.0, 1e6)));
  r.push_back({"map.free_space", "enum", "0 = ray tracing and extrusion, 1 = none",
               [&m] { return static_cast<double>(m.free_space); },
               [&m](double v) {
                 m.free_space = static_cast<FreeSpaceMode>(
                     checked_integer<std::underlying_type_t<FreeSpaceMode>>("map.free_space", v));
               },
               closed(0.0, 1.0)});
  r.push_back(ref("map.free_unite_gap", "m", "free bands of one cell closer than this unite",
                  m.free_unite_gap, closed(0.0, 100.0)));
  auto& g = p.ground;
  r.push_back(ref_int("ground.iterations", "-", "K, RRT iterations of Alg. 4", g.iterations, closed(0.0, 100000.0)));
  r.push_back(ref("ground.normal_threshold", "-", "N_th: 1 - |n1.n2| allowed between patches",
                  g.normal_threshold, closed(0.0, 1.0)));
  r.push_back(ref("ground.elevation_threshold", "m", "E_th: height step allowed between patches",
                  g.elevation_threshold, closed(0.0, 100.0)));
  r.push_back(ref("ground.expansion_distance", "m", "d_n, node expansion distance of eq. (2)",
                  g.expansion_distance, above(0.0, 100.0)));
  r.push_back(ref("ground.top_noise", "m", "sigma of the HVoxel tops on a flat floor, allowed in a patch's RMS",
                  g.top_noise, closed(0.0, 10.0)));
  // 2^64 − 2048: the largest double below 2^64, the largest seed a number in a file can name.
  r.push_back(ref_int("ground.seed", "-", "random seed of the patch exploration", g.seed,
                      closed(0.0, 18446744073709549568.0)));
  auto& o = p.occupancy;
  r.push_back(ref("occupancy.sigma", "m", "sigma of the obstacle term of eq. (4)", o.sigma, above(0.0, 100.0)));
  r.push_back(ref("occupancy.ground_gain", "-", "K_g of eq. (4)", o.ground_gain, closed(0.0, 0.5)));
  r.push_back(ref("occupancy.ground_distance", "m", "d_pth of eq. (4)", o.ground_distance, above(0.0, 100.0)));
  r.push_back(ref("occupancy.z_plus", "m", "z+, upper detection limit above the ground", o.z_plus,
                  closed(-1000.0, 1000.0)));
  r.push_back(ref("occupancy.z_minus", "m", "z-, lower detection limit below the ground", o.z_minus,
                  closed(-1000.0, 1000.0)));
  r.push_back(ref("occupancy.clamp_min", "-", "lowest occupancy probability kept", o.clamp_min, open(0.0, 0.5)));
  r.push_back(ref("occupancy.clamp_max", "-", "highest occupancy probability kept", o.clamp_max, open(0.5, 1.0)));
  r.push_back(ref("occupancy.ground_reach", "m", "farthest an HVoxel may be from a ground patch to be judged",
                  o.ground_reach, above(0.0, 10000.0)));
  r.push_back(ref("occupancy.obstacle_reach", "m",
                  "farthest a column standing on a ground patch's plane may be from it to be judged an obstacle",
                  o.obstacle_reach, above(0.0, 10000.0)));
  r.push_back(ref("occupancy.free_ray_height", "m", "a ray frees the cells it crosses at most this high above the ground",
                  o.free_ray_height, closed(0.0, 1000.0)));
  auto& s = p.slam;
  r.push_back(ref_int("slam.interpolation_window", "cells", "IDW window of eq. (12), odd",
                      s.interpolation_window, closed(1.0, 9.0)));
  r.push_back(ref("slam.idw_power", "-", "p of eq. (12)", s.idw_power, above(0.0, 100.0)));
  r.push_back(ref_int("slam.max_iterations", "-", "Gauss-Newton iterations per scan",
                      s.max_iterations, closed(1.0, 1000.0)));
  r.push_back(ref("slam.idw_weight", "-", "weight of an IDW-interpolated neighbour (eq. 12)",
                  s.idw_weight, closed(0.0, 1.0)));
  r.push_back(ref("slam.min_match_height", "m", "thinner scan HVoxels do not take part in matching",
                  s.min_match_height, closed(0.0, 100.0)));
  r.push_back(ref("slam.min_layer_height", "m", "intervals are widened to this for the IoU (eq. 9)",
                  s.min_layer_height, above(0.0, 100.0)));
  r.push_back(ref("slam.robust_scale", "-", "Cauchy scale on the residual 1 - M_H; 0 = off",
                  s.robust_scale, closed(0.0, 1e6)));
  r.push_back(ref("slam.convergence_translation", "m", "a smaller Gauss-Newton step ends the match",
                  s.convergence_translation, above(0.0, 100.0)));
  r.push_back(ref("slam.convergence_rotation", "rad", "a smaller Gauss-Newton step ends the match",
                  s.convergence_rotation, above(0.0, kPi)));
  r.push_back(ref("slam.degeneracy_ratio", "-", "curvature ratio of eq. (5) under which a match is degenerate",
                  s.degeneracy_ratio, below(0.0, 1.0)));
  r.push_back(ref_int("slam.max_hvoxels", "-", "HVoxels matched per scan at most; 0 = all",
                      s.max_hvoxels, closed(0.0, 1e8)));
  r.push_back(ref("slam.coarse_trigger_ratio", "-",
                  "a match scoring under this times the running mean is retried by a coarse search; 0 = never",
                  s.coarse_trigger_ratio, closed(0.0, 1.0)));
  r.push_back(ref("slam.coarse_translation", "m",
                  "half-width of the coarse search in x and y; at most 100 cells (50 steps of 2 cells)",
                  s.coarse_translation, closed(0.0, 20.0)));
  r.push_back(ref("slam.coarse_rotation", "rad", "half-width of the coarse search in yaw",
                  s.coarse_rotation, closed(0.0, kPi)));
  r.push_back(ref("slam.odometry_sigma_translation", "m",
                  "odometry's sigma in x and y per scan (fixed part); large = odometry only as the guess",
                  s.odometry_sigma_translation, above(0.0, 100.0)));
  r.push_back(ref("slam.odometry_sigma_rotation", "rad", "odometry's sigma in yaw per scan (fixed part)",
                  s.odometry_sigma_rotation, above(0.0, 10.0)));
  r.push_back(ref("slam.odometry_noise", "-", "odometry's sigma added per metre travelled and per radian turned",
                  s.odometry_noise, closed(0.0, 10.0)));
  r.push_back(ref_int("slam.hvoxel_centroids", "-",
                      "2: match scan HVoxels at their points' plan centroids and the map's cells at their tall points' centroids; 1: the scan's only; 0: at their cells' centres (the paper's eq. 6)",
                      s.hvoxel_centroids, closed(0.0, 2.0)));
  r.push_back(ref("slam.wall_tilt_drift", "rad",
                  "per scan: how far the tilt from the floors may wander between scans; the walls' lean corrects it (0 = off)",
                  s.wall_tilt_drift, closed(0.0, 0.1)));
  r.push_back(ref_int("slam.wall_refine", "-", "1: refine x, y and yaw against the map's walls after the planar match; 0: off",
                      s.wall_refine, closed(0.0, 1.0)));
  r.push_back(ref("slam.wall_min_height", "m", "points of HVoxels at least this tall count as walls (wall refinement)",
                  s.wall_min_height, above(0.0, 100.0)));
  r.push_back(ref("slam.wall_band_height", "m", "the walls' plan moments are kept per height band this tall",
                  s.wall_band_height, closed(0.01, 100.0)));
  r.push_back(ref_int("slam.wall_iterations", "-", "Gauss-Newton iterations of the wall refinement",
                      s.wall_iterations, closed(1.0, 100.0)));
  r.push_back(ref("slam.wall_min_pairs", "-", "fewer scan cells paired with a map wall: the pose is kept",
                  s.wall_min_pairs, closed(3.0, 1e6)));
  r.push_back(ref("slam.wall_max_rotation", "rad", "a wall refinement turning farther than this is not taken",
                  s.wall_max_rotation, above(0.0, 1.0)));
  r.push_back(ref("slam.surface_max_height", "m", "HVoxels at most this tall count as horizontal surfaces (attitude fit)",
                  s.surface_max_height, above(0.0, 5.0)));
  r.push_back(ref("slam.attitude_gate", "m", "farthest a scan surface is paired with the map's (attitude fit)",
                  s.attitude_gate, above(0.0, 10.0)));
  r.push_back(ref_int("slam.attitude_iterations", "-", "Gauss-Newton iterations of the attitude fit; 0 = off",
                      s.attitude_iterations, closed(0.0, 100.0)));
  r.push_back(ref("slam.attitude_min_surfaces", "-", "fewer surface pairs: the attitude keeps its guess",
                  s.attitude_min_surfaces, closed(3.0, 1e6)));
  r.push_back(ref("slam.attitude_min_lever", "m", "RMS lever arm under which roll or pitch is not observable",
                  s.attitude_min_lever, above(0.0, 100.0)));
  r.push_back(ref("slam.level_prior", "-", "pull of the attitude fit toward a level floor (fraction of the map's)",
                  s.level_prior, closed(0.0, 100.0)));
  r.push_back(ref("slam.level_max_slope", "rad", "a scan floor tilted more than this is a slope: not levelled",
                  s.level_max_slope, closed(0.0, 1.2)));
  r.push_back(ref("slam.max_floor_tilt", "rad", "steepest plane taken for a scan's floor",
                  s.max_floor_tilt, closed(0.0, 1.2)));
  r.push_back(ref("slam.imu_gravity_time_constant", "s",
                  "time constant of the IMU's complementary filter (accelerometer gravity vs gyro)",
                  s.imu_gravity_time_constant, above(0.0, 1000.0)));
  r.push_back(ref("slam.imu_accel_gate", "-",
                  "|accel| farther than this fraction of g from g: the sample does not correct the tilt",
                  s.imu_accel_gate, closed(0.0, 10.0)));
  r.push_back(ref("slam.imu_tilt_weight", "-",
                  "pull of the attitude fit toward the IMU's gravity (fraction of the map pairs' tilt information)",
                  s.imu_tilt_weight, closed(0.0, 1e6)));
  r.push_back(ref("slam.imu_roll", "rad", "IMU mounting in the sensor frame, roll of R_sensor_imu", s.imu_roll,
                  closed(-kPi, kPi)));
  r.push_back(ref("slam.imu_pitch", "rad", "IMU mounting in the sensor frame, pitch of R_sensor_imu", s.imu_pitch,
                  closed(-0.5 * kPi, 0.5 * kPi)));
  r.push_back(ref("slam.imu_yaw", "rad", "IMU mounting in the sensor frame, yaw of R_sensor_imu", s.imu_yaw,
                  closed(-kPi, kPi)));
  r.push_back(ref_int("slam.deskew", "-",
                      "1: points with a time moved to one time by constant velocity (odometry's or an IMU's, to "
                      "the scan's time; else the last two estimates', to the sweep's middle); 0: off",
                      s.deskew, closed(0.0, 1.0)));
  r.push_back(ref_int("slam.loop_closure", "-", "1: loop closure (key frames, place recognition, pose graph, map rebuilt); 0: off",
                      s.loop_closure, closed(0.0, 1.0)));
  r.push_back(ref("slam.keyframe_distance", "m", "a key frame every this far along the estimated path",
                  s.keyframe_distance, above(0.0, 10000.0)));
  r.push_back(ref("slam.keyframe_rotation", "rad", "or after turning this much since the last key frame",
                  s.keyframe_rotation, above(0.0, kPi)));
  r.push_back(ref_int("slam.loop_submap_scans", "-", "scans merged into a key frame's sub-map at most",
                      s.loop_submap_scans, closed(1.0, 100.0)));
  r.push_back(ref("slam.loop_min_travel", "m", "a loop candidate is at least this far back along the path",
                  s.loop_min_travel, closed(0.0, 1e6)));
  r.push_back(ref("slam.loop_search_radius", "m", "a loop candidate is at most this far from the drifted estimate",
                  s.loop_search_radius, above(0.0, 1e5)));
  r.push_back(ref("slam.loop_max_descriptor_distance", "-",
                  "place descriptors farther apart than this (0 same, 1 unlike) are no loop candidate",
                  s.loop_max_descriptor_distance, above(0.0, 1.0)));
  r.push_back(ref_int("slam.loop_candidates", "-", "loop candidates verified per key frame at most",
                      s.loop_candidates, closed(1.0, 50.0)));
  r.push_back(ref("slam.loop_search_translation", "m",
                  "half-width of the loop verification's coarse search in x and y (at most 100 cells are searched)",
                  s.loop_search_translation, closed(0.0, 20.0)));
  r.push_back(ref("slam.loop_search_rotation", "rad", "half-width of the loop verification's coarse search in yaw",
                  s.loop_search_rotation, closed(0.0, kPi)));
  r.push_back(ref("slam.loop_min_score", "-", "mean M_H of a loop verification under which the candidate is refused",
                  s.loop_min_score, closed(0.0, 1.0)));
  return r;
}

namespace {

void require(bool ok, const char* name, double value, const char* domain) {
  if (ok) return;
  std::ostringstream msg;
  msg << "parameter " << name << " = " << number_text(value) << " is invalid: must be " << domain;
  throw Error(msg.str());
}

}  // namespace

void validate(const Params& p) {
  // Every scalar in its range first (NaN and infinity are in none).
  Params copy = p;
  for (const auto& r : param_refs(copy)) {
    const double v = r.get();
    if (r.range.contains(v)) continue;
    throw Error("parameter " + r.name + " = " + number_text(v) + " is out of its range " + r.range.text() +
                (r.unit == "-" || r.unit == "enum" ? "" : " " + r.unit));
  }
  // Then the rules between parameters.
  const auto& m = p.map;
  require(m.max_range > m.min_range, "map.max_range", m.max_range, "> map.min_range");
  // The scan is binned into a dense window of (2·max_range/cell)^2 cells: keep it in memory.
  const double half_cells = std::ceil(m.max_range / m.cell_size);
  require(half_cells <= 2048.0, "map.max_range", m.max_range,
          "at most 2048 cells from the sensor (max_range / cell_size <= 2048)");
  require(m.density_threshold <= m.density_gain, "map.density_threshold", m.density_threshold, "in [0, K_m]");
  const auto& o = p.occupancy;
  require(o.z_plus > o.z_minus, "occupancy.z_plus", o.z_plus, "> occupancy.z_minus");
  const auto& s = p.slam;
  require(s.interpolation_window % 2 == 1, "slam.interpolation_window", s.interpolation_window,
          "an odd number in [1, 9]");
  // The coarse search walks (2n + 1)^2 positions per yaw step with n = coarse_translation / (2 cells).
  require(s.coarse_translation <= 100.0 * m.cell_size, "slam.coarse_translation", s.coarse_translation,
          "at most 100 cells (100 * map.cell_size)");
}

}  // namespace hmap
