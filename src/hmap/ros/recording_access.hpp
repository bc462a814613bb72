#pragma once
// Internal to hmap::ros: one recording, whatever its kind (a ROS 1 bag, an MCAP file, a rosbag2
// folder), as the messages bag_reader.cpp needs, in plain C++17 types (rosbag_access.cpp, the
// ROS 1 side, is compiled as C++17: see rosbag_access.hpp).

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
  std::string format;          ///< "ROS 1 bag", "MCAP", "rosbag2 (sqlite3)", ...
  std::uint32_t version = 0;   ///< 200 for ROS 1 bags v2.0, 0 for others
  double start_time = 0.0;
  double end_time = 0.0;
  std::size_t messages = 0;
  std::size_t chunks = 0;
  std::string compression;       ///< empty: the caller finds it (ROS 1)
  std::vector<TopicCount> topics;
  std::vector<std::string> warnings;  ///< e.g. a recording cut off, read up to its last whole message
  bool scanned = false;               ///< read record by record, without an index (a cut-off ROS 1 bag)
  std::uint64_t readable_end = 0;     ///< scanned: [byte] where the readable part ends
  std::uint64_t file_size = 0;        ///< scanned: [bytes]
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

/// A recording open for reading. Every function throws std::exception for anything wrong (our
/// InputError naming the file, or a library's exception that the caller wraps).
class Recording {
 public:
  virtual ~Recording() = default;
  [[nodiscard]] virtual Summary summary() const = 0;
  /// Indexes the messages of a PointCloud2 topic (at most max, 0 = all) and returns their headers.
  virtual std::vector<CloudHeader> index_clouds(const std::string& topic, std::size_t max) = 0;
  /// Decodes the k-th indexed cloud.
  [[nodiscard]] virtual RawCloud read_cloud(std::size_t k) const = 0;
  /// Every transform of /tf and /tf_static.
  [[nodiscard]] virtual std::vector<RawTransform> read_tf() const = 0;
  /// Every message of a sensor_msgs/Imu topic.
  [[nodiscard]] virtual std::vector<RawImu> read_imu(const std::string& topic) const = 0;
  /// The poses of an Odometry, PoseStamped or TransformStamped topic (child empty for PoseStamped).
  [[nodiscard]] virtual std::vector<RawTransform> read_poses(const std::string& topic) const = 0;
};

/// A ROS 1 bag: Debian's rosbag libraries when hmap was built with them, else a refusal saying so.
[[nodiscard]] std::unique_ptr<Recording> open_ros1_bag(const std::string& path);

/// A ROS 1 bag read record by record from its first byte (`bytes`, the whole file), for one that
/// rosbag cannot open by its index (cut off before the index was written, or the index damaged):
/// its messages up to the first record or chunk that is cut off or malformed, with a warning
/// naming `path`, the byte where the readable part ends and the messages read. Throws
/// std::runtime_error when not one whole message is there.
[[nodiscard]] std::unique_ptr<Recording> open_scanned_ros1_bag(const std::string& path, std::string bytes);

}  // namespace hmap::ros::access
