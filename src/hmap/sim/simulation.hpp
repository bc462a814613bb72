#pragma once
// A simulated recording (`hmap simulate`, `hmap demo`, hmap.sim.simulate): a scene, a sensor, a
// scripted path, noisy scans, the true poses, noisy odometry and the true geometry the sensor
// could see. Pure: the caller reads a JSON scene file and writes the recording.

#include <cstdint>
#include <functional>
#include <string>
#include <variant>

#include "hmap/core/imu.hpp"
#include "hmap/core/types.hpp"
#include "hmap/sim/scene.hpp"
#include "hmap/sim/sensors.hpp"

namespace hmap::sim {

/// A simulated sensor of any kind.
using AnySensor = std::variant<SpinningLidar, DepthCamera, LineScanner>;

/// Whether a sensor's noise model is on.
enum class SensorNoise : std::uint8_t {
  kModelled,  ///< the device's range noise and dropouts
  kNone,      ///< exact returns (the recording's truth_seen)
};

/// The sensors `hmap simulate --sensor` names.
[[nodiscard]] std::vector<std::string> sensor_names();
/// The names of sensor_names() that are spinning lidars (a sweep, a car's roof).
[[nodiscard]] bool is_spinning_lidar(const std::string& name);
/// sensor_names() as one comma-separated line, for help texts and errors.
[[nodiscard]] std::string sensor_names_text();

/// The sensor `name` (sensor_names(): the device presets of sensors.hpp) with noise seed `seed`.
/// Throws hmap::Error listing the known names for any other.
[[nodiscard]] AnySensor make_sensor(const std::string& name, std::uint64_t seed, SensorNoise noise = SensorNoise::kModelled);

struct SimulationSpec {
  /// The built-in scene whose path is driven (parking: the car route; boxes: along the enclosure);
  /// any other name, or "" for a scene of the caller's (simulate(spec, scene)), the office robot's route.
  std::string scene = "parking";
  std::string sensor = "vlp16";    ///< one of sensor_names()
  std::size_t frames = 0;          ///< 0: the whole path
  std::size_t stride = 1;          ///< take every stride-th frame of the 10 Hz path
  bool long_route = false;         ///< parking: drive on past the side road (about 313 m)
  double route_km = 1.0;           ///< [km] city: length of the drive, [0.1, 20] (city_car_route)
  /// city: a random walk on the streets (city_car_route), or a closed loop around blocks back to
  /// the start (city_loop_route, at least route_km long)
  enum class CityRoute : std::uint8_t { kRandom, kLoop } city_route = CityRoute::kRandom;
  /// truth_seen, truth_surface and truth_ground; false leaves them empty (and skips the noise-free
  /// second scan of every frame): a long drive's truth would be gigabytes.
  bool truth = true;
  std::uint64_t seed = 1;
  double truth_spacing = 0.1;      ///< [m] of the dense surface sample
  double truth_reach = 30.0;       ///< [m] the sample is kept this close to the path
  double imu_rate = 0.0;           ///< [Hz] of a simulated IMU on the sensor (noise: sim::ImuSimParams); 0 = none
  /// Spinning lidars: each frame is a sweep taken while the sensor moves (SpinningLidar::sweep,
  /// 0.1 s), its points in the sensor frame of their column's time, with that time; the true pose
  /// is the one at the sweep's start, the reference of the times. Otherwise the whole frame is
  /// taken at one instant.
  bool sweep = false;
  /// [rad] spinning lidars: the sensor mounted turned by this about its own z axis, in
  /// [−π, π]. The scene then lies at that angle to the first scan's axes, and so to the grid of a
  /// map built in its frame: the built-in scenes' walls are otherwise parallel to it.
  double mount_yaw = 0.0;
};

struct SimulatedRecording {
  std::vector<PointCloud> scans;   ///< sensor frame
  std::vector<std::vector<float>> point_times;  ///< [s] per point from the sweep's start, per scan (sweep only)
  PoseList T_world_sensor;         ///< the truth
  std::vector<double> times;       ///< [s]
  PoseList odometry;               ///< integrated noisy odometry
  ImuSamples imu;                  ///< the simulated IMU over the whole path, when asked for
  PointCloud truth_ground;         ///< the part of truth_surface that is walkable ground (roads, floors, ramps)
  PointCloud truth_seen;           ///< noise-free returns of the same sensor at every pose, scene at the last time
  PointCloud truth_surface;        ///< dense sample of every surface within the sensor's reach of the path
  std::size_t points = 0;
};

/// Throws hmap::Error unless route_km (SimulationSpec::route_km) is in [0.1, 20].
void check_route_km(double route_km);
/// For spec.scene "city": throws hmap::Error for a route_km out of range or truth asked for.
void check_city(const SimulationSpec& spec);

/// Length of the path through the poses' positions [m].
[[nodiscard]] double path_length(const PoseList& poses);

using SimulationProgress = std::function<void(std::size_t, std::size_t, std::size_t)>;

/// Where each frame goes as it is made instead of into SimulatedRecording::scans and point_times:
/// `sink(k, points_sensor, point_times)` (point_times empty unless spec.sweep), so that a long
/// drive is written as it is simulated and its scans are never all in memory.
using FrameSink = std::function<void(std::size_t, const PointCloud&, const std::vector<float>&)>;

/// Runs the simulation in `scene`; `progress(done, total, points)` is called after each frame,
/// with the points of the frames done so far (after the first: what the whole recording will
/// weigh). With a `sink`, the scans go to it and the recording holds none. Throws hmap::Error for
/// a spec out of range (stride 0, an unknown sensor, route_km outside [0.1, 20], ...).
[[nodiscard]] SimulatedRecording simulate(const SimulationSpec& spec, const Scene& scene,
                                          const SimulationProgress& progress = {}, const FrameSink& sink = {});

/// The same in the built-in scene spec.scene (make_scene).
[[nodiscard]] SimulatedRecording simulate(const SimulationSpec& spec, const SimulationProgress& progress = {},
                                          const FrameSink& sink = {});

/// The bytes a recording of `frames` frames will take on disk and in memory, from the points of
/// its first `done` frames: each point a 16-byte KITTI record and a 12-byte truth_seen.ply vertex (the
/// dense truth.ply comes on top).
[[nodiscard]] double recording_bytes(std::size_t points_done, std::size_t done, std::size_t frames);

}  // namespace hmap::sim
