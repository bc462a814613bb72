#pragma once
// KITTI odometry layout: velodyne/NNNNNN.bin scans, poses.txt, calib.txt, times.txt.

#include <cstddef>
#include <filesystem>
#include <optional>
#include <vector>

#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap {

/// Reads a KITTI Velodyne scan: little-endian float32 quadruples x, y, z, intensity [m, m, m, -];
/// intensity is dropped. Non-finite points are dropped and counted in `stats`. Throws InputError
/// when the file size is not a multiple of 16 bytes.
[[nodiscard]] PointCloud read_kitti_bin(const std::filesystem::path& path, CloudReadStats* stats = nullptr);

/// A times.txt: one timestamp [s] per line ('#' comments and blank lines skipped). Throws
/// InputError naming the line of anything else.
[[nodiscard]] std::vector<double> read_kitti_times(const std::filesystem::path& path);

/// A KITTI sequence folder, listed but not yet read: scans are read one at a time with
/// read_kitti_bin(sequence.scan_paths[i]) (read_cloud for the .pcd of hmap simulate --sweep).
struct KittiSequence {
  std::filesystem::path dir;
  std::vector<std::filesystem::path> scan_paths;  ///< dir/velodyne/*.bin (else *.pcd: scans with per-point time), sorted by name
  /// One pose per scan, from dir/poses.txt. With calib.txt's Tr, KITTI's camera-frame poses P are
  /// turned into scanner poses, T_map_scan = Tr⁻¹ · P · Tr, so that the map frame is the first
  /// scan's frame (z up); without Tr the poses are taken to be T_map_scan as they are.
  std::optional<PoseList> T_map_scan;
  std::optional<Pose> T_cam_velo;  ///< Tr of dir/calib.txt
  std::vector<double> times;       ///< [s] from dir/times.txt; empty when absent
};

struct KittiSequenceOptions {
  /// Use only the first N scans; poses.txt and times.txt may then hold more lines than scans used
  /// (the rest are ignored), never fewer. Without it, their counts must equal the scan count.
  std::optional<std::size_t> max_scans;
};

/// Lists the scans of `dir` and reads its poses, calibration and times, then checks the counts
/// with check_kitti_sequence. Throws InputError when `dir/velodyne` is missing or empty, or a
/// file is malformed or has the wrong number of lines.
[[nodiscard]] KittiSequence open_kitti_sequence(const std::filesystem::path& dir,
                                                const KittiSequenceOptions& options = {});

/// Throws InputError naming poses.txt (or times.txt) and both counts when the sequence does not
/// hold exactly one pose (time) per scan.
void check_kitti_sequence(const KittiSequence& sequence);

}  // namespace hmap
