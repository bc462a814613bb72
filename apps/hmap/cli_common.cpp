#include "cli_common.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstdio>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/config.hpp"
#include "hmap/sources/open_scan_source.hpp"
#include "hmap/core/sensor_profile.hpp"

namespace hmap::cli {

void ParamOptions::add_to(CLI::App& app) {
  app.add_option("--preset", preset,
                 "Parameter preset: indoor (0.05 m cells, 5 m) and outdoor (0.25 m, 25 m) of the paper's section V, "
                 "room (0.1 m, 10 m) between them (default: map and slam choose the first whose range holds 95 % "
                 "of the first scan)")
      ->check(CLI::IsMember({"indoor", "room", "outdoor"}));
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

ScanSourceSpec InputOptions::spec(bool poses_required) const {
  ScanSourceSpec spec;
  spec.kitti = kitti;
  spec.files = files;
  spec.poses = poses;
  spec.max_scans = scans;
  spec.poses_required = poses_required;
  spec.rgbd = sensors.rgbd;
  spec.tum = sensors.tum;
  spec.intrinsics = sensors.intrinsics;
  spec.depth_scale = sensors.depth_scale;
  spec.up = sensors.up;
  for (const auto& token : sensors.rotation) spec.rotation += token + " ";
  spec.bag = sensors.bag;
  spec.cloud_topic = sensors.cloud_topic;
  spec.pose_topic = sensors.pose_topic;
  spec.tf_frames = sensors.tf_frames;
  spec.budget = &memory_budget();
  spec.warn = [](const std::string& w) { std::fprintf(stderr, "hmap: warning: %s\n", w.c_str()); };
  return spec;
}

ScanSource InputOptions::open_inputs(bool poses_required) const { return open_scan_source(spec(poses_required)); }

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
