#pragma once
// Internal to hmap::ros: the only code that touches ROS types. Debian's ROS 1 message headers
// need C++17 (they use std::allocator<void>::rebind, gone in C++20), so rosbag_access.cpp is
// compiled as C++17 and this header holds nothing but standard C++17 types.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hmap::ros::access {

struct TopicCount {
  std::string name;
  std::string type;
  std::size_t messages = 0;
};

struct Summary {
  std::uint32_t version = 0;
  double start_time = 0.0;
  double end_time = 0.0;
  std::size_t messages = 0;
  std::vector<TopicCount> topics;
};

/// One transform parent ← child at a stamp (translation, quaternion x y z w).
struct RawTransform {
  std::string parent;
  std::string child;
  double stamp = 0.0;
  double t[3] = {0, 0, 0};
  double q[4] = {0, 0, 0, 1};
  bool is_static = false;
};

struct RawField {
  std::string name;
  std::uint32_t offset = 0;
  std::uint8_t datatype = 0;
  std::uint32_t count = 0;
};

struct RawCloud {
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  std::vector<RawField> fields;
  bool is_bigendian = false;
  std::uint32_t point_step = 0;
  std::uint32_t row_step = 0;
  std::vector<std::uint8_t> data;
};

/// One sensor_msgs/Imu message.
struct RawImu {
  double stamp = 0.0;
  double orientation[4] = {0, 0, 0, 1};  ///< x y z w
  double orientation_covariance0 = 0.0;  ///< −1: no orientation (REP 145)
  double gyro[3] = {0, 0, 0};
  double accel[3] = {0, 0, 0};
};

struct CloudHeader {
  double stamp = 0.0;
  std::string frame_id;
};

/// A bag open for reading. Every function throws std::exception (rosbag's or std::runtime_error)
/// for anything wrong; the caller turns it into an InputError naming the file.
class BagFile {
 public:
  explicit BagFile(const std::string& path);
  ~BagFile();
  BagFile(const BagFile&) = delete;
  BagFile& operator=(const BagFile&) = delete;

  [[nodiscard]] Summary summary() const;
  /// Indexes the messages of a PointCloud2 topic (at most max, 0 = all) and returns their headers.
  std::vector<CloudHeader> index_clouds(const std::string& topic, std::size_t max);
  /// Decodes the k-th indexed cloud.
  [[nodiscard]] RawCloud read_cloud(std::size_t k) const;
  /// Every transform of /tf and /tf_static (tf2_msgs/TFMessage or tf/tfMessage).
  [[nodiscard]] std::vector<RawTransform> read_tf() const;
  /// Every message of a sensor_msgs/Imu topic.
  [[nodiscard]] std::vector<RawImu> read_imu(const std::string& topic) const;
  /// The poses of an Odometry, PoseStamped or TransformStamped topic (child empty for PoseStamped).
  [[nodiscard]] std::vector<RawTransform> read_poses(const std::string& topic) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hmap::ros::access
