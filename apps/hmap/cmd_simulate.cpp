// hmap simulate: a recording with ground truth, in the KITTI layout.

#include <cstdio>
#include <numbers>

#include "cli_common.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/imu_text.hpp"
#include "hmap/io/ply_export.hpp"
#include "hmap/io/sequence_writer.hpp"
#include "hmap/io/read_support.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/scene_json.hpp"
#include "hmap/sim/simulation.hpp"

namespace hmap::cli {

namespace {

struct SimulateOptions {
  sim::SimulationSpec spec;
  std::string scene_file;  ///< a JSON scene instead of the built-in spec.scene
  std::string out;
  bool route_km_given = false;
  std::string route = "random";
  double mount_yaw_deg = 0.0;  ///< [deg] --mount-yaw
};

void run_simulate(const SimulateOptions& o) {
  const bool city = o.scene_file.empty() && o.spec.scene == "city";
  if (o.route_km_given && !city) throw Error("--route-km is for --scene city (the other routes have their own length)");
  if (city && o.spec.long_route) throw Error("--long-route is for --scene parking; the city's drive takes --route-km");
  if (city) sim::check_route_km(o.spec.route_km);
  if (o.route != "random" && !city) throw Error("--route is for --scene city");
  prepare_output_set(o.out, {"velodyne/", "poses.txt", "times.txt", "odometry.txt", "truth.ply", "truth_seen.ply", "truth_ground.ply", "imu.txt"},
                     "simulate");  // before the work
  Progress progress("simulating", 1);
  const auto t0 = Clock::now();
  std::size_t total = 0;
  // The scene file is read here (the library takes the scene); its errors name the file.
  const sim::Scene scene = [&] {
    if (o.scene_file.empty()) return sim::make_scene(o.spec.scene);
    const std::string text = detail::read_file_bytes(o.scene_file, std::size_t{64} << 20);
    try {
      return sim::scene_from_json(text);
    } catch (const Error& e) {
      throw InputError(o.scene_file, "", e.what());
    }
  }();
  sim::SimulationSpec spec = o.spec;
  if (o.route == "loop") spec.city_route = sim::SimulationSpec::CityRoute::kLoop;
  if (!o.scene_file.empty()) spec.scene.clear();  // a scene of our own: the office robot's route
  spec.truth = !city;  // a town's dense truth would be gigabytes; its drive has none
  sim::SimulatedRecording rec;
  // One set: a kill leaves the old recording or the new one (a shorter run over a longer one
  // used to leave the old run's last scans beside the new poses). The scans are written as they
  // are made, so a long drive's are never all in memory.
  write_folder_atomic(o.out, [&](const std::filesystem::path& dir) {
    std::filesystem::create_directories(dir / "velodyne");
    const auto write_frame = [&](std::size_t k, const PointCloud& points, const std::vector<float>& times) {
      if (spec.sweep) write_simulated_frame(dir, k, points, times);
      else write_simulated_frame(dir, k, points);
    };
    rec = sim::simulate(spec, scene, [&](std::size_t done, std::size_t n, std::size_t points) {
      if (total == 0) {
        // Said before the rest of the work: the scans are written as they come, the noise-free
        // returns (truth_seen.ply, 12 bytes a point) held in memory until the end.
        const double bytes = sim::recording_bytes(points, done, n);
        const double held = spec.truth ? bytes * 12.0 / 28.0 : 0.0;
        std::printf("simulate: %zu frames of about %s points: about %s to write (%s held in memory while simulating); "
                    "--frames N or --stride N make it smaller.\n",
                    n, human_count(static_cast<double>(points) / static_cast<double>(done)).c_str(), human_bytes(bytes).c_str(),
                    human_bytes(held).c_str());
        std::fflush(stdout);
        memory_budget().require(held, "the simulated recording's truth (--frames N or --stride N make it smaller)");
        progress = Progress("simulating", total = n);
      }
      progress.update(done, ms_since(t0) / static_cast<double>(done));
    }, write_frame);
    progress.finish();
    write_simulated_records(dir, rec.T_world_sensor, rec.times, rec.odometry, rec.truth_surface);
    if (spec.truth) {
      write_points_ply(dir / "truth_seen.ply", rec.truth_seen);
      write_points_ply(dir / "truth_ground.ply", rec.truth_ground);
    }
    if (!rec.imu.empty()) write_imu_text(dir / "imu.txt", rec.imu);
  });
  const double length = sim::path_length(rec.T_world_sensor);
  const std::string truth_text =
      city ? std::string("no truth files (the town's would be gigabytes)")
           : format("truth.ply (%s surface points every %.2f m; its walkable ground in truth_ground.ply), truth_seen.ply "
                    "(%s noise-free returns)",
                    human_count(static_cast<double>(rec.truth_surface.size())).c_str(), o.spec.truth_spacing,
                    human_count(static_cast<double>(rec.truth_seen.size())).c_str());
  const std::string turned = o.mount_yaw_deg != 0.0 ? format(", the sensor turned %g deg", o.mount_yaw_deg) : "";
  std::printf("Simulated %zu %s %s of '%s' (seed %llu%s) along %.1f m in %.1f s: %s points. Wrote %s: "
              "velodyne/*.%s, poses.txt (truth%s), times.txt, odometry.txt (noisy), %s.\n",
              rec.T_world_sensor.size(), o.spec.sensor.c_str(), o.spec.sweep ? "sweeps" : "frames", o.scene_file.empty() ? o.spec.scene.c_str() : o.scene_file.c_str(),
              static_cast<unsigned long long>(o.spec.seed), turned.c_str(), length, ms_since(t0) / 1000.0,
              human_count(static_cast<double>(rec.points)).c_str(), o.out.c_str(), o.spec.sweep ? "pcd" : "bin",
              o.spec.sweep ? " at each sweep's start; each point's time t [s] from it is in the .pcd" : "",
              truth_text.c_str());
  if (!rec.imu.empty()) std::printf("imu.txt: %zu IMU samples at %g Hz.\n", rec.imu.size(), o.spec.imu_rate);
}

}  // namespace

void add_simulate_command(CLI::App& app) {
  auto opts = std::make_shared<SimulateOptions>();
  auto* cmd = app.add_subcommand("simulate", "Simulate a sensor moving through a scene; write KITTI layout and truth");
  cmd->add_option("--scene", opts->spec.scene,
                  "Built-in scene: office, parking, boxes, city (a town of 8 x 8 blocks on a sloping plane, for long "
                  "drives: --route-km; no truth files)")
      ->check(CLI::IsMember({"office", "parking", "boxes", "city"}))
      ->capture_default_str();
  cmd->add_option("--scene-file", opts->scene_file, "A JSON scene description instead of a built-in scene");
  cmd->add_option("--sensor", opts->spec.sensor, sim::sensor_names_text())
      ->check(CLI::IsMember(sim::sensor_names()))
      ->capture_default_str();
  cmd->add_option("--frames", opts->spec.frames, "Number of frames (default: the whole path)")->check(kCount);
  cmd->add_option("--stride", opts->spec.stride, "Keep every N-th frame of the 10 Hz path")->capture_default_str();
  cmd->add_flag("--long-route", opts->spec.long_route,
                "parking: drive on after the side road (U-turn, back south, east to the street's end; ~313 m)");
  auto* route_km = cmd->add_option("--route-km", opts->spec.route_km,
                                   "city: length of the drive through the streets [km], 0.1 to 20 (turns at random "
                                   "intersections from a fixed seed, coming back over streets driven before)")
                       ->capture_default_str();
  cmd->add_option("--route", opts->route,
                  "city: 'random' (a random walk of --route-km) or 'loop' (around a rectangle of blocks at least "
                  "--route-km long, back to the start and 40 m on: for loop closure)")
      ->check(CLI::IsMember({"random", "loop"}))
      ->capture_default_str();
  cmd->add_option("--seed", opts->spec.seed, "Noise seed")->check(kCount)->capture_default_str();
  cmd->add_option("--truth-spacing", opts->spec.truth_spacing, "Spacing of the true surface sample [m]")->capture_default_str();
  cmd->add_option("--imu-rate", opts->spec.imu_rate,
                  "[Hz] also write imu.txt: an IMU on the sensor (gyro and specific force with noise and a fixed "
                  "seed; the format of hmap slam --imu); 0 = none")
      ->capture_default_str();
  cmd->add_flag("--sweep", opts->spec.sweep,
                "vlp16, hdl64: each scan a 0.1 s sweep taken while the sensor moves, written as velodyne/*.pcd with "
                "each point's time t [s] from the sweep's start (hmap slam deskews them); poses.txt at the starts");
  cmd->add_option("--mount-yaw", opts->mount_yaw_deg,
                  "[deg] vlp16, hdl64, os0-64: the sensor mounted turned about its axis, -180 to 180, so that the "
                  "scene's walls lie at that angle to the first scan's axes (and to the grid of a map in its frame)")
      ->capture_default_str();
  cmd->add_option("--out,-o", opts->out, "Output folder")->required();
  cmd->callback([opts, route_km] {
    opts->route_km_given = route_km->count() > 0;
    opts->spec.mount_yaw = opts->mount_yaw_deg * std::numbers::pi / 180.0;
    run_simulate(*opts);
  });
}

}  // namespace hmap::cli
