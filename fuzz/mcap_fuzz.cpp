// Fuzzes the MCAP reader (src/hmap/ros/mcap_reader.hpp) through the recording interface: the topic
// list, then every PointCloud2 topic's clouds with their poses (from /tf or a pose topic), each
// decoded from CDR. Any bytes give clouds or one hmap::InputError, with no huge allocation (every
// length is checked against the bytes before allocating) and no endless loop.
#include "fuzz_target.hpp"
#include "hmap/ros/bag_reader.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  // Inputs that are not MCAP would test the ROS 1 reader (the rosbag target does that).
  if (size < 8 || std::string_view(reinterpret_cast<const char*>(data), 8) != std::string_view("\x89MCAP0\r\n", 8)) return 0;
  hmap::fuzz::read_input(data, size, [](const std::filesystem::path& path) {
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
