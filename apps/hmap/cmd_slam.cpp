// hmap slam: scans in, poses estimated by Gauss-Newton matching on the HMAP (section IV-C), the
// map built at those poses.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "cli_common.hpp"
#include "mcap_output.hpp"
#include "hmap/io/prefetch.hpp"
#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/core/sensor_profile.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/gravity.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/imu_text.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/png.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/slam/hmap_slam.hpp"
#include "hmap/slam/loop_closure.hpp"
#include "hmap/render/render.hpp"
#ifdef HMAP_HAVE_VIEW
#include "live_view.hpp"
#endif
#ifdef HMAP_HAVE_ROS
#include "hmap/ros/bag_reader.hpp"
#endif

namespace hmap::cli {

namespace {

struct SlamOptions : InputOptions {
  ParamOptions params;
  std::string attitude_from;
  std::string odometry;
  std::string gt;
  std::string imu;
  std::string imu_topic;
  std::vector<double> imu_rpy;
  std::string sensor_up;            ///< the sensor's up axis as mounted (-z: upside down)
  std::string out;
  std::string mcap;
  std::string continue_from;        ///< a saved map the scans are localised in and added to
  std::vector<double> start;        ///< X Y YAW_DEG: where the first scan is looked for in it
  double search = 5.0;              ///< [m] half-width of that search in x and y
  double search_yaw_deg = 180.0;    ///< [deg] half-width in yaw
  bool loop_closure = false;     ///< --loop-closure: slam.loop_closure=1
  bool no_loop_closure = false;  ///< --no-loop-closure: slam.loop_closure=0
#ifdef HMAP_HAVE_VIEW
  LiveViewOptions view;
#endif
};

/// A pose file with one pose per scan (more allowed when --scans cut the sequence); in a KITTI
/// folder with calib.txt the poses are turned into scanner poses as the folder's own are.
PoseList read_scan_poses(const std::string& path, std::size_t scans, const std::optional<Pose>& T_cam_velo) {
  PoseList poses = read_poses(path);
  if (poses.size() < scans) {
    throw InputError(path, "", "holds " + std::to_string(poses.size()) + " poses for " + std::to_string(scans) + " scans");
  }
  poses.resize(scans);
  if (T_cam_velo) {
    for (auto& P : poses) P = T_cam_velo->inverse() * P * *T_cam_velo;
  }
  return poses;
}

/// The IMU samples of the run: --imu FILE, else the bag's sensor_msgs/Imu topic (--imu-topic when
/// it has several); none otherwise. `from` says where they came from.
std::optional<ImuSamples> load_imu(const SlamOptions& o, std::string& from) {
  if (!o.imu.empty()) {
    from = o.imu;
    return read_imu_text(o.imu);
  }
#ifdef HMAP_HAVE_ROS
  if (!o.sensors.bag.empty()) {
    if (const auto topic = ros::bag_imu_topic(o.sensors.bag, o.imu_topic)) {
      from = o.sensors.bag + " " + *topic;
      return ros::read_bag_imu(o.sensors.bag, *topic);
    }
    return std::nullopt;
  }
#endif
  if (!o.imu_topic.empty()) throw Error("--imu-topic needs a bag (--bag)");
  return std::nullopt;
}

void run_slam(const SlamOptions& o) {
  ParamSources sources = o.params.sources();
  if (!o.imu_rpy.empty()) {
    sources.values = {{"slam.imu_roll", o.imu_rpy[0]}, {"slam.imu_pitch", o.imu_rpy[1]}, {"slam.imu_yaw", o.imu_rpy[2]}};
  }
  if (o.loop_closure && o.no_loop_closure) throw Error("--loop-closure and --no-loop-closure exclude each other");
  if (o.loop_closure || o.no_loop_closure) sources.values.emplace_back("slam.loop_closure", o.loop_closure ? 1.0 : 0.0);
  // From the named preset (or outdoor) first, so that a bad value is refused before any work.
  Params params = [&] {
    ParamSources named = sources;
    if (named.preset.empty()) named.preset = "outdoor";
    return resolve_params(named);
  }();
  // --continue: the saved map with its own map parameters (a map built on with another cell would
  // not be one map); the matching's (slam.*) may be set.
  std::optional<MapFile> old;
  if (!o.continue_from.empty()) {
    const ParamOptions& po = o.params;
    if (!po.preset.empty() || !po.config.empty() || po.cell || po.min_range || po.max_range) {
      throw Error("hmap slam --continue: the map is continued with the parameters it was built with; "
                  "--preset, --config, --cell, --min-range and --max-range cannot change them (--set slam.* can)");
    }
    for (const std::string& kv : po.overrides) {
      if (kv.rfind("slam.", 0) != 0) {
        throw Error("hmap slam --continue: --set " + kv + ": only slam.* parameters can be set for a continued map");
      }
    }
    if (!(o.search >= 0.0 && o.search <= 20.0)) throw Error(format("--search %g: the half-width must be in [0, 20] m", o.search));
    if (!(o.search_yaw_deg >= 0.0 && o.search_yaw_deg <= 180.0)) {
      throw Error(format("--search-yaw %g: the half-width must be in [0, 180] degrees", o.search_yaw_deg));
    }
    old = load_map_file(o.continue_from);
    if (old->map.empty()) throw InputError(o.continue_from, "", "holds an empty map: there is nothing to continue");
  } else if (!o.start.empty() || o.search != 5.0 || o.search_yaw_deg != 180.0) {
    throw Error("--start, --search and --search-yaw place the first scan in a continued map: they need --continue");
  }
  // 'source' poses come from an RGB-D folder or a bag: refused before anything is read otherwise.
  const bool sensor_input = !o.sensors.rgbd.empty() || !o.sensors.tum.empty() || !o.sensors.bag.empty();
  if (o.odometry == "source" && !sensor_input) {
    throw Error("--odometry source needs an RGB-D folder or a bag (their poses are the odometry)");
  }
  if (o.gt == "source" && !sensor_input) throw Error("--gt source needs an RGB-D folder or a bag (their poses are the truth)");
  prepare_output_set(o.out, {"poses.txt", "poses_tum.txt", "matches.csv", "loop_closures.csv", "map.hmap", "trajectory.png", "truth.txt"}, "slam");  // before the work
  if (!o.mcap.empty()) check_mcap_output(o.mcap);
  const ScanSource src = o.open_inputs(/*poses_required=*/false);  // no --poses here
  // Defaults the first scan can tell (the ring spacing), for parameters left at the preset's value.
  CloudReadStats read_stats;
  std::optional<PointCloud> first;
  std::vector<float> first_times;
  std::string chosen_text;
  if (!src.scans.empty()) {
    first = src.read(0, read_stats, &first_times);
    // No preset named: the sensor's reach chooses it (a depth camera's 5 m: indoor).
    const ScanParams chosen = resolve_params_for_scan(sources, *first);
    params = chosen.params;
    chosen_text = chosen_summary(chosen);
  }
  // RGB-D folders and bags come with poses (the camera's, or /tf and odometry topics): their z,
  // roll and pitch serve as the attitude unless --attitude-from is given, and with
  // `--odometry source` their motion is the initial guess.
  const bool sensor_poses = src.frames != nullptr && src.T_map_scan.has_value();
  if (o.odometry == "source" && !sensor_poses) {
    throw Error("--odometry source needs an RGB-D folder or a bag (their poses are the odometry)");
  }
  const std::size_t n = src.scans.size();
  std::optional<Pose> T_cam_velo;
  std::vector<double> times;
  if (!o.kitti.empty()) {
    KittiSequenceOptions ko;
    if (o.scans > 0) ko.max_scans = o.scans;
    const KittiSequence seq = open_kitti_sequence(o.kitti, ko);
    T_cam_velo = seq.T_cam_velo;
    times = seq.times;
  }
  if (times.size() != n && src.stamps.size() == n) times = src.stamps;
  // Real stamps (times.txt, a bag's) drive the IMU and the deskewing's velocity; without them the
  // scan index stands in for poses_tum.txt and a sweep's span for the scan period.
  const bool stamped = times.size() == n;
  if (!o.mcap.empty() && stamped) check_mcap_stamps(times, o.kitti.empty() ? "the scans' stamps" : o.kitti + "/times.txt");
  if (!stamped) {
    times.resize(n);
    for (std::size_t k = 0; k < n; ++k) times[k] = static_cast<double>(k);
  }
  std::string imu_from;
  const std::optional<ImuSamples> imu_samples = load_imu(o, imu_from);
  std::optional<slam::ImuAttitudeFilter> imu;
  if (imu_samples) {
    if (!stamped) throw Error("an IMU needs the scans' stamps: a KITTI folder with times.txt, or a bag");
    imu.emplace(*imu_samples, params);
  }
  std::optional<PoseList> attitude;
  std::optional<PoseList> odometry;
  std::optional<PoseList> truth;
  // --attitude-from scans: z, roll and pitch from the scans even where the input has poses (an
  // RGB-D folder's are its tracker's, 7-Scenes' and TUM's the ground truth).
  const bool attitude_from_scans = o.attitude_from == "scans";
  if (!o.attitude_from.empty() && !attitude_from_scans) {
    attitude = read_scan_poses(o.attitude_from, n, T_cam_velo);
  } else if (sensor_poses && !attitude_from_scans) {
    attitude = *src.T_map_scan;
  }
  if (o.odometry == "source") {
    odometry = *src.T_map_scan;
  } else if (!o.odometry.empty()) {
    odometry = read_scan_poses(o.odometry, n, T_cam_velo);
  }
  if (o.gt == "source") {
    if (!sensor_poses) throw Error("--gt source needs an RGB-D folder or a bag (their poses are the truth)");
    truth = *src.T_map_scan;
  } else if (!o.gt.empty()) {
    truth = read_scan_poses(o.gt, n, T_cam_velo);
  }

  std::optional<slam::HmapSlam> holder;
  MapStats old_stats;
  std::size_t old_centroids = 0;
  if (old) {
    old_stats = old->map.stats();
    slam::ContinueOptions where;
    if (!o.start.empty()) where.guess = {o.start[0], o.start[1], o.start[2] * std::numbers::pi / 180.0};
    where.search_translation = o.search;
    where.search_rotation = o.search_yaw_deg * std::numbers::pi / 180.0;
    old_centroids = old->centroids ? old->centroids->size() : 0;
    holder.emplace(params, std::move(old->map), where, std::move(old->centroids));
    params = holder->params();
    chosen_text.clear();  // what the first scan chose for the map is the saved map's now
  } else {
    holder.emplace(params);
  }
  slam::HmapSlam& slam = *holder;
  // Loop closure rebuilds the map from this run's scans: a continued map's saved part would be lost.
  std::optional<slam::LoopCloser> loops;
  if (params.slam.loop_closure != 0 && !old) loops.emplace(params);
  // The first scan defines the map frame; with a reference it starts at the reference's first
  // pose (x, y, yaw below; its height here), so that ATE needs no alignment. A continued map's
  // frame is the saved one.
  if (!old && !attitude && (odometry || truth)) slam.start_at_height(slam::attitude_of(odometry ? odometry->front() : truth->front()).z);
  // A depth camera's frame is optical (y down): the first frame's tilt guess is its floor's, found
  // about −y. A LiDAR's frame is taken as level, its floor found about +z by the first match,
  // unless --sensor-up names how it is mounted (-z: upside down); its floor is then found about that.
  std::string first_tilt;
  const bool optical = !o.sensors.rgbd.empty() || !o.sensors.tum.empty();
  const bool named_up = !o.sensor_up.empty();
  if (named_up && attitude) {
    throw Error("--sensor-up: the attitude is given (" +
                std::string(o.attitude_from.empty() ? "the input's poses" : "--attitude-from") +
                "); it applies when the attitude is estimated from the scans");
  }
  const Eigen::Vector3d prior_up = [&] {
    if (!named_up) return Eigen::Vector3d(-Eigen::Vector3d::UnitY());
    try {
      return parse_up_axis(o.sensor_up);
    } catch (const Error& e) {
      throw Error(std::string("--sensor-up: ") + e.what());
    }
  }();
  if ((named_up || (!old && optical)) && !attitude && first) {
    const std::optional<SensorFloor> floor = floor_under_sensor(*first, prior_up);
    const char* sensor = optical ? "camera" : "sensor";
    if (floor) {
      slam.start_with_up(floor->up_sensor);
      const slam::Attitude a = slam.first_attitude();
      first_tilt = format(" First %s levelled by its floor (%zu of %zu points): roll %.1f°, pitch %.1f°, %s %.2f m above it.",
                          optical ? "frame" : "scan", floor->inliers, floor->points, a.roll * 180.0 / std::numbers::pi,
                          a.pitch * 180.0 / std::numbers::pi, sensor, floor->sensor_height);
    } else if (named_up) {
      slam.start_with_up(prior_up);
      first_tilt = format(" First scan taken as level about --sensor-up %s (no floor within 34° of it under the %s).",
                          o.sensor_up.c_str(), sensor);
    } else {
      throw InputError(src.scans.front().string(), "",
                       "the first depth frame shows no floor within 34° of the camera's -y axis, so its tilt is not "
                       "known: give the attitude (--attitude-from POSES, or drop --attitude-from scans to use the "
                       "folder's poses), or the camera's up axis (--sensor-up)");
    }
  }
  std::optional<slam::MapAlignResult> relocalised;
  double relocalise_ms = 0.0;  // the first scan of a continued map: its search and match
  PoseList estimate;
  double ms_total = 0.0;
  std::size_t converged = 0;
  std::size_t degenerate = 0;
  std::size_t coarse = 0;
  std::size_t coarse_rejected = 0;  // the search's pick lay along what the scan does not constrain
  std::size_t wide = 0;             // lost after the search: every heading searched too
  std::size_t skipped = 0;
  std::size_t heading_only = 0;
  std::size_t wall_levelled = 0;  // scans whose tilt the walls' lean corrected (slam.wall_tilt_drift)
  std::size_t walls_applied = 0;
  double wall_yaw_moved = 0.0;  // |yaw change| summed over the refined scans [rad]
  std::size_t iterations = 0;
  double score_sum = 0.0;
  std::string log = "scan,matched,converged,iterations,initial_cost,final_cost,score,hvoxels,degenerate,coarse_search,"
                    "coarse_rejected,wide_search,skipped,eig0,eig1,eig2,guess_x,guess_y,guess_yaw,x,y,yaw,z,roll,pitch,attitude_fit,surfaces,surface_rms,"
                    "observable_x,observable_y,observable_z,observable_roll,observable_pitch,observable_yaw,planar_passes,deskewed,"
                    "imu,tilt_hypotheses,tilt_from_floor,heading_only,wall_refined,wall_pairs,wall_rms,wall_dx,wall_dy,wall_dyaw,wall_tilt,wall_tilt_walls,ms\n";
#ifdef HMAP_HAVE_VIEW
  LiveView live(o.view);  // the map and the estimated path in the browser, as they grow
  std::vector<Eigen::Vector3d> path;
#endif
  Progress progress("slam", n);
  double ms_loops = 0.0;
  std::vector<double> closure_ms;  // [ms] per loop closed: the loop step of the scan that closed it  // key frames, sub-maps, place search and verification during the run
  std::size_t deskewed = 0;
  std::size_t timed = 0;  // scans whose points carry a time
  // From a bag or an RGB-D folder, scan k + 1 is decoded while scan k is matched; the first, read
  // above, is not read again.
  Prefetcher<ReadScan> scans(n, [&](std::size_t k) {
    ReadScan r;
    if (k == 0) {
      r.cloud = std::move(*first);
      r.times_s = std::move(first_times);
    } else {
      r.cloud = src.read(k, r.stats, &r.times_s);
    }
    return r;
  }, src.frames ? ReadAhead::kYes : ReadAhead::kNo);  // bags and RGB-D frames decode; files copy
  for (std::size_t k = 0; k < n; ++k) {
    ReadScan next = scans.next();
    read_stats += next.stats;
    const PointCloud cloud = std::move(next.cloud);
    const std::vector<float> point_times = std::move(next.times_s);
    const auto t0 = Clock::now();
    std::optional<slam::Attitude> att;
    if (attitude) att = slam::attitude_of((*attitude)[k]);
    std::optional<slam::PlanarPose> guess;
    if (odometry && k > 0) {
      // Odometry gives the motion since the last scan; it is applied to the last estimate.
      const slam::PlanarPose last = slam::planar_of(estimate.back());
      guess = last * (slam::inverse(slam::planar_of((*odometry)[k - 1])) * slam::planar_of((*odometry)[k]));
    } else if (k == 0 && !old && (odometry || truth)) {
      // The first scan defines the map frame: put it where the reference trajectory starts.
      guess = slam::planar_of(odometry ? odometry->front() : truth->front());
    }
    slam::ScanInput in;
    in.points_sensor = cloud;
    in.times = point_times;
    if (stamped) in.stamp = times[k];
    in.attitude = att;
    in.guess = guess;
    if (imu) in.imu = imu->prior_for_scan(times[k], point_times, slam.velocity().linear);
    const slam::SlamStep step = for_scan(src, k, [&] {
      slam::SlamStep s = slam.process(in);
      memory_budget().require(static_cast<double>(slam.map().memory_bytes()), "the map");  // grows with the area seen
      return s;
    });
    if (step.relocalised) {
      relocalised = step.relocalised;
      relocalise_ms = ms_since(t0);
    }
    deskewed += step.deskewed ? 1 : 0;
    wall_levelled += step.wall_tilt_walls > 0 ? 1 : 0;
    timed += point_times.empty() ? 0 : 1;
    const double ms = ms_since(t0);
    ms_total += ms;
    {
      const auto& m = step.match;
      const slam::PlanarPose xi = slam::planar_of(step.T_map_sensor);
      const slam::Attitude at = slam::attitude_of(step.T_map_sensor);
      const auto& af = step.attitude;
      log += format(
                    "%zu,%d,%d,%d,%.6g,%.6g,%.6g,%zu,%d,%d,%d,%d,%d,%.6g,%.6g,%.6g,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,"
                    "%d,%zu,%.4f,%d,%d,%d,%d,%d,%d,%d,%d,%d,%d,%d,%d,%d,%zu,%.4f,%.5f,%.5f,%.6f,%.6f,%zu,%.3f\n",
                    k, step.matched ? 1 : 0, m.converged ? 1 : 0, m.iterations, m.initial_cost, m.final_cost, m.score,
                    m.hvoxels_used, m.degenerate ? 1 : 0, m.coarse_search ? 1 : 0, m.coarse_rejected ? 1 : 0, m.wide_search ? 1 : 0, m.skipped ? 1 : 0, m.eigenvalues(0),
                    m.eigenvalues(1), m.eigenvalues(2), step.guess.x, step.guess.y, step.guess.yaw, xi.x, xi.y, xi.yaw,
                    at.z, at.roll, at.pitch, af.ran ? 1 : 0, af.surfaces, af.rms, step.observable[0] ? 1 : 0,
                    step.observable[1] ? 1 : 0, step.observable[2] ? 1 : 0, step.observable[3] ? 1 : 0,
                    step.observable[4] ? 1 : 0, step.observable[5] ? 1 : 0, step.planar_passes, step.deskewed ? 1 : 0,
                    step.imu_used ? 1 : 0, step.tilt_hypotheses, step.tilt_from_floor ? 1 : 0, m.heading_only ? 1 : 0,
                    step.walls.applied ? 1 : 0, step.walls.pairs, step.walls.rms, step.walls.change.x, step.walls.change.y,
                    step.walls.change.yaw, step.wall_tilt, step.wall_tilt_walls, ms);
    }
    estimate.push_back(step.T_map_sensor);
    if (loops) {
      const auto t_loop = Clock::now();
      loops->add_scan(cloud, step.T_map_sensor);
      const double ms_loop = ms_since(t_loop);
      ms_loops += ms_loop;
      // A loop closed in this step: its time is the step's (sub-map, place search, verifications).
      closure_ms.resize(loops->closures().size(), ms_loop);
    }
    if (step.matched) {
      converged += step.match.converged ? 1 : 0;
      degenerate += step.match.degenerate ? 1 : 0;
      coarse += step.match.coarse_search ? 1 : 0;
      coarse_rejected += step.match.coarse_rejected ? 1 : 0;
      wide += step.match.wide_search ? 1 : 0;
      skipped += step.match.skipped ? 1 : 0;
      heading_only += step.match.heading_only ? 1 : 0;
      walls_applied += step.walls.applied ? 1 : 0;
      wall_yaw_moved += std::abs(step.walls.change.yaw);
      iterations += static_cast<std::size_t>(step.match.iterations);
      score_sum += step.match.skipped ? 0.0 : step.match.score;
    }
    progress.update(k + 1, ms_total / static_cast<double>(k + 1));
#ifdef HMAP_HAVE_VIEW
    if (o.view.enabled) {
      path.push_back(estimate.back().translation());
      live.update(slam.map(), {}, nullptr, path, format("scan %zu of %zu", k + 1, n));
    }
#endif
  }
  progress.finish();

  // Loop closure: the pose graph over the key frames, every pose corrected, and the tiles the moved
  // scans reach rebuilt from the scans, read again (all of the map when scans were merged deskewed:
  // docs/SLAM.md).
  std::optional<slam::LoopClosureResult> closed;
  std::optional<TileRebuild> rebuilt;
  double ms_graph = 0.0;
  double ms_rebuild = 0.0;
  std::string loop_log = "keyframe_old,keyframe_new,scan_old,scan_new,descriptor_distance,descriptor_yaw,score,x,y,z,yaw,"
                         "drift_translation,drift_yaw,ms\n";
  if (loops) {
    const auto t_graph = Clock::now();
    closed = loops->close();
    ms_graph = ms_since(t_graph);
    closure_ms.resize(closed->closures.size(), ms_graph);  // closed by the last key frame, in close()
    for (std::size_t i = 0; i < closed->closures.size(); ++i) {
      const slam::LoopClosure& c = closed->closures[i];
      loop_log += format("%zu,%zu,%zu,%zu,%.4f,%.5f,%.4f,%.4f,%.4f,%.4f,%.5f,%.4f,%.5f,%.2f\n", c.keyframe_old, c.keyframe_new,
                         c.scan_old, c.scan_new, c.descriptor_distance, c.descriptor_yaw, c.score, c.T_old_new.x,
                         c.T_old_new.y, c.T_old_new.z, c.T_old_new.yaw, c.drift_translation, c.drift_yaw, closure_ms[i]);
    }
    if (!closed->closures.empty()) {
      const auto t_rebuild = Clock::now();
      CloudReadStats again;
      rebuilt = slam::map_at_corrected_poses(params, slam.map_holds_scans_as_given() ? &slam.map() : nullptr, estimate, closed->T_map_sensor,
                                             [&](std::size_t k, PointCloud& out) { out = src.read(k, again); }, &slam.map_centroids());
      ms_rebuild = ms_since(t_rebuild);
      estimate = rebuilt->T_map_sensor;
    }
  }
  const HMap& final_map = rebuilt ? rebuilt->map : slam.map();

  // The poses, the map and the picture are one set: a kill leaves the old folder or the new one.
  write_folder_atomic(o.out, [&](const std::filesystem::path& dir) {
    write_poses_kitti(dir / "poses.txt", estimate);
    if (o.gt == "source") write_poses_kitti(dir / "truth.txt", *truth);
    write_poses_tum(dir / "poses_tum.txt", times, estimate);
    write_file_atomic(dir / "matches.csv", log);
    if (loops) write_file_atomic(dir / "loop_closures.csv", loop_log);
    // The cell centroids go with the map: after a loop closure, those summed again at the
    // corrected poses where the map was rebuilt.
    const CellCentroids* centroids = &slam.map_centroids();
    if (rebuilt) centroids = rebuilt->centroids ? &*rebuilt->centroids : nullptr;
    save_hmap(dir / "map.hmap", final_map, {}, nullptr, centroids);
    const render::HeightRange range = render::resolve_range(final_map, {});
    render::TopViewport vp;
    RgbImage picture = render::render_top(final_map, range, 2000, vp, 2.0);
    std::vector<render::PathLayer> layers;
    if (truth) layers.push_back({&*truth, 255, 255, 255, "truth (--gt)"});
    layers.push_back({&estimate, 255, 0, 255, "estimate"});
    render::draw_paths_and_legend(picture, vp, render::height_legend(range), layers);
    write_png(dir / "trajectory.png", picture);
  });

  // Every scan but the first is matched; a continued map's first too.
  const std::size_t matches = old ? n : (n > 0 ? n - 1 : 0);
  const double matched = matches > 0 ? static_cast<double>(matches) : 1.0;
  const double scored = matches > skipped ? static_cast<double>(matches - skipped) : 1.0;  // mean M_H over these
  const MapStats st = final_map.stats();
  // Told with the result, not before the work: an error stays the one line of its run.
  if (!src.description.empty()) std::printf("input: %s\n", src.description.c_str());
  std::printf(
      "SLAM on %zu scans: %.1f ms per scan (%.1f scans/s, matching and map update), %.1f Gauss-Newton "
      "iterations per scan, %zu of %zu matches converged, %zu degenerate, %zu needed the coarse search%s, "
      "%zu kept the guess (fewer than %zu HVoxels)%s, mean M_H %.3f. The map has %zu cells and %zu HVoxels (cell %.3f m). Wrote %s/{poses.txt, poses_tum.txt, "
      "map.hmap, trajectory.png, matches.csv%s}%s. Attitude (z, roll, pitch): %s.%s%s%s%s Deskewed: %zu of %zu scans "
      "(per-point time).\n",
      n, n > 0 ? ms_total / static_cast<double>(n) : 0.0,
      ms_total > 0.0 ? 1000.0 * static_cast<double>(n) / ms_total : 0.0, static_cast<double>(iterations) / matched,
      converged, matches, degenerate, coarse,
      (coarse_rejected > 0 ? format(" (%zu of whose picks lay along what the scan does not constrain: the prediction's minimum kept)", coarse_rejected) : std::string()).append(
          wide > 0 ? format("; %zu fitted the map less than half as well as the matches before and searched every heading", wide) : std::string()).c_str(),
      skipped, slam::ScanMatcher::kMinHVoxels,
      heading_only > 0 ? format(", %zu turned their yaw alone on the thin HVoxels (x, y from odometry)", heading_only).c_str() : "",
      score_sum / scored,
      st.cells, st.hvoxels, params.map.cell_size, o.out.c_str(), o.gt == "source" ? ", truth.txt" : "",
      truth ? " (truth in white, estimate in magenta)" : "",
      attitude ? "given (the poses of the input or --attitude-from)"
               : imu ? "estimated from the scans with the IMU's gravity as prior"
                     : params.slam.wall_tilt_drift > 0.0
                         ? format("estimated from the scans (floor normal + map surfaces; the walls' lean held it to gravity on %zu of %zu scans, slam.wall_tilt_drift)",
                                  wall_levelled, n).c_str()
                         : "estimated from the scans (floor normal + map surfaces)",
      first_tilt.c_str(),
      chosen_text.empty() ? "" : " Chosen from the first scan:", chosen_text.c_str(),
      imu ? (" IMU: " + std::to_string(imu_samples->size()) + " samples from " + imu_from + ".").c_str() : "", deskewed, n);
  if (old) {
    std::printf("Continued %s (%zu cells, %zu HVoxels, %zu cell centroids before; its parameters, cell %.3f m).",
                o.continue_from.c_str(), old_stats.cells, old_stats.hvoxels, old_centroids, params.map.cell_size);
    if (relocalised) {
      const PlanarShift& at = relocalised->shift;
      std::printf(" The first scan was found at x %.3f m, y %.3f m, z %.3f m, yaw %.2f deg (coarse search of +-%g m, "
                  "+-%g deg; M_H %.3f over %zu columns), then matched, in %.2f s.",
                  at.x, at.y, at.z, at.yaw * 180.0 / std::numbers::pi, o.search, o.search_yaw_deg,
                  relocalised->match.score, relocalised->columns_used, relocalise_ms / 1000.0);
    }
    if (old->grid) {
      std::printf(" Its 2D grid and ground patches are not carried (SLAM keeps the HMAP alone): hmap map --continue %s "
                  "--poses %s/poses.txt adds the scans to all its layers.",
                  o.continue_from.c_str(), o.out.c_str());
    }
    if (params.slam.loop_closure != 0) std::printf(" Loop closure is off for a continued map (its rebuild would drop the saved map).");
    std::printf("\n");
  }
  if (params.slam.wall_refine != 0) {
    std::printf("Walls (slam.wall_refine): %zu of %zu matches refined against the map's walls, by %.3f deg of yaw on "
                "average (matches.csv: wall_*).\n",
                walls_applied, matches,
                walls_applied > 0 ? wall_yaw_moved / static_cast<double>(walls_applied) * 180.0 / std::numbers::pi : 0.0);
  }
  if (closed) {
    const std::size_t kfs = closed->keyframes;
    double ms_worst = 0.0;
    for (const double ms : closure_ms) ms_worst = std::max(ms_worst, ms);
    std::printf("Loop closure: %zu key frames, %zu loops closed (%zu candidates verified), %.1f ms per key frame for "
                "sub-maps, place search and verification (%.1f ms at most for a key frame that closed a loop)",
                kfs, closed->closures.size(), closed->candidates_verified, kfs > 0 ? ms_loops / static_cast<double>(kfs) : 0.0,
                ms_worst);
    if (!closed->closures.empty()) {
      std::printf("; pose graph %.1f ms (%d iterations), poses moved by up to %.2f m (the last by %.2f m); ", ms_graph,
                  closed->graph.iterations, closed->max_correction, closed->end_correction);
      if (rebuilt->whole) {
        std::printf("the whole map rebuilt from the %zu scans in %.2f s (scans were merged deskewed)", rebuilt->scans_integrated,
                    ms_rebuild / 1000.0);
      } else {
        std::printf("%zu of %zu scans moved more than %.3f m: %zu tiles rebuilt from %zu scans read again, %zu tiles kept, "
                    "in %.2f s", rebuilt->scans_moved, n, params.map.cell_size / 10.0, rebuilt->tiles_rebuilt,
                    rebuilt->scans_integrated, rebuilt->tiles_kept, ms_rebuild / 1000.0);
      }
      std::printf("; %s/loop_closures.csv", o.out.c_str());
    }
    std::printf(".\n");
  }
  if (timed > 0 && params.slam.deskew == 0) {
    std::printf("%zu scans carry a time per point but were not deskewed (slam.deskew=0).\n", timed);
  }
  // SLAM keeps no 2D grid: the one export would derive from the map's columns.
  // /tf at the scans' stamps when they are real (times.txt, a bag's), else all at 0.
  if (!o.mcap.empty()) write_run_mcap(o.mcap, final_map, {}, nullptr, estimate, stamped ? std::span<const double>(times) : std::span<const double>{});
#ifdef HMAP_HAVE_VIEW
  if (o.view.enabled) {
    live.update(final_map, {}, nullptr, path, format("done: %zu scans, written to %s", n, o.out.c_str()), true);
    live.serve_until_stopped();
  }
#endif
}

}  // namespace

void add_slam_command(CLI::App& app) {
  auto opts = std::make_shared<SlamOptions>();
  auto* cmd = app.add_subcommand("slam", "Estimate planar poses by matching scans on the HMAP, and build the map");
  opts->add_input_options(*cmd, /*poses_help=*/"");
  cmd->add_option("--attitude-from", opts->attitude_from,
                  "Poses (KITTI or TUM) whose z, roll and pitch are used, like an IMU's; 'scans': estimated from the "
                  "scans even where the input has poses (an RGB-D folder's or a bag's, used otherwise; a depth "
                  "camera's first frame is levelled by its floor)");
  cmd->add_option("--odometry", opts->odometry,
                  "Odometry poses: the initial guess moves by their increments ('source': the poses of the RGB-D "
                  "folder or bag)");
  cmd->add_option("--gt", opts->gt,
                  "True poses, drawn in trajectory.png; 'source': the RGB-D folder's or bag's poses, also written as "
                  "OUT/truth.txt (KITTI layout) for hmap eval traj");
  cmd->add_option("--imu", opts->imu,
                  "IMU text file, one sample per line: t gx gy gz ax ay az [qx qy qz qw] (s, rad/s, m/s^2; spaces or "
                  "commas; '#' comments; ns stamps when all exceed 1e14). Needs the scans' stamps (times.txt). A bag's "
                  "sensor_msgs/Imu topic is used without it");
  cmd->add_option("--imu-topic", opts->imu_topic, "The bag's sensor_msgs/Imu topic, when it has several");
  cmd->add_option("--imu-rpy", opts->imu_rpy,
                  "IMU mounting R_sensor_imu = Rz(yaw)Ry(pitch)Rx(roll) as ROLL PITCH YAW [rad] (slam.imu_roll, "
                  "imu_pitch, imu_yaw; default identity)")
      ->expected(3);
  cmd->add_option("--sensor-up", opts->sensor_up,
                  "The sensor's up axis as mounted (x, y, z with a sign): -z for a LiDAR mounted upside down, -y for "
                  "a camera's optical frame (the default for RGB-D). The first scan's floor is looked for about it; "
                  "when the attitude is estimated from the scans");
  cmd->add_option("--out,-o", opts->out, "Output folder")->required();
  cmd->add_option("--mcap", opts->mcap,
                  "Also write the map and the estimated poses as an MCAP recording for Foxglove (OUT.mcap), as hmap "
                  "export --mcap writes it, with the 2D grid derived from the map's columns and one /tf per scan at its "
                  "stamp (times.txt of a KITTI folder, a bag's; else 0)");
  cmd->add_option("--continue", opts->continue_from,
                  "A saved map (.hmap) to localise the scans in and add them to: its map parameters stay (slam.* "
                  "may be --set); the first scan is found by a coarse search about --start, the poses are in its "
                  "frame, and map.hmap is the map continued (its HVoxels; a 2D grid is not carried)");
  cmd->add_option("--start", opts->start,
                  "With --continue: X Y YAW_DEG, where the first scan is looked for in the saved map (default 0 0 0, "
                  "where its first scan was)")
      ->expected(3);
  cmd->add_option("--search", opts->search, "With --continue: half-width of the first scan's search in x and y [m], 0-20")
      ->capture_default_str();
  cmd->add_option("--search-yaw", opts->search_yaw_deg,
                  "With --continue: half-width of the first scan's search in yaw [deg], 0-180")
      ->capture_default_str();
  cmd->add_flag("--loop-closure", opts->loop_closure,
                "Close loops (slam.loop_closure=1, the default): key frames, place recognition, verification by map "
                "alignment, a pose graph; the poses corrected and the map rebuilt; loop_closures.csv");
  cmd->add_flag("--no-loop-closure", opts->no_loop_closure, "No loop closure (slam.loop_closure=0): the scan-to-map poses as they are");
  opts->params.add_to(*cmd);
#ifdef HMAP_HAVE_VIEW
  opts->view.add_to(*cmd);
#endif
  cmd->callback([opts] { run_slam(*opts); });
}

}  // namespace hmap::cli
