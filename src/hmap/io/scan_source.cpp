#include "hmap/io/scan_source.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/cloud_reader.hpp"
#include "hmap/io/gravity.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/io/rgbd.hpp"

namespace hmap {

namespace {

/// The depth images of an RGB-D folder, back-projected one at a time.
class RgbdFrames final : public FrameReader {
 public:
  explicit RgbdFrames(RgbdSequence seq) : seq_(std::move(seq)) {}
  [[nodiscard]] PointCloud read(std::size_t index, CloudReadStats& stats, std::vector<float>* times_s) const override {
    if (times_s != nullptr) times_s->clear();
    return read_rgbd_frame(seq_, index, &stats);
  }

 private:
  RgbdSequence seq_;
};

}  // namespace

ScanSource open_scan_files(const ScanSourceSpec& spec) {
  ScanSource src;
  src.budget = spec.budget;
  const std::size_t max_scans = spec.max_scans;
  if (!spec.kitti.empty() && !spec.files.empty()) throw Error("give either --kitti DIR or scan files, not both");
  if (spec.kitti.empty() && spec.files.empty()) throw Error("no scans: give --kitti DIR or scan files");
  if (!spec.kitti.empty()) {
    KittiSequenceOptions options;
    if (max_scans > 0) options.max_scans = max_scans;
    KittiSequence seq = open_kitti_sequence(spec.kitti, options);
    src.scans = seq.scan_paths;
    src.stamps = std::move(seq.times);
    if (seq.T_map_scan) {
      src.T_map_scan = std::move(seq.T_map_scan);
      src.poses_name = (std::filesystem::path(spec.kitti) / "poses.txt").string();
    }
  } else {
    for (const auto& f : spec.files) src.scans.emplace_back(f);
  }
  if (max_scans > 0 && src.scans.size() > max_scans) src.scans.resize(max_scans);
  if (!spec.poses.empty()) {
    PoseFile file = read_stamped_pose_file(spec.poses);
    src.T_map_scan = std::move(file.poses);
    src.poses_name = spec.poses;
    // The scans' own stamps (a KITTI folder's times.txt) first, else the poses'.
    if (src.stamps.empty()) src.stamps = std::move(file.times);
  }
  if (src.T_map_scan) {
    auto& poses = *src.T_map_scan;
    const bool truncated = max_scans > 0 && poses.size() > src.scans.size() && src.scans.size() == max_scans;
    if (poses.size() != src.scans.size() && !truncated) {
      throw InputError(src.poses_name, "", "holds " + std::to_string(poses.size()) + " poses for " +
                                               std::to_string(src.scans.size()) + " scans");
    }
    poses.resize(src.scans.size());
    if (src.stamps.size() > poses.size()) src.stamps.resize(poses.size());
  } else if (spec.poses_required) {
    throw Error("no poses: give --poses FILE (KITTI or TUM format) or a KITTI folder with poses.txt; "
                "to estimate poses from the scans, use `hmap slam`");
  }
  return src;
}

ScanSource open_rgbd_source(const ScanSourceSpec& spec) {
  ScanSource src;
  src.budget = spec.budget;
  const std::string dir = spec.rgbd.empty() ? spec.tum : spec.rgbd;
  RgbdOptions options;
  if (!spec.intrinsics.empty()) options.intrinsics = spec.intrinsics;
  options.depth_scale = spec.depth_scale;
  options.max_frames = spec.max_scans;
  RgbdSequence seq = open_rgbd_sequence(dir, options);
  if (!spec.tum.empty() && seq.layout != RgbdLayout::kTum) throw InputError(dir, "", "is not a TUM RGB-D folder (no depth.txt)");
  src.T_map_scan.emplace();
  for (const auto& frame : seq.frames) {
    src.scans.push_back(frame.depth_png);
    src.T_map_scan->push_back(frame.T_world_cam);
  }
  src.poses_name = dir;
  src.description = std::to_string(seq.frames.size()) + " RGB-D frames of " + dir +
                    (seq.layout == RgbdLayout::kTum ? " (TUM)" : " (7-Scenes)");
  if (seq.frames_without_pose > 0) src.description += ", " + std::to_string(seq.frames_without_pose) + " without pose skipped";
  src.frames = std::make_shared<RgbdFrames>(std::move(seq));
  return src;
}

void check_one_input(const ScanSourceSpec& spec) {
  const int inputs = static_cast<int>(!spec.rgbd.empty()) + static_cast<int>(!spec.tum.empty()) +
                     static_cast<int>(!spec.bag.empty()) + static_cast<int>(!spec.kitti.empty()) +
                     static_cast<int>(!spec.files.empty());
  if (inputs > 1) throw Error("give one input: --kitti DIR, scan files, --rgbd DIR, --tum DIR or --bag FILE");
  if (spec.sensor_input() && !spec.poses.empty()) {
    throw Error("--poses applies to scan files and KITTI folders; RGB-D folders and bags carry their poses");
  }
}

void apply_up(ScanSource& src, const ScanSourceSpec& spec) {
  const bool rgbd = !spec.rgbd.empty() || !spec.tum.empty();
  std::string up = spec.up;
  if (up.empty() && spec.rotation.empty() && rgbd) up = "floor";
  if (up.empty() && spec.rotation.empty()) return;
  if (!up.empty() && !spec.rotation.empty()) throw Error("give either --up or --rotation, not both");
  if (!src.T_map_scan) throw Error("--up and --rotation turn the poses of the scans; these scans have none");
  auto& poses = *src.T_map_scan;
  Pose T_map_world = Pose::Identity();
  if (!spec.rotation.empty()) {
    T_map_world = parse_rotation(spec.rotation);
  } else if (up == "floor") {
    // The cameras' (or scanners') own up vectors give the prior: −y of an optical frame, +z otherwise.
    Eigen::Vector3d prior = Eigen::Vector3d::Zero();
    for (const auto& T : poses) prior += rgbd ? Eigen::Vector3d(-T.linear().col(1)) : Eigen::Vector3d(T.linear().col(2));
    PointCloud points_world;
    const std::size_t frames = std::min<std::size_t>(8, src.scans.size());
    CloudReadStats ignored;
    for (std::size_t f = 0; f < frames; ++f) {
      const std::size_t k = frames > 1 ? f * (src.scans.size() - 1) / (frames - 1) : 0;
      const PointCloud cloud = src.read(k, ignored);
      const std::size_t step = std::max<std::size_t>(1, cloud.size() / 20000);
      for (std::size_t i = 0; i < cloud.size(); i += step) {
        points_world.push_back((poses[k] * cloud[i].cast<double>()).cast<float>());
      }
    }
    std::vector<Eigen::Vector3d> sensors;
    for (const auto& T : poses) sensors.push_back(T.translation());
    const FloorParams floor_params;
    FloorEstimate floor = estimate_floor(points_world, prior, floor_params, sensors);
    if (!floor.found) {
      throw Error(format("no floor plane found in %zu frames (a plane within %.0f deg of the sensors' up and %.0f m of a sensor, "
                         "holding %.0f %% of the points); give the up axis with --up AXIS or --rotation",
                         frames, floor_params.max_tilt * 180.0 / M_PI, floor_params.max_sensor_distance,
                         floor_params.min_inlier_fraction * 100.0));
    }
    const bool flipped = orient_floor_below_sensors(floor, sensors, prior);
    T_map_world = gravity_rotation(floor.up_world);
    src.description += format("%sup from the floor plane (%.3f, %.3f, %.3f)%s, %zu of %zu points on it",
                              src.description.empty() ? "" : "; ", floor.up_world.x(), floor.up_world.y(),
                              floor.up_world.z(), flipped ? " (turned to face the sensors above it)" : "",
                              floor.inliers, floor.points);
  } else {
    T_map_world = gravity_rotation(parse_up_axis(up));
    src.description += (src.description.empty() ? "" : "; ") + std::string("world up axis ") + up;
  }
  for (auto& T : poses) T = T_map_world * T;
}

ScanSource open_scan_source_without_recordings(const ScanSourceSpec& spec) {
  check_one_input(spec);
  ScanSource src;
  if (!spec.rgbd.empty() || !spec.tum.empty()) {
    src = open_rgbd_source(spec);
  } else if (!spec.bag.empty()) {
    throw Error("this hmap was built without ROS bag support: apt-get install librosbag-dev libsensor-msgs-dev "
                "libnav-msgs-dev libtf2-msgs-dev, then configure and build again");
  } else {
    src = open_scan_files(spec);
  }
  apply_up(src, spec);
  return src;
}

PointCloud ScanSource::read(std::size_t index, CloudReadStats& stats, std::vector<float>* times_s) const {
  if (times_s != nullptr) times_s->clear();
  if (frames) return frames->read(index, stats, times_s);
  CloudReadStats s;
  const auto& path = scans.at(index);
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".png") throw InputError(path.string(), "", "a depth image needs its camera: use --rgbd DIR or --tum DIR");
  // Before the read: the file's bytes are held while its points are parsed (at most as many bytes
  // again for the binary formats, fewer for the text ones).
  if (budget != nullptr) {
    std::error_code size_error;
    const std::uintmax_t size = std::filesystem::file_size(path, size_error);
    if (!size_error) budget->require(2.0 * static_cast<double>(size), path.string() + ": reading the scan");
  }
  PointCloud cloud = read_cloud(path, &s, times_s, budget);
  stats += s;
  return cloud;
}

}  // namespace hmap
