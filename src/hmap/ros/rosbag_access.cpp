// Compiled as C++17 (see rosbag_access.hpp and CMakeLists.txt).
#include "hmap/ros/rosbag_access.hpp"

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <console_bridge/console.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <numeric>
#include <stdexcept>
#include <type_traits>

#include "hmap/ros/rosbag_scan.hpp"

namespace hmap::ros::access {

namespace {

RawTransform make_transform(const std::string& parent, const std::string& child, double stamp, double x, double y,
                            double z, const geometry_msgs::Quaternion& q) {
  RawTransform r;
  r.parent = parent;
  r.child = child;
  r.stamp = stamp;
  r.t[0] = x;
  r.t[1] = y;
  r.t[2] = z;
  r.q[0] = q.x;
  r.q[1] = q.y;
  r.q[2] = q.z;
  r.q[3] = q.w;
  return r;
}

/// One message as its serialized bytes, whichever way the bag was read (by its index through
/// rosbag, or scanned record by record): every message is decoded from these by the code below.
struct Message {
  const std::string& topic;
  const std::string& datatype;
  const std::string& md5sum;
  const std::uint8_t* data;
  std::size_t size;
};

/// ROS's input stream over a message's bytes. An empty message is refused here: its buffer may be
/// a null pointer, and ROS's stream advances the pointer before it checks the length (found by
/// the rosbag fuzzer: a zero-length PointCloud2 record).
::ros::serialization::IStream stream_of(const Message& m) {
  if (m.size == 0 || m.data == nullptr) throw std::runtime_error("a message on topic " + m.topic + " is empty");
  return {const_cast<std::uint8_t*>(m.data), static_cast<std::uint32_t>(m.size)};
}

/// Deserializes with ROS's own code when the message's md5sum is T's (as MessageInstance::instantiate).
template <typename T>
bool deserialize_as(const Message& m, T& msg) {
  if (m.md5sum != ::ros::message_traits::MD5Sum<T>::value()) return false;
  ::ros::serialization::IStream in = stream_of(m);
  ::ros::serialization::deserialize(in, msg);
  return true;
}

/// The std_msgs/Header at the front of a PointCloud2: seq, stamp (sec, nsec), frame_id.
CloudHeader cloud_header(const Message& m) {
  if (m.datatype != "sensor_msgs/PointCloud2") {
    throw std::runtime_error("topic " + m.topic + " holds " + m.datatype + ", not sensor_msgs/PointCloud2");
  }
  ::ros::serialization::IStream in = stream_of(m);
  std::uint32_t seq = 0;
  ::ros::Time stamp;
  CloudHeader h;
  ::ros::serialization::deserialize(in, seq);
  ::ros::serialization::deserialize(in, stamp);
  ::ros::serialization::deserialize(in, h.frame_id);
  h.stamp = stamp.toSec();
  return h;
}

/// A PointCloud2, decoded by hand from its serialized bytes: ROS's own deserializer resizes a
/// vector to the length a (possibly damaged) message claims before checking that the bytes are there.
RawCloud cloud_from_bytes(const std::vector<std::uint8_t>& bytes) {
  std::size_t at = 0;
  const auto need = [&](std::size_t n) {
    if (n > bytes.size() - at) throw std::runtime_error("PointCloud2 message ends at byte " + std::to_string(bytes.size()) +
                                                        " while " + std::to_string(n) + " more bytes were expected");
  };
  const auto u32 = [&] {
    need(4);
    std::uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);  // ROS serialization is little-endian, as this machine
    at += 4;
    return v;
  };
  const auto u8 = [&] {
    need(1);
    return bytes[at++];
  };
  const auto str = [&] {
    const std::uint32_t n = u32();
    need(n);
    std::string v(reinterpret_cast<const char*>(bytes.data() + at), n);
    at += n;
    return v;
  };
  RawCloud c;
  (void)u32();  // header.seq
  (void)u32();  // header.stamp
  (void)u32();
  (void)str();  // header.frame_id
  c.height = u32();
  c.width = u32();
  const std::uint32_t n_fields = u32();
  need(static_cast<std::size_t>(n_fields) * 13);  // name length, offset, datatype, count
  for (std::uint32_t i = 0; i < n_fields; ++i) {
    RawField f;
    f.name = str();
    f.offset = u32();
    f.datatype = u8();
    f.count = u32();
    c.fields.push_back(std::move(f));
  }
  c.is_bigendian = u8() != 0;
  c.point_step = u32();
  c.row_step = u32();
  const std::uint32_t n_data = u32();
  need(n_data);
  c.data.assign(bytes.begin() + static_cast<std::ptrdiff_t>(at), bytes.begin() + static_cast<std::ptrdiff_t>(at + n_data));
  return c;
}

/// The transforms of a tf2_msgs/TFMessage (or tf/tfMessage, the same md5sum).
void append_tf(const Message& m, std::vector<RawTransform>& out) {
  // A transform takes at least 76 bytes: a damaged count is refused before ROS resizes to it.
  std::uint32_t count = 0;
  if (m.size >= 4) std::memcpy(&count, m.data, 4);
  if (m.size < 4 || static_cast<std::uint64_t>(count) * 76 > m.size) {
    throw std::runtime_error("a " + m.topic + " message claims " + std::to_string(count) + " transforms in " +
                             std::to_string(m.size) + " bytes");
  }
  tf2_msgs::TFMessage msg;
  if (!deserialize_as(m, msg)) return;
  const bool is_static = m.topic.find("tf_static") != std::string::npos;
  for (const auto& t : msg.transforms) {
    out.push_back(make_transform(t.header.frame_id, t.child_frame_id, t.header.stamp.toSec(), t.transform.translation.x,
                                 t.transform.translation.y, t.transform.translation.z, t.transform.rotation));
    out.back().is_static = is_static;
  }
}

RawImu imu_from(const Message& m) {
  sensor_msgs::Imu msg;
  if (!deserialize_as(m, msg)) {
    throw std::runtime_error("IMU topic " + m.topic + " holds " + m.datatype + ", not sensor_msgs/Imu");
  }
  RawImu r;
  r.stamp = msg.header.stamp.toSec();
  r.orientation[0] = msg.orientation.x;
  r.orientation[1] = msg.orientation.y;
  r.orientation[2] = msg.orientation.z;
  r.orientation[3] = msg.orientation.w;
  r.orientation_covariance0 = msg.orientation_covariance[0];
  r.gyro[0] = msg.angular_velocity.x;
  r.gyro[1] = msg.angular_velocity.y;
  r.gyro[2] = msg.angular_velocity.z;
  r.accel[0] = msg.linear_acceleration.x;
  r.accel[1] = msg.linear_acceleration.y;
  r.accel[2] = msg.linear_acceleration.z;
  return r;
}

RawTransform pose_from(const Message& m) {
  nav_msgs::Odometry o;
  geometry_msgs::PoseStamped s;
  geometry_msgs::TransformStamped t;
  if (deserialize_as(m, o)) {
    const auto& p = o.pose.pose;
    return make_transform(o.header.frame_id, o.child_frame_id, o.header.stamp.toSec(), p.position.x, p.position.y,
                          p.position.z, p.orientation);
  }
  if (deserialize_as(m, s)) {
    const auto& p = s.pose;
    return make_transform(s.header.frame_id, "", s.header.stamp.toSec(), p.position.x, p.position.y, p.position.z,
                          p.orientation);
  }
  if (deserialize_as(m, t)) {
    const auto& tr = t.transform;
    return make_transform(t.header.frame_id, t.child_frame_id, t.header.stamp.toSec(), tr.translation.x,
                          tr.translation.y, tr.translation.z, tr.rotation);
  }
  throw std::runtime_error("pose topic " + m.topic + " holds " + m.datatype +
                           ", not nav_msgs/Odometry, geometry_msgs/PoseStamped or TransformStamped");
}

/// Calls f(Message) for each message of `view`, in its order (by time).
template <typename F>
void for_each_message(rosbag::View&& view, F&& f) {
  std::vector<std::uint8_t> bytes;
  for (const rosbag::MessageInstance& m : view) {
    bytes.resize(m.size());
    ::ros::serialization::OStream out(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
    m.write(out);
    f(Message{m.getTopic(), m.getDataType(), m.getMD5Sum(), bytes.data(), bytes.size()});
  }
}

}  // namespace

struct BagFile::Impl {
  rosbag::Bag bag;
  std::vector<rosbag::MessageInstance> clouds;  // valid while `bag` is open
};

BagFile::BagFile(const std::string& path) : impl_(std::make_unique<Impl>()) {
  // rosbag logs through console_bridge on stderr before it throws; the exception says it all.
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  impl_->bag.open(path, rosbag::bagmode::Read);
}

BagFile::~BagFile() = default;

Summary BagFile::summary() const {
  Summary s;
  s.format = "ROS 1 bag";
  s.version = impl_->bag.getMajorVersion() * 100U + impl_->bag.getMinorVersion();
  rosbag::View view(impl_->bag);
  std::map<std::string, TopicCount> topics;
  for (const rosbag::ConnectionInfo* c : view.getConnections()) {
    auto& t = topics[c->topic];
    t.name = c->topic;
    t.type = t.type.empty() || t.type == c->datatype ? c->datatype : "mixed";
  }
  for (const rosbag::MessageInstance& m : view) {
    ++topics[m.getTopic()].messages;
    ++s.messages;
  }
  if (s.messages > 0) {
    s.start_time = view.getBeginTime().toSec();
    s.end_time = view.getEndTime().toSec();
  }
  for (auto& entry : topics) s.topics.push_back(entry.second);
  return s;
}

std::vector<CloudHeader> BagFile::index_clouds(const std::string& topic, std::size_t max) {
  rosbag::View view(impl_->bag, rosbag::TopicQuery(topic));
  std::vector<CloudHeader> headers;
  std::vector<std::uint8_t> buffer;
  for (const rosbag::MessageInstance& m : view) {
    buffer.resize(m.size());
    ::ros::serialization::OStream out(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
    m.write(out);
    headers.push_back(cloud_header(Message{m.getTopic(), m.getDataType(), m.getMD5Sum(), buffer.data(), buffer.size()}));
    impl_->clouds.push_back(m);
    if (max > 0 && headers.size() == max) break;
  }
  return headers;
}

RawCloud BagFile::read_cloud(std::size_t k) const {
  const rosbag::MessageInstance& m = impl_->clouds.at(k);
  std::vector<std::uint8_t> bytes(m.size());
  ::ros::serialization::OStream out(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
  m.write(out);
  return cloud_from_bytes(bytes);
}

std::vector<RawTransform> BagFile::read_tf() const {
  std::vector<RawTransform> out;
  for_each_message(rosbag::View(impl_->bag, rosbag::TopicQuery(std::vector<std::string>{"/tf", "/tf_static", "tf", "tf_static"})),
                   [&](const Message& m) { append_tf(m, out); });
  return out;
}

std::vector<RawImu> BagFile::read_imu(const std::string& topic) const {
  std::vector<RawImu> out;
  for_each_message(rosbag::View(impl_->bag, rosbag::TopicQuery(topic)), [&](const Message& m) { out.push_back(imu_from(m)); });
  return out;
}

std::vector<RawTransform> BagFile::read_poses(const std::string& topic) const {
  std::vector<RawTransform> out;
  for_each_message(rosbag::View(impl_->bag, rosbag::TopicQuery(topic)), [&](const Message& m) { out.push_back(pose_from(m)); });
  return out;
}

namespace {

/// A bag read without its index (rosbag_scan.hpp): the same messages, decoded by the same code.
class ScannedBag final : public Recording {
 public:
  ScannedBag(std::string file, BagScan scan, std::string warning)
      : messages_(std::move(file), std::move(scan)), warning_(std::move(warning)) {
    // In time order, as rosbag's View gives them (file order among equal times).
    const auto& all = messages_.scan().messages;
    order_.resize(all.size());
    std::iota(order_.begin(), order_.end(), 0);
    std::stable_sort(order_.begin(), order_.end(), [&](std::size_t a, std::size_t b) { return all[a].time_ns < all[b].time_ns; });
  }

  [[nodiscard]] Summary summary() const override {
    const BagScan& scan = messages_.scan();
    Summary s;
    s.format = "ROS 1 bag";
    s.version = 200;
    std::map<std::string, TopicCount> topics;
    for (const auto& [id, c] : scan.connections) {
      auto& t = topics[c.topic];
      t.name = c.topic;
      t.type = t.type.empty() || t.type == c.type ? c.type : "mixed";
    }
    for (const auto& m : scan.messages) {
      ++topics[scan.connections.at(m.conn).topic].messages;
      ++s.messages;
    }
    if (!order_.empty()) {
      s.start_time = static_cast<double>(scan.messages[order_.front()].time_ns) * 1e-9;
      s.end_time = static_cast<double>(scan.messages[order_.back()].time_ns) * 1e-9;
    }
    for (auto& entry : topics) s.topics.push_back(entry.second);
    s.chunks = scan.chunk_count;
    s.compression = scan.compressions.empty() ? "none" : scan.compressions.size() == 1 ? *scan.compressions.begin() : "mixed";
    s.scanned = true;
    s.readable_end = scan.end;
    s.file_size = scan.file_size;
    s.warnings.push_back(warning_);
    return s;
  }

  std::vector<CloudHeader> index_clouds(const std::string& topic, std::size_t max) override {
    std::vector<CloudHeader> headers;
    for_each({topic}, [&](const Message& m, std::size_t k) {
      headers.push_back(cloud_header(m));
      clouds_.push_back(k);
      return max == 0 || headers.size() < max;
    });
    return headers;
  }

  [[nodiscard]] RawCloud read_cloud(std::size_t k) const override { return cloud_from_bytes(messages_.bytes(clouds_.at(k))); }

  [[nodiscard]] std::vector<RawTransform> read_tf() const override {
    std::vector<RawTransform> out;
    for_each({"/tf", "/tf_static", "tf", "tf_static"}, [&](const Message& m, std::size_t) { append_tf(m, out); });
    return out;
  }

  [[nodiscard]] std::vector<RawImu> read_imu(const std::string& topic) const override {
    std::vector<RawImu> out;
    for_each({topic}, [&](const Message& m, std::size_t) { out.push_back(imu_from(m)); });
    return out;
  }

  [[nodiscard]] std::vector<RawTransform> read_poses(const std::string& topic) const override {
    std::vector<RawTransform> out;
    for_each({topic}, [&](const Message& m, std::size_t) { out.push_back(pose_from(m)); });
    return out;
  }

 private:
  /// Calls f(message, its index in the scan) for the messages of `topics`, in time order, until
  /// f returns false (an f returning void sees them all).
  template <typename F>
  void for_each(const std::vector<std::string>& topics, F&& f) const {
    const BagScan& scan = messages_.scan();
    for (const std::size_t k : order_) {
      const ScannedConnection& c = scan.connections.at(scan.messages[k].conn);
      if (std::find(topics.begin(), topics.end(), c.topic) == topics.end()) continue;
      const std::vector<std::uint8_t> bytes = messages_.bytes(k);
      const Message m{c.topic, c.type, c.md5sum, bytes.data(), bytes.size()};
      if constexpr (std::is_same_v<decltype(f(m, k)), bool>) {
        if (!f(m, k)) return;
      } else {
        f(m, k);
      }
    }
  }

  ScannedMessages messages_;
  std::vector<std::size_t> order_;
  std::vector<std::size_t> clouds_;
  std::string warning_;
};

/// Why the bag had to be read without its index, for the warning.
std::string index_state(const BagScan& scan) {
  if (!scan.has_header) return "its file header record is cut off or damaged";
  if (scan.index_pos == 0) return "it has no index: its recorder was stopped before writing it";
  if (scan.index_pos >= scan.file_size) {
    return "its index, announced at byte " + std::to_string(scan.index_pos) + ", lies past its end";
  }
  if (scan.end < scan.file_size && scan.index_pos <= scan.end) return "its index is cut off";
  return "its index is damaged";
}

}  // namespace

}  // namespace hmap::ros::access

namespace hmap::ros::access {

std::unique_ptr<Recording> open_ros1_bag(const std::string& path) { return std::make_unique<BagFile>(path); }

std::unique_ptr<Recording> open_scanned_ros1_bag(const std::string& path, std::string bytes) {
  BagScan scan = scan_bag(bytes);
  const std::string where = "the readable part ends at byte " + std::to_string(scan.end) + " of " +
                            std::to_string(scan.file_size) + (scan.end < scan.file_size ? " (" + scan.stop + ")" : "");
  if (scan.messages.empty()) {
    throw std::runtime_error("no whole message to read: " + index_state(scan) + ", and " + where);
  }
  std::string warning = path + ": read linearly, without its index (" + index_state(scan) + "): " + where + "; " +
                        std::to_string(scan.messages.size()) +
                        (scan.messages.size() == 1 ? " whole message read" : " whole messages read");
  return std::make_unique<ScannedBag>(std::move(bytes), std::move(scan), std::move(warning));
}

}  // namespace hmap::ros::access
