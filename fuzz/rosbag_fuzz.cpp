// Fuzzes the ROS 1 bag reader (src/hmap/ros/bag_reader.hpp): the topic list, then every
// PointCloud2 topic's clouds with their poses (from /tf or from an odometry topic), each decoded.
// Any bytes give clouds or one hmap::InputError; nothing of rosbag's own may escape.
#include "fuzz_target.hpp"
#include "hmap/ros/bag_reader.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  hmap::fuzz::read_input(data, size, [](const std::filesystem::path& path) {
    const hmap::ros::BagInfo info = hmap::ros::read_bag_info(path);
    std::vector<std::string> pose_topics = {""};  // "" = /tf
    for (const auto& topic : info.topics) {
      if (topic.type == "nav_msgs/Odometry" || topic.type == "geometry_msgs/PoseStamped" ||
          topic.type == "geometry_msgs/TransformStamped") {
        pose_topics.push_back(topic.name);
      }
    }
    for (const auto& topic : info.topics) {
      if (topic.type != "sensor_msgs/PointCloud2") continue;
      for (const auto& pose_topic : pose_topics) {
        try {
          hmap::ros::BagCloudOptions options;
          options.cloud_topic = topic.name;
          options.pose_topic = pose_topic;
          options.max_clouds = 4;
          const hmap::ros::BagCloudReader reader(path, options);
          for (std::size_t i = 0; i < reader.frames().size(); ++i) {
            hmap::CloudReadStats stats;
            const hmap::PointCloud cloud = reader.read(i, &stats);
            hmap::fuzz::check_cloud(cloud, stats);
          }
        } catch (const hmap::InputError& e) {
          hmap::fuzz::check_message(e);  // one topic's failure; try the others
        }
      }
    }
  });
  return 0;
}
