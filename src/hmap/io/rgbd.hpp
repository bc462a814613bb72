#pragma once
// RGB-D sequences: depth frames with per-frame camera poses, in the Microsoft 7-Scenes layout
// (frame-N.depth.png + frame-N.pose.txt + camera-intrinsics.txt) or the TUM RGB-D layout
// (depth.txt + depth/*.png + groundtruth.txt, poses associated by timestamp). The camera frame is
// optical (x right, y down, z forward); the data's world frame is whatever the recording used, so
// the map frame is obtained with a gravity rotation T_map_world (see gravity.hpp).

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"
#include "hmap/io/depth_image.hpp"

namespace hmap {

enum class RgbdLayout : std::uint8_t {
  k7Scenes,  ///< frame-NNNNNN.depth.png, frame-NNNNNN.pose.txt (4×4 T_world_cam), camera-intrinsics.txt
  kTum,      ///< depth.txt (t file), groundtruth.txt (t tx ty tz qx qy qz qw), depth in 1/5000 m
};

struct RgbdFrame {
  std::filesystem::path depth_png;
  Pose T_world_cam = Pose::Identity();  ///< optical camera frame → the recording's world frame
  double time = 0.0;                    ///< [s]; the frame number for 7-Scenes
};

struct RgbdSequence {
  std::filesystem::path dir;
  RgbdLayout layout = RgbdLayout::k7Scenes;
  DepthCamera camera;
  std::vector<RgbdFrame> frames;          ///< frames with a pose, in time order
  std::size_t frames_without_pose = 0;    ///< skipped: pose file missing or not finite, or no ground truth near the stamp
};

struct RgbdOptions {
  std::optional<std::filesystem::path> intrinsics;  ///< overrides the folder's (or the layout's default)
  std::optional<double> depth_scale;                ///< [m per unit]; 7-Scenes 0.001, TUM 0.0002
  std::size_t max_frames = 0;                       ///< 0 = all
  /// TUM: a depth stamp is given the pose interpolated between the two ground-truth poses around
  /// it, when they are at most this far apart [s]; otherwise the frame has no pose.
  double max_pose_gap = 0.1;
};

/// Lists an RGB-D folder, telling the layout by its files: depth.txt → TUM; frame-*.depth.png in
/// the folder or in its sub-folders (7-Scenes seq-NN/) → 7-Scenes. Poses are read now; depth
/// images are read one at a time by read_rgbd_frame. Throws InputError for a folder of neither
/// layout, no frame with a pose, or a malformed pose, list or intrinsics file.
[[nodiscard]] RgbdSequence open_rgbd_sequence(const std::filesystem::path& dir, const RgbdOptions& options = {});

/// The points of frame `index` in its optical camera frame (depth_to_points of its image).
[[nodiscard]] PointCloud read_rgbd_frame(const RgbdSequence& sequence, std::size_t index,
                                         CloudReadStats* stats = nullptr);

/// Reads a 7-Scenes pose file: a 4×4 row-major matrix, rows on lines. Returns nullopt when a value
/// is infinite or NaN (7-Scenes marks lost tracking so); throws InputError for a malformed file or
/// a matrix that is not a rigid transform.
[[nodiscard]] std::optional<Pose> read_matrix4_pose(const std::filesystem::path& path);

}  // namespace hmap
