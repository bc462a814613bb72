#pragma once
// A recording's clouds (ROS 1 bag, MCAP file, rosbag2 folder) as a ScanSource: the cloud topic's
// messages with their poses from /tf or an odometry topic, read one at a time. Reached through
// open_scan_source (hmap/sources/open_scan_source.hpp) for `--bag` and hmap.io.bag_sequence.

#include "hmap/io/scan_source.hpp"

namespace hmap::ros {

/// `spec.bag` with `spec.cloud_topic`, `pose_topic` or `tf_frames` (MAP [SENSOR]), at most
/// `spec.max_scans` clouds; the reader's warnings go to `spec.warn`. Up / rotation not applied.
/// Throws hmap::Error for both a pose topic and /tf frames, InputError for a recording it
/// cannot read, a topic it does not hold or clouds without poses.
[[nodiscard]] ScanSource open_bag_source(const ScanSourceSpec& spec);

}  // namespace hmap::ros
