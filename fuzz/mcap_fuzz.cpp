// Fuzzes the MCAP reader (src/hmap/ros/mcap_reader.hpp) through the recording interface: the topic
// list, then every PointCloud2 topic's clouds with their poses (from /tf or a pose topic), each
// decoded from CDR. Any bytes give clouds or one hmap::InputError, with no huge allocation (every
// length is checked against the bytes before allocating) and no endless loop.
//
// A mutated file almost never keeps a matching data section CRC, and a file whose CRC matches is
// read differently (a zstd chunk only as far as each message needs, its own CRC not checked
// again): so when the footer points to a summary preceded by a Data End record with a CRC, that
// CRC is set to the bytes' own before reading, and both ways are fuzzed.
#include <zlib.h>

#include <vector>

#include "fuzz_target.hpp"
#include "hmap/ros/bag_reader.hpp"

namespace {

std::uint64_t le64_at(const std::vector<std::uint8_t>& b, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | b[at + static_cast<std::size_t>(i)];
  return v;
}

/// Sets the Data End record's CRC (when it has a nonzero one) to that of the data section.
void match_data_crc(std::vector<std::uint8_t>& b) {
  constexpr std::size_t kFooter = 1 + 8 + 20 + 8;  // opcode, length, summary start/offset/crc, magic
  if (b.size() < 8 + kFooter) return;
  const std::uint64_t summary_start = le64_at(b, b.size() - kFooter + 9);
  if (summary_start < 8 + 13 || summary_start > b.size() - kFooter) return;
  const std::size_t end = static_cast<std::size_t>(summary_start) - 13;
  if (b[end] != 0x0F || le64_at(b, end + 1) != 4) return;
  if ((b[end + 9] | b[end + 10] | b[end + 11] | b[end + 12]) == 0) return;  // no CRC written: leave it so
  const auto crc = static_cast<std::uint32_t>(crc32_z(crc32_z(0L, Z_NULL, 0), b.data(), end));
  for (int i = 0; i < 4; ++i) b[end + 9 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(crc >> (8 * i));
}

}  // namespace

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  // Inputs that are not MCAP would test the ROS 1 reader (the rosbag target does that).
  if (size < 8 || std::string_view(reinterpret_cast<const char*>(data), 8) != std::string_view("\x89MCAP0\r\n", 8)) return 0;
  std::vector<std::uint8_t> bytes(data, data + size);
  match_data_crc(bytes);
  hmap::fuzz::read_input(bytes.data(), bytes.size(), [](const std::filesystem::path& path) {
    const hmap::ros::BagInfo info = hmap::ros::read_bag_info(path);
    std::vector<std::string> pose_topics = {""};  // "" = /tf
    for (const auto& topic : info.topics) {
      if (topic.type == "nav_msgs/msg/Odometry" || topic.type == "geometry_msgs/msg/PoseStamped") pose_topics.push_back(topic.name);
    }
    for (const auto& topic : info.topics) {
      if (topic.type == "sensor_msgs/msg/Imu") {
        try {
          (void)hmap::ros::read_bag_imu(path, topic.name);
        } catch (const hmap::InputError& e) {
          hmap::fuzz::check_message(e);
        }
      }
      if (topic.type != "sensor_msgs/msg/PointCloud2") continue;
      for (const auto& pose_topic : pose_topics) {
        try {
          hmap::ros::BagCloudOptions options;
          options.cloud_topic = topic.name;
          options.pose_topic = pose_topic;
          options.max_clouds = 4;
          const hmap::ros::BagCloudReader reader(path, options);
          for (std::size_t i = 0; i < reader.frames().size(); ++i) {
            hmap::CloudReadStats stats;
            std::vector<float> times;
            const hmap::PointCloud cloud = reader.read(i, &stats, &times);
            hmap::fuzz::check_cloud(cloud, stats);
            if (!times.empty() && times.size() != cloud.size()) hmap::fuzz::fail("a time per point, or none");
          }
        } catch (const hmap::InputError& e) {
          hmap::fuzz::check_message(e);  // one topic's failure; try the others
        }
      }
    }
  });
  return 0;
}
