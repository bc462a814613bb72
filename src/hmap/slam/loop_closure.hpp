#pragma once
// Loop closure for the scan-to-map SLAM (docs/SLAM.md, "Loop closure"): the scans are grouped
// into key frames (one every slam.keyframe_distance metres or slam.keyframe_rotation radians),
// each with a sub-map of its first scans in its own level frame; a key frame's place descriptor
// (place_descriptor.hpp) is compared with those of key frames far back along the path and near
// the drifted estimate; the nearest are verified by aligning the two sub-maps (align_maps: the
// scan matcher's IoU with its coarse search) and accepted when the mean M_H reaches
// slam.loop_min_score. At the end a pose graph (pose_graph.hpp) of odometry edges between
// consecutive key frames and the loop edges is optimised, and every scan's pose is corrected by
// its two key frames' corrections, blended along the path.

#include <cstddef>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "hmap/maps/map_rebuild.hpp"
#include "hmap/maps/mapper.hpp"
#include "hmap/slam/place_descriptor.hpp"
#include "hmap/slam/pose_graph.hpp"

namespace hmap::slam {

/// One accepted loop closure, as data.
struct LoopClosure {
  std::size_t keyframe_old = 0;  ///< the key frame revisited
  std::size_t keyframe_new = 0;  ///< the key frame that revisits it
  std::size_t scan_old = 0;      ///< their scans
  std::size_t scan_new = 0;
  double descriptor_distance = 0.0;  ///< [0, 1] of compare_places
  double descriptor_yaw = 0.0;       ///< [rad] its yaw guess
  double score = 0.0;                ///< mean M_H of the verifying alignment
  GraphPose T_old_new;               ///< the new key frame in the old one's frame, from the alignment
  /// [m, rad] how far T_old_new is from what the drifted estimates said (the drift it removes).
  double drift_translation = 0.0;
  double drift_yaw = 0.0;
};

/// What LoopCloser::close did.
struct LoopClosureResult {
  PoseList T_map_sensor;              ///< every scan's pose, corrected (the input when no loop closed)
  std::vector<LoopClosure> closures;
  std::size_t keyframes = 0;
  std::size_t candidates_verified = 0;  ///< alignments run
  PoseGraphResult graph;
  double max_correction = 0.0;        ///< [m] the largest move of a scan's position
  double end_correction = 0.0;        ///< [m] the last scan's
};

/// Collects the SLAM's scans as key frames and closes loops among them. Not thread-safe.
class LoopCloser {
 public:
  /// Throws hmap::Error for invalid parameters (the slam.keyframe_* and slam.loop_* ones).
  explicit LoopCloser(const Params& params);
  ~LoopCloser();
  LoopCloser(LoopCloser&&) noexcept;
  LoopCloser& operator=(LoopCloser&&) noexcept;

  /// The next scan with its estimated pose: starts a key frame when the path has gone far enough,
  /// else adds it to the current key frame's sub-map while it has room. When a key frame's
  /// sub-map is complete, loops are searched for it (LoopCloser::closures grows).
  void add_scan(std::span<const Point3f> points_sensor, const Pose& T_map_sensor);

  /// Searches for the last key frame's loops, optimises the pose graph and corrects every scan's
  /// pose. Call once, after the last scan.
  [[nodiscard]] LoopClosureResult close();

  [[nodiscard]] std::size_t keyframes() const;
  [[nodiscard]] const std::vector<LoopClosure>& closures() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// The map built again from `scans` scans at `T_map_sensor` (the corrected poses): scan(k, out)
/// fills `out` with scan k's points in the sensor frame, passed on to integrated(k, points, pose)
/// when given. The whole map is rebuilt (the HMAP's merging is per column, but extrusion frees
/// space along rays that cross many tiles).
[[nodiscard]] HMap rebuild_map(const Params& params, std::span<const Pose> T_map_sensor,
                               const std::function<void(std::size_t, PointCloud&)>& scan,
                               const RebuiltScan& integrated = {});

/// The map at the loop-corrected poses. When `built` is given, it must be the scans as
/// scan(k, out) reads them integrated at T_built[k], in order (the SLAM's map when no scan was
/// deskewed): only the tiles the moved scans reach are rebuilt (rebuild_moved_tiles, a scan
/// counting as moved when its correction moves a point within map.max_range by more than a tenth
/// of a cell; the others keep their built pose). Without it the whole map is rebuilt at
/// T_corrected (result.whole).
///
/// `centroids`: the SLAM's cell centroids (slam.hvoxel_centroids 2), summed at T_built as
/// HmapSlam sums them. result.centroids then holds them at result.T_map_sensor: each scan read
/// again adds its tall HVoxels' centroids (at least slam.min_match_height; HVoxelised in the level
/// frame of its pose's z, roll and pitch, moved by its x, y and yaw), in the tiles rebuilt (all
/// of them when the whole map is); elsewhere those of `centroids` stay as they were. Without
/// them, or with slam.hvoxel_centroids below 2, result.centroids is empty.
///
/// Throws hmap::Error as rebuild_moved_tiles does, and for centroids of another cell size.
[[nodiscard]] TileRebuild map_at_corrected_poses(const Params& params, const HMap* built, std::span<const Pose> T_built,
                                                 std::span<const Pose> T_corrected,
                                                 const std::function<void(std::size_t, PointCloud&)>& scan,
                                                 const CellCentroids* centroids = nullptr);

}  // namespace hmap::slam
