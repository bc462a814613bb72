#pragma once
// Recordings: ROS 1 bags (read with Debian's rosbag C++ libraries), MCAP files and rosbag2 folders
// (ROS 2: .db3 or .mcap files with metadata.yaml, read by mcap_reader.hpp and cdr.hpp), one
// interface whatever the kind (told by a folder, or the file's first bytes): sensor_msgs
// PointCloud2 clouds and their poses, from /tf (+ /tf_static) or from a nav_msgs/Odometry (or
// geometry_msgs/PoseStamped) topic. No ROS header leaks from here: users see hmap types only.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "hmap/core/imu.hpp"
#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap::ros {

struct BagTopic {
  std::string name;
  std::string type;           ///< e.g. sensor_msgs/PointCloud2
  std::size_t messages = 0;
};

struct BagInfo {
  std::string format;         ///< "ROS 1 bag", "MCAP", "rosbag2 (sqlite3, 1 file)", ...
  std::uint32_t version = 0;  ///< 200 for ROS 1 bags v2.0, 0 for ROS 2 recordings
  double start_time = 0.0;    ///< [s] first message's record time
  double end_time = 0.0;      ///< [s]
  std::size_t messages = 0;
  std::size_t chunks = 0;
  std::string compression;    ///< none, lz4, bz2 or "mixed"
  std::vector<BagTopic> topics;  ///< sorted by name
  std::vector<std::string> warnings;  ///< e.g. "cut off at byte N; read the M whole messages before it"
  /// A ROS 1 bag without a usable index (cut off, or the index damaged) is read record by record
  /// from its start: then the byte where its readable part ends, else 0.
  std::uint64_t scanned_to = 0;
  std::uint64_t file_size = 0;  ///< [bytes], when scanned
};

/// Lists the topics of a bag (any kind: a ROS 1 bag, an MCAP file, a rosbag2 folder). Throws InputError naming the file for an unreadable or corrupt bag.
[[nodiscard]] BagInfo read_bag_info(const std::filesystem::path& path);

/// sensor_msgs/PointField datatypes.
enum class PointFieldType : std::uint8_t { kInt8 = 1, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

struct PointFieldDesc {
  std::string name;
  std::uint32_t offset = 0;
  std::uint8_t datatype = 7;
  std::uint32_t count = 1;
};

/// A sensor_msgs/PointCloud2 as plain data: the message's layout fields and its data bytes.
struct PointCloud2Data {
  std::uint32_t height = 1;
  std::uint32_t width = 0;
  std::vector<PointFieldDesc> fields;
  bool is_bigendian = false;
  std::uint32_t point_step = 0;
  std::uint32_t row_step = 0;
  std::span<const std::uint8_t> data;
};

/// Decodes the x, y, z fields of any layout (any offsets, any numeric datatype, either byte order,
/// organized or not, row padding allowed) into `points` (cleared first). Non-finite points (NaN
/// marks invalid pixels of organized clouds) are dropped and counted. Throws InputError(source,
/// position, ...) when x, y or z is missing, a field lies outside point_step, row_step < width ·
/// point_step, or the data holds fewer than height · row_step bytes.
/// `times_s` given: filled with each kept point's time [s] from the cloud's stamp when the cloud
/// has a field t, time or timestamp (units as point_times_to_seconds detects them), left empty when
/// it has none; a non-finite time is refused.
void decode_pointcloud2(const PointCloud2Data& cloud, PointCloud& points, CloudReadStats* stats,
                        const std::string& source, const std::string& position, std::vector<float>* times_s = nullptr);

/// The sensor_msgs/Imu topic of a bag: `topic` when given, else the bag's only Imu topic; nullopt
/// when it has none. Throws InputError when it has several and none is named, or the named one is
/// not sensor_msgs/Imu.
[[nodiscard]] std::optional<std::string> bag_imu_topic(const std::filesystem::path& path, const std::string& topic);

/// Every message of a sensor_msgs/Imu topic as samples (orientation kept unless its covariance[0]
/// is −1, REP 145's "no orientation"). Throws InputError naming the bag and the message for a
/// value that is not finite or a stamp not after the previous one.
[[nodiscard]] ImuSamples read_bag_imu(const std::filesystem::path& path, const std::string& topic);

struct BagCloudOptions {
  /// sensor_msgs/PointCloud2 topic; empty: the recording's only PointCloud2 topic (more than one,
  /// or none, is an error naming them)
  std::string cloud_topic;
  /// nav_msgs/Odometry, geometry_msgs/PoseStamped or geometry_msgs/TransformStamped topic. The pose
  /// (parent ← child) is interpolated at the cloud stamp; when the cloud's frame differs from the
  /// child frame and /tf(_static) links them, that transform is appended.
  std::string pose_topic;
  /// Without a pose topic, poses come from /tf and /tf_static: T_map_cloud along the chain of
  /// transforms from `map_frame` (empty = the root of the cloud frame's tree) to `sensor_frame`
  /// (empty = the cloud's header.frame_id), each interpolated at the cloud stamp.
  std::string map_frame;
  std::string sensor_frame;
  /// A stamp up to this far outside a transform's samples takes the nearest one [s]; farther has no pose.
  double max_extrapolation = 0.05;
  std::size_t max_clouds = 0;  ///< 0 = all
};

/// One cloud of the bag, indexed but not decoded.
struct BagCloudFrame {
  double stamp = 0.0;      ///< [s] header.stamp
  std::string frame_id;
  Pose T_map_cloud = Pose::Identity();
};

/// The clouds of one topic with their poses. The constructor reads the poses and every cloud's
/// header; read() decodes one cloud at a time. Throws InputError: for an unreadable bag, a missing
/// or mistyped topic, or a cloud with no pose ("<topic>: no pose at stamp <t> ...").
class BagCloudReader {
 public:
  BagCloudReader(const std::filesystem::path& path, const BagCloudOptions& options);
  ~BagCloudReader();
  BagCloudReader(const BagCloudReader&) = delete;
  BagCloudReader& operator=(const BagCloudReader&) = delete;

  [[nodiscard]] const std::vector<BagCloudFrame>& frames() const;
  /// The points of cloud `index` in its own frame (not thread-safe: the bag is one file handle).
  [[nodiscard]] PointCloud read(std::size_t index, CloudReadStats* stats = nullptr,
                                std::vector<float>* times_s = nullptr) const;
  /// Where the poses came from, for messages ("/tf: map -> os_sensor" or "odometry /odom").
  [[nodiscard]] const std::string& pose_source() const;
  /// The PointCloud2 topic read: the one asked for, or the recording's only one.
  [[nodiscard]] const std::string& cloud_topic() const;
  /// The topic was not asked for: the recording's only PointCloud2 topic was taken.
  [[nodiscard]] bool cloud_topic_chosen() const;
  /// What the reader met and read past (a recording cut off), one line each, for the user.
  [[nodiscard]] const std::vector<std::string>& warnings() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hmap::ros
