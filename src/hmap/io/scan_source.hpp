#pragma once
// A run's scans as one sequence, whatever they came from: a KITTI folder, a list of scan files
// (with a pose file), an RGB-D folder (7-Scenes, TUM) or a recording (a ROS bag, MCAP, rosbag2).
// Each has a name, a pose T_map_scan when the source gives one, a stamp when it has them, and its
// points read one at a time. The CLI (`--kitti`, `--rgbd`, `--bag`, ...) and the Python package
// (hmap.io.*_sequence) open them through the same call: open_scan_source (hmap/sources), which
// reaches the recordings' opener in hmap::ros; this file holds the rest and takes no ROS.

#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "hmap/core/budget.hpp"
#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap {

/// What to open, as plain fields: exactly one input of kitti, files, rgbd, tum, bag.
struct ScanSourceSpec {
  std::string kitti;                  ///< KITTI-layout folder (velodyne/, poses.txt, calib.txt, times.txt)
  std::vector<std::string> files;     ///< scan files, in order (.pcd .ply .bin .xyz .txt .csv .pts .vtk)
  std::string poses;                  ///< poses T_map_scan (KITTI or TUM) for files or a KITTI folder
  std::size_t max_scans = 0;          ///< the first N scans only; 0 = all
  bool poses_required = false;        ///< a source without poses is refused (hmap map needs them)
  std::string rgbd;                   ///< 7-Scenes or TUM RGB-D folder (layout told by its files)
  std::string tum;                    ///< TUM RGB-D folder (must hold depth.txt)
  std::string intrinsics;             ///< fx fy cx cy or a 3x3 matrix, overriding the folder's
  std::optional<double> depth_scale;  ///< [m per depth unit]
  std::string up;                     ///< up axis of the world frame (x, -y, ...) or "floor"; RGB-D default "floor"
  std::string rotation;               ///< T_map_world rotation, 9 numbers row-major (parse_rotation); empty: none
  std::string bag;                    ///< recording: ROS 1 bag, MCAP file or rosbag2 folder
  std::string cloud_topic;            ///< sensor_msgs/PointCloud2 topic (empty: the only one)
  std::string pose_topic;             ///< nav_msgs/Odometry (or PoseStamped) topic giving the poses
  std::vector<std::string> tf_frames; ///< MAP [SENSOR] frames of /tf
  /// Reads of scan files are checked against it (the file's bytes, twice); null: unchecked.
  const MemoryBudget* budget = nullptr;
  /// Told what a reader read past (a recording cut off), one line each; null: not told.
  std::function<void(const std::string&)> warn;

  [[nodiscard]] bool sensor_input() const { return !rgbd.empty() || !tum.empty() || !bag.empty(); }
};

/// Reads the frames of a source that is not a list of files (an RGB-D folder, a recording).
class FrameReader {
 public:
  virtual ~FrameReader() = default;
  /// `times_s` given: each point's time [s] when the frame carries one, else left empty.
  [[nodiscard]] virtual PointCloud read(std::size_t index, CloudReadStats& stats,
                                        std::vector<float>* times_s = nullptr) const = 0;
};

/// The scans of a run and their poses.
struct ScanSource {
  /// Scan files, the depth images of an RGB-D folder, or "topic@stamp" of a recording's clouds.
  std::vector<std::filesystem::path> scans;
  std::optional<PoseList> T_map_scan;  ///< one per scan when the source has poses (always for RGB-D, recordings)
  std::string poses_name;              ///< the file the poses came from, for messages
  std::shared_ptr<const FrameReader> frames;  ///< set for RGB-D folders and recordings
  std::vector<double> stamps;                 ///< [s] per scan when the source has them (times.txt, TUM poses, bags)
  std::string description;                    ///< e.g. "50 RGB-D frames of DIR (7-Scenes)"; empty for files
  const MemoryBudget* budget = nullptr;       ///< the spec's, for read()

  /// The points of scan `index` in its sensor frame, non-finite ones dropped. `times_s` given:
  /// each point's time [s] for PCD files and bag clouds that carry one, else empty. Not
  /// thread-safe for recordings (one file handle).
  [[nodiscard]] PointCloud read(std::size_t index, CloudReadStats& stats, std::vector<float>* times_s = nullptr) const;
};

/// A KITTI folder or scan files (`spec.kitti` or `spec.files`, one of them), with `spec.poses`
/// overriding the folder's, at most `spec.max_scans`; the up / rotation of the spec not applied.
/// Throws InputError for a pose count that does not match, hmap::Error for no or two inputs.
[[nodiscard]] ScanSource open_scan_files(const ScanSourceSpec& spec);

/// An RGB-D folder (`spec.rgbd`, or `spec.tum` which must be TUM); up / rotation not applied.
[[nodiscard]] ScanSource open_rgbd_source(const ScanSourceSpec& spec);

/// Checks the inputs of `spec` (one of them; no pose file for RGB-D and recordings): hmap::Error
/// naming the options otherwise. Part of open_scan_source.
void check_one_input(const ScanSourceSpec& spec);

/// Turns the poses by T_map_world from `spec.rotation`, `spec.up` (an axis or "floor": the
/// dominant near-horizontal plane of up to 8 frames spread over the run, 20k points each at most);
/// for RGB-D sources "floor" unless given. Adds what it did to `src.description`. hmap::Error for
/// both given, no poses to turn, or no floor found.
void apply_up(ScanSource& src, const ScanSourceSpec& spec);

/// Every source but recordings (open_scan_source adds those): the inputs checked, the source
/// opened and turned by apply_up. A bag throws hmap::Error (hmap::io does not read recordings).
[[nodiscard]] ScanSource open_scan_source_without_recordings(const ScanSourceSpec& spec);

}  // namespace hmap
