#pragma once
// Internal to hmap::ros: the only code that touches ROS types. Debian's ROS 1 message headers
// need C++17 (they use std::allocator<void>::rebind, gone in C++20), so rosbag_access.cpp is
// compiled as C++17 and this header holds nothing but standard C++17 types.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hmap/ros/recording_access.hpp"

namespace hmap::ros::access {

/// A bag open for reading. Every function throws std::exception (rosbag's or std::runtime_error)
/// for anything wrong; the caller turns it into an InputError naming the file.
class BagFile final : public Recording {
 public:
  explicit BagFile(const std::string& path);
  ~BagFile() override;
  BagFile(const BagFile&) = delete;
  BagFile& operator=(const BagFile&) = delete;

  [[nodiscard]] Summary summary() const override;
  /// Indexes the messages of a PointCloud2 topic (at most max, 0 = all) and returns their headers.
  std::vector<CloudHeader> index_clouds(const std::string& topic, std::size_t max) override;
  /// Decodes the k-th indexed cloud.
  [[nodiscard]] RawCloud read_cloud(std::size_t k) const override;
  /// Every transform of /tf and /tf_static (tf2_msgs/TFMessage or tf/tfMessage).
  [[nodiscard]] std::vector<RawTransform> read_tf() const override;
  /// Every message of a sensor_msgs/Imu topic.
  [[nodiscard]] std::vector<RawImu> read_imu(const std::string& topic) const override;
  /// The poses of an Odometry, PoseStamped or TransformStamped topic (child empty for PoseStamped).
  [[nodiscard]] std::vector<RawTransform> read_poses(const std::string& topic) const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hmap::ros::access
