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

#include <cstring>
#include <map>
#include <stdexcept>

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
    if (m.getDataType() != "sensor_msgs/PointCloud2") {
      throw std::runtime_error("topic " + topic + " holds " + m.getDataType() + ", not sensor_msgs/PointCloud2");
    }
    // Only the std_msgs/Header at the front is decoded here: seq, stamp (sec, nsec), frame_id.
    buffer.resize(m.size());
    ::ros::serialization::OStream out(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
    m.write(out);
    ::ros::serialization::IStream in(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
    std::uint32_t seq = 0;
    ::ros::Time stamp;
    CloudHeader h;
    ::ros::serialization::deserialize(in, seq);
    ::ros::serialization::deserialize(in, stamp);
    ::ros::serialization::deserialize(in, h.frame_id);
    h.stamp = stamp.toSec();
    headers.push_back(std::move(h));
    impl_->clouds.push_back(m);
    if (max > 0 && headers.size() == max) break;
  }
  return headers;
}

RawCloud BagFile::read_cloud(std::size_t k) const {
  // Decoded by hand from the serialized bytes: ROS's own deserializer resizes a vector to the
  // length a (possibly damaged) message claims before checking that the bytes are there.
  const rosbag::MessageInstance& m = impl_->clouds.at(k);
  std::vector<std::uint8_t> bytes(m.size());
  ::ros::serialization::OStream out(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
  m.write(out);
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

std::vector<RawTransform> BagFile::read_tf() const {
  std::vector<RawTransform> out;
  rosbag::View view(impl_->bag, rosbag::TopicQuery(std::vector<std::string>{"/tf", "/tf_static", "tf", "tf_static"}));
  std::vector<std::uint8_t> bytes;
  for (const rosbag::MessageInstance& m : view) {
    // A transform takes at least 76 bytes: a damaged count is refused before ROS resizes to it.
    bytes.resize(m.size());
    ::ros::serialization::OStream raw(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
    m.write(raw);
    std::uint32_t count = 0;
    if (bytes.size() >= 4) std::memcpy(&count, bytes.data(), 4);
    if (bytes.size() < 4 || static_cast<std::uint64_t>(count) * 76 > bytes.size()) {
      throw std::runtime_error("a " + m.getTopic() + " message claims " + std::to_string(count) + " transforms in " +
                               std::to_string(bytes.size()) + " bytes");
    }
    const auto msg = m.instantiate<tf2_msgs::TFMessage>();
    if (!msg) continue;
    const bool is_static = m.getTopic().find("tf_static") != std::string::npos;
    for (const auto& t : msg->transforms) {
      out.push_back(make_transform(t.header.frame_id, t.child_frame_id, t.header.stamp.toSec(), t.transform.translation.x,
                                   t.transform.translation.y, t.transform.translation.z, t.transform.rotation));
      out.back().is_static = is_static;
    }
  }
  return out;
}

std::vector<RawImu> BagFile::read_imu(const std::string& topic) const {
  std::vector<RawImu> out;
  rosbag::View view(impl_->bag, rosbag::TopicQuery(topic));
  for (const rosbag::MessageInstance& m : view) {
    const auto msg = m.instantiate<sensor_msgs::Imu>();
    if (!msg) throw std::runtime_error("IMU topic " + topic + " holds " + m.getDataType() + ", not sensor_msgs/Imu");
    RawImu r;
    r.stamp = msg->header.stamp.toSec();
    r.orientation[0] = msg->orientation.x;
    r.orientation[1] = msg->orientation.y;
    r.orientation[2] = msg->orientation.z;
    r.orientation[3] = msg->orientation.w;
    r.orientation_covariance0 = msg->orientation_covariance[0];
    r.gyro[0] = msg->angular_velocity.x;
    r.gyro[1] = msg->angular_velocity.y;
    r.gyro[2] = msg->angular_velocity.z;
    r.accel[0] = msg->linear_acceleration.x;
    r.accel[1] = msg->linear_acceleration.y;
    r.accel[2] = msg->linear_acceleration.z;
    out.push_back(r);
  }
  return out;
}

std::vector<RawTransform> BagFile::read_poses(const std::string& topic) const {
  std::vector<RawTransform> out;
  rosbag::View view(impl_->bag, rosbag::TopicQuery(topic));
  for (const rosbag::MessageInstance& m : view) {
    if (const auto o = m.instantiate<nav_msgs::Odometry>()) {
      const auto& p = o->pose.pose;
      out.push_back(make_transform(o->header.frame_id, o->child_frame_id, o->header.stamp.toSec(), p.position.x,
                                   p.position.y, p.position.z, p.orientation));
    } else if (const auto s = m.instantiate<geometry_msgs::PoseStamped>()) {
      const auto& p = s->pose;
      out.push_back(make_transform(s->header.frame_id, "", s->header.stamp.toSec(), p.position.x, p.position.y,
                                   p.position.z, p.orientation));
    } else if (const auto t = m.instantiate<geometry_msgs::TransformStamped>()) {
      const auto& tr = t->transform;
      out.push_back(make_transform(t->header.frame_id, t->child_frame_id, t->header.stamp.toSec(), tr.translation.x,
                                   tr.translation.y, tr.translation.z, tr.rotation));
    } else {
      throw std::runtime_error("pose topic " + topic + " holds " + m.getDataType() +
                               ", not nav_msgs/Odometry, geometry_msgs/PoseStamped or TransformStamped");
    }
  }
  return out;
}

}  // namespace hmap::ros::access

namespace hmap::ros::access {

std::unique_ptr<Recording> open_ros1_bag(const std::string& path) { return std::make_unique<BagFile>(path); }

}  // namespace hmap::ros::access
