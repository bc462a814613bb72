#pragma once
// Writing simulated sequences in the KITTI odometry layout, so that everything that reads real
// KITTI data (open_kitti_sequence, read_kitti_bin) reads them too.

#include <filesystem>
#include <span>
#include <vector>

#include "hmap/core/types.hpp"

namespace hmap {

/// Writes `cloud` as little-endian float32 quadruples x, y, z, intensity (intensity 0), replacing
/// `path` atomically. Throws hmap::Error when the file cannot be written.
void write_kitti_bin(const std::filesystem::path& path, const PointCloud& cloud);

/// Writes `cloud` with each point's time [s] as a binary PCD (v0.7) with float fields x y z t,
/// replacing `path` atomically: the field read_pcd takes as per-point time (t in seconds from the
/// sweep's start, as a Velodyne driver's `time`). Throws hmap::Error when the counts differ, a time
/// is not finite, or the file cannot be written.
void write_pcd_with_time(const std::filesystem::path& path, const PointCloud& cloud, std::span<const float> times_s);

/// Writes a sequence folder:
///   dir/velodyne/NNNNNN.bin  one scan per frame (sensor frame), numbered from 000000; with
///                            `point_times` (one list per frame, one time per point) NNNNNN.pcd
///                            with the field t instead (write_pcd_with_time)
///   dir/poses.txt            true T_world_sensor per frame, KITTI format (no calib.txt: the poses
///                            are scanner poses as they are)
///   dir/times.txt            one time [s] per frame
///   dir/odometry.txt         odometry poses, KITTI format; skipped when `odometry_poses` is empty
///   dir/truth.ply            the dense true surface points; skipped when `truth_points` is empty
/// Creates `dir` and dir/velodyne. Throws hmap::Error when the counts of frames, poses, times,
/// (non-empty) odometry and (non-empty) point times differ, or a file cannot be written.
void write_simulated_sequence(const std::filesystem::path& dir, std::span<const PointCloud> frames,
                              const PoseList& true_poses, std::span<const double> times,
                              const PoseList& odometry_poses, const PointCloud& truth_points,
                              std::span<const std::vector<float>> point_times = {});

/// Writes frame `index` of a sequence folder as write_simulated_sequence does:
/// dir/velodyne/NNNNNN.bin; dir/velodyne must exist. For writing a long recording frame by frame
/// as it is made.
void write_simulated_frame(const std::filesystem::path& dir, std::size_t index, const PointCloud& frame);
/// The same with a time per point: dir/velodyne/NNNNNN.pcd (write_pcd_with_time).
void write_simulated_frame(const std::filesystem::path& dir, std::size_t index, const PointCloud& frame,
                           std::span<const float> point_times);

/// The rest of write_simulated_sequence after its frames: poses.txt, times.txt, odometry.txt (when
/// `odometry_poses` is not empty) and truth.ply (when `truth_points` is not empty). Throws
/// hmap::Error when the counts of poses, times and (non-empty) odometry differ.
void write_simulated_records(const std::filesystem::path& dir, const PoseList& true_poses, std::span<const double> times,
                             const PoseList& odometry_poses, const PointCloud& truth_points);

}  // namespace hmap
