#pragma once
// Internal to hmap::ros: ROS 2 recordings as an access::Recording: one MCAP file, or a rosbag2
// folder (metadata.yaml with its .db3 SQLite files or .mcap files), messages decoded from CDR.

#include <filesystem>
#include <memory>

#include "hmap/ros/recording_access.hpp"

namespace hmap::ros::access {

/// Opens `path`: a folder (rosbag2) or an MCAP file. Throws InputError naming the file and what is wrong.
[[nodiscard]] std::unique_ptr<Recording> open_ros2(const std::filesystem::path& path);

/// True when the file starts with the MCAP magic bytes.
[[nodiscard]] bool is_mcap_file(const std::filesystem::path& path);

}  // namespace hmap::ros::access
