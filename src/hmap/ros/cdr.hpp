#pragma once
// ROS 2 messages in CDR (XCDR1, OMG DDS-XTypes "plain CDR" as rmw serializes it): a 4-byte
// encapsulation header (0x00 0x00 big endian, 0x00 0x01 little endian, then 2 option bytes), then
// the fields in order, each primitive aligned to its size (8 at most) counted from after the
// header; strings as a u32 length with the terminating NUL; sequences as a u32 count.
// Decodes the message types hmap reads into the plain structs of recording_access.hpp.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "hmap/ros/recording_access.hpp"

namespace hmap::ros::cdr {

/// Reads one CDR message, every read checked against the message's end (InputError(source,
/// position, ...) naming the field's byte).
class Reader {
 public:
  Reader(std::span<const std::uint8_t> bytes, const std::string& source, const std::string& position);

  std::uint8_t u8();
  std::uint32_t u32();
  std::int32_t i32();
  double f64();
  std::string string();
  /// A sequence's element count, checked against the bytes left (each element >= `min_bytes`).
  std::uint32_t count(std::size_t min_bytes);
  std::span<const std::uint8_t> bytes(std::size_t n);
  [[nodiscard]] bool big_endian() const { return big_endian_; }

 private:
  void align(std::size_t n);
  void need(std::size_t n) const;
  template <typename T>
  T get();

  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 4;
  bool big_endian_ = false;
  const std::string& source_;
  const std::string& position_;
};

/// The message types, by their ROS 2 names.
inline constexpr const char* kPointCloud2 = "sensor_msgs/msg/PointCloud2";
inline constexpr const char* kTfMessage = "tf2_msgs/msg/TFMessage";
inline constexpr const char* kOdometry = "nav_msgs/msg/Odometry";
inline constexpr const char* kPoseStamped = "geometry_msgs/msg/PoseStamped";
inline constexpr const char* kTransformStamped = "geometry_msgs/msg/TransformStamped";
inline constexpr const char* kImu = "sensor_msgs/msg/Imu";

/// sensor_msgs/msg/PointCloud2 up to (not including) its fields: header stamp and frame.
[[nodiscard]] access::CloudHeader decode_cloud_header(std::span<const std::uint8_t> msg, const std::string& source,
                                                      const std::string& position);
/// A whole sensor_msgs/msg/PointCloud2 (its data bytes copied).
[[nodiscard]] access::RawCloud decode_cloud(std::span<const std::uint8_t> msg, const std::string& source,
                                            const std::string& position);
/// tf2_msgs/msg/TFMessage: its transforms, appended to `out`.
void decode_tf(std::span<const std::uint8_t> msg, bool is_static, std::vector<access::RawTransform>& out,
               const std::string& source, const std::string& position);
/// nav_msgs/msg/Odometry, geometry_msgs/msg/PoseStamped or geometry_msgs/msg/TransformStamped by `type`.
[[nodiscard]] access::RawTransform decode_pose(std::span<const std::uint8_t> msg, const std::string& type,
                                               const std::string& source, const std::string& position);
/// sensor_msgs/msg/Imu.
[[nodiscard]] access::RawImu decode_imu(std::span<const std::uint8_t> msg, const std::string& source,
                                        const std::string& position);

}  // namespace hmap::ros::cdr
