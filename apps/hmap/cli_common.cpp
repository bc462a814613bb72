#include "cli_common.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/cloud_reader.hpp"
#include "hmap/io/config.hpp"
#include "hmap/io/gravity.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/io/rgbd.hpp"
#include "hmap/core/sensor_profile.hpp"

namespace hmap::cli {

void ParamOptions::add_to(CLI::App& app) {
  app.add_option("--preset", preset,
                 "Parameter preset of the paper's section V (default: map and slam choose indoor when 95 % of the "
                 "first scan lies within the indoor preset's 5 m reach, else outdoor)")
      ->check(CLI::IsMember({"indoor", "outdoor"}));
  app.add_option("--config", config, "YAML parameter file applied on top of the preset");
  app.add_option("--set", overrides, "Override one parameter, NAME=VALUE (repeatable; see hmap params)");
  app.add_option("--cell", cell, "Grid cell size [m] (map.cell_size)");
  app.add_option("--min-range", min_range, "Drop points closer than this to the sensor [m]");
  app.add_option("--max-range", max_range, "Drop points farther than this from the sensor [m]");
}

ParamSources ParamOptions::sources() const {
  return ParamSources{preset, config, overrides, cell, min_range, max_range, {}};
}

Params ParamOptions::resolve(const std::string& fallback) const {
  ParamSources s = sources();
  if (s.preset.empty()) s.preset = fallback;
  return resolve_params(s);
}

std::string chosen_summary(const ScanParams& chosen) {
  std::string text;
  if (!chosen.preset_reason.empty()) text += format(" preset %s (%s).", chosen.preset.c_str(), chosen.preset_reason.c_str());
  for (const ChosenDefault& c : chosen.adapted) text += format(" %s = %g (%s).", c.name.c_str(), c.value, c.reason.c_str());
  return text;
}

ScanSource ScanSource::open(const std::string& kitti_dir, const std::vector<std::string>& files,
                            const std::string& poses_file, std::size_t max_scans, bool poses_required) {
  ScanSource src;
  if (!kitti_dir.empty() && !files.empty()) throw Error("give either --kitti DIR or scan files, not both");
  if (kitti_dir.empty() && files.empty()) throw Error("no scans: give --kitti DIR or scan files");
  if (!kitti_dir.empty()) {
    KittiSequenceOptions options;
    if (max_scans > 0) options.max_scans = max_scans;
    KittiSequence seq = open_kitti_sequence(kitti_dir, options);
    src.scans = seq.scan_paths;
    src.stamps = std::move(seq.times);
    if (seq.T_map_scan) {
      src.T_map_scan = std::move(seq.T_map_scan);
      src.poses_name = (std::filesystem::path(kitti_dir) / "poses.txt").string();
    }
  } else {
    for (const auto& f : files) src.scans.emplace_back(f);
  }
  if (max_scans > 0 && src.scans.size() > max_scans) src.scans.resize(max_scans);
  if (!poses_file.empty()) {
    PoseFile file = read_stamped_pose_file(poses_file);
    src.T_map_scan = std::move(file.poses);
    src.poses_name = poses_file;
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
  } else if (poses_required) {
    throw Error("no poses: give --poses FILE (KITTI or TUM format) or a KITTI folder with poses.txt; "
                "to estimate poses from the scans, use `hmap slam`");
  }
  return src;
}

void ScanSourceOptions::add_to(CLI::App& app) {
  app.add_option("--rgbd", rgbd, "RGB-D folder: 7-Scenes (frame-N.depth.png + .pose.txt) or TUM (depth.txt + groundtruth.txt)");
  app.add_option("--tum", tum, "TUM RGB-D folder (depth.txt, groundtruth.txt; depth in 1/5000 m)");
  app.add_option("--intrinsics", intrinsics, "Depth camera intrinsics file: fx fy cx cy, or a 3x3 matrix");
  app.add_option("--depth-scale", depth_scale, "Metres per depth unit (7-Scenes 0.001, TUM 0.0002)");
  app.add_option("--up", up,
                 "Up axis of the data's world frame (x, y, z with a sign, e.g. -y), or 'floor' to estimate it from "
                 "the dominant floor plane (the default for RGB-D)");
  // Nine tokens (as the help shows) or one quoted string split at its spaces: both work.
  app.add_option("--rotation", rotation,
                 "Rotation T_map_world making the map frame gravity-aligned: 9 numbers, row-major (R00 R01 ... R22)")
      ->expected(9)
      ->allow_extra_args(false)
      ->delimiter(' ');
  app.add_option("--bag", bag, "Recording: ROS 1 bag, MCAP file or rosbag2 folder (sensor_msgs/PointCloud2 + /tf or an odometry topic)");
  app.add_option("--cloud-topic", cloud_topic, "PointCloud2 topic of the bag (default: its only PointCloud2 topic)");
  app.add_option("--pose-topic", pose_topic, "nav_msgs/Odometry (or PoseStamped) topic of the bag giving the cloud poses");
  app.add_option("--tf-frames", tf_frames, "MAP [SENSOR]: poses from /tf, map frame to the cloud's (or SENSOR) frame")
      ->expected(1, 2);
}

void InputOptions::add_input_options(CLI::App& app, const std::string& poses_help) {
  app.add_option("--kitti", kitti, kKittiHelp);
  app.add_option("scans", files, kScanFilesHelp);
  if (!poses_help.empty()) app.add_option("--poses", poses, poses_help);
  app.add_option("--scans", scans, kScanCountHelp)->check(kCount);
  sensors.add_to(app);
}

ScanSource InputOptions::open_inputs(bool poses_required) const {
  return ScanSource::open(sensors, kitti, files, poses, scans, poses_required);
}

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

/// T_map_world from --rotation, --up AXIS or --up floor (the dominant near-horizontal plane of a
/// few frames, up to 8 spread over the run, 20k points each at most).
void make_gravity_aligned(ScanSource& src, const ScanSourceOptions& o, bool rgbd) {
  std::string up = o.up;
  if (up.empty() && o.rotation.empty() && rgbd) up = "floor";
  if (up.empty() && o.rotation.empty()) return;
  if (!up.empty() && !o.rotation.empty()) throw Error("give either --up or --rotation, not both");
  if (!src.T_map_scan) throw Error("--up and --rotation turn the poses of the scans; these scans have none");
  auto& poses = *src.T_map_scan;
  Pose T_map_world = Pose::Identity();
  if (!o.rotation.empty()) {
    std::string joined;
    for (const auto& token : o.rotation) joined += token + " ";
    T_map_world = parse_rotation(joined);
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

}  // namespace

ScanSource ScanSource::open(const ScanSourceOptions& o, const std::string& kitti_dir,
                            const std::vector<std::string>& files, const std::string& poses_file, std::size_t max_scans,
                            bool poses_required) {
  const int inputs = static_cast<int>(!o.rgbd.empty()) + static_cast<int>(!o.tum.empty()) + static_cast<int>(!o.bag.empty()) +
                     static_cast<int>(!kitti_dir.empty()) + static_cast<int>(!files.empty());
  if (inputs > 1) throw Error("give one input: --kitti DIR, scan files, --rgbd DIR, --tum DIR or --bag FILE");
  if (!o.any_input()) {
    ScanSource src = open(kitti_dir, files, poses_file, max_scans, poses_required);
    make_gravity_aligned(src, o, false);
    return src;
  }
  if (!poses_file.empty()) throw Error("--poses applies to scan files and KITTI folders; RGB-D folders and bags carry their poses");
  ScanSource src;
  const bool rgbd = !o.rgbd.empty() || !o.tum.empty();
  if (rgbd) {
    const std::string dir = o.rgbd.empty() ? o.tum : o.rgbd;
    RgbdOptions options;
    if (!o.intrinsics.empty()) options.intrinsics = o.intrinsics;
    options.depth_scale = o.depth_scale;
    options.max_frames = max_scans;
    RgbdSequence seq = open_rgbd_sequence(dir, options);
    if (!o.tum.empty() && seq.layout != RgbdLayout::kTum) throw InputError(dir, "", "is not a TUM RGB-D folder (no depth.txt)");
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
  } else {
#ifdef HMAP_HAVE_ROS
    src = open_bag_source(o, max_scans);
#else
    throw Error("this hmap was built without ROS bag support: apt-get install librosbag-dev libsensor-msgs-dev "
                "libnav-msgs-dev libtf2-msgs-dev, then configure and build again");
#endif
  }
  make_gravity_aligned(src, o, rgbd);
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
  std::error_code size_error;
  const std::uintmax_t size = std::filesystem::file_size(path, size_error);
  if (!size_error) memory_budget().require(2.0 * static_cast<double>(size), path.string() + ": reading the scan");
  PointCloud cloud = read_cloud(path, &s, times_s, &memory_budget());
  stats += s;
  return cloud;
}

Progress::Progress(std::string what, std::size_t total)
    : what_(std::move(what)), total_(total), active_(::isatty(STDERR_FILENO) == 1), last_() {}

void Progress::update(std::size_t done, double ms_per_item) {
  if (!active_) return;
  const auto now = Clock::now();
  if (done < total_ && now - last_ < std::chrono::milliseconds(100)) return;
  last_ = now;
  constexpr int kWidth = 30;
  const double frac = total_ > 0 ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
  const int filled = static_cast<int>(std::lround(frac * kWidth));
  std::fprintf(stderr, "\r%s [%s%s] %zu/%zu  %.1f ms each", what_.c_str(),
               std::string(static_cast<std::size_t>(filled), '#').c_str(),
               std::string(static_cast<std::size_t>(kWidth - filled), ' ').c_str(), done, total_, ms_per_item);
  std::fflush(stderr);
}

void Progress::finish() {
  if (!active_) return;
  std::fprintf(stderr, "\r\033[K");
  std::fflush(stderr);
}

MemoryBudget& memory_budget() {
  static MemoryBudget budget;
  return budget;
}

void prepare_output_set(const std::filesystem::path& dir, std::initializer_list<std::string_view> owned, std::string_view command) {
  struct stat st {};
  if (::stat(dir.c_str(), &st) == 0 && !S_ISDIR(st.st_mode)) throw Error(dir.string() + ": the output folder is a file");
  std::filesystem::path folder = std::filesystem::absolute(dir).lexically_normal();
  if (folder.filename().empty()) folder = folder.parent_path();  // "out/x/"
  const std::filesystem::path parent = folder.parent_path();
  std::error_code ec;
  std::filesystem::create_directories(parent, ec);
  if (ec) throw Error(dir.string() + ": cannot create the folder " + parent.string() + " (" + ec.message() + ")");
  check_output_set_folder(dir, owned, command);
}

void check_output_extension(const std::string& path, std::initializer_list<std::string_view> extensions,
                            const std::string& what) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  std::string names;
  for (const std::string_view e : extensions) {
    if (ext == e) return;
    names += (names.empty() ? "" : " or ") + std::string(e);
  }
  throw Error(path + ": " + what + "; give a name ending in " + names + ", not " + (ext.empty() ? "none" : ext));
}

std::string human_bytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 4) {
    bytes /= 1024.0;
    ++u;
  }
  return u == 0 ? format("%.0f %s", bytes, units[u]) : format("%.1f %s", bytes, units[u]);
}

std::string human_count(double n) {
  if (n >= 1e6) return format("%.2f M", n / 1e6);
  if (n >= 1e4) return format("%.1f k", n / 1e3);
  return format("%.0f", n);
}

}  // namespace hmap::cli
