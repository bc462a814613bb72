#include "hmap/ros/cdr.hpp"

#include <bit>
#include <cstring>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap::ros::cdr {

namespace {
constexpr std::size_t kEncapsulation = 4;
}

Reader::Reader(std::span<const std::uint8_t> bytes, const std::string& source, const std::string& position)
    : bytes_(bytes), source_(source), position_(position) {
  if (bytes.size() < kEncapsulation) throw InputError(source, position, "CDR message shorter than its 4-byte header");
  if (bytes[0] != 0 || bytes[1] > 1) {
    throw InputError(source, position, format("unknown CDR encapsulation 0x%02x%02x (hmap reads plain CDR, 0x0000 and 0x0001)",
                                              bytes[0], bytes[1]));
  }
  big_endian_ = bytes[1] == 0;
}

void Reader::need(std::size_t n) const {
  if (n > bytes_.size() - pos_) {
    throw InputError(source_, position_, "CDR message cut off: a field of " + std::to_string(n) + " bytes at byte " +
                                             std::to_string(pos_) + " of " + std::to_string(bytes_.size()));
  }
}

void Reader::align(std::size_t n) {
  // Alignment counts from the end of the encapsulation header.
  const std::size_t rel = pos_ - kEncapsulation;
  const std::size_t pad = (n - rel % n) % n;
  need(pad);
  pos_ += pad;
}

template <typename T>
T Reader::get() {
  align(sizeof(T));
  need(sizeof(T));
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, bytes_.data() + pos_, sizeof(T));
  if (big_endian_ != (std::endian::native == std::endian::big)) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  }
  pos_ += sizeof(T);
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

std::uint8_t Reader::u8() { return get<std::uint8_t>(); }
std::uint32_t Reader::u32() { return get<std::uint32_t>(); }
std::int32_t Reader::i32() { return get<std::int32_t>(); }
double Reader::f64() { return get<double>(); }

std::string Reader::string() {
  const std::uint32_t n = u32();
  need(n);
  std::size_t len = n;
  if (len > 0 && bytes_[pos_ + len - 1] == 0) --len;  // the terminating NUL
  std::string s(reinterpret_cast<const char*>(bytes_.data() + pos_), len);
  pos_ += n;
  return s;
}

std::uint32_t Reader::count(std::size_t min_bytes) {
  const std::uint32_t n = u32();
  if (static_cast<std::uint64_t>(n) * min_bytes > bytes_.size() - pos_) {
    throw InputError(source_, position_, "CDR sequence of " + std::to_string(n) + " elements at byte " + std::to_string(pos_) +
                                             " is longer than the message");
  }
  return n;
}

std::span<const std::uint8_t> Reader::bytes(std::size_t n) {
  need(n);
  auto s = bytes_.subspan(pos_, n);
  pos_ += n;
  return s;
}

namespace {

double stamp(Reader& r) {
  const std::int32_t sec = r.i32();
  const std::uint32_t nsec = r.u32();
  return static_cast<double>(sec) + 1e-9 * static_cast<double>(nsec);
}

access::CloudHeader header(Reader& r) {
  access::CloudHeader h;
  h.stamp = stamp(r);
  h.frame_id = r.string();
  return h;
}

void vector3(Reader& r, double* out) {
  for (int i = 0; i < 3; ++i) out[i] = r.f64();
}

void quaternion(Reader& r, double* out) {
  for (int i = 0; i < 4; ++i) out[i] = r.f64();
}

void skip_doubles(Reader& r, int n) {
  for (int i = 0; i < n; ++i) (void)r.f64();
}

}  // namespace

access::CloudHeader decode_cloud_header(std::span<const std::uint8_t> msg, const std::string& source, const std::string& position) {
  Reader r(msg, source, position);
  return header(r);
}

access::RawCloud decode_cloud(std::span<const std::uint8_t> msg, const std::string& source, const std::string& position) {
  Reader r(msg, source, position);
  (void)header(r);
  access::RawCloud c;
  c.height = r.u32();
  c.width = r.u32();
  // A PointField is at least 4 (name length) + 4 + 1 + 4 bytes.
  const std::uint32_t fields = r.count(13);
  for (std::uint32_t k = 0; k < fields; ++k) {
    access::RawField f;
    f.name = r.string();
    f.offset = r.u32();
    f.datatype = r.u8();
    f.count = r.u32();
    c.fields.push_back(std::move(f));
  }
  c.is_bigendian = r.u8() != 0;
  c.point_step = r.u32();
  c.row_step = r.u32();
  const std::uint32_t n = r.count(1);
  const auto data = r.bytes(n);
  c.data.assign(data.begin(), data.end());
  return c;
}

void decode_tf(std::span<const std::uint8_t> msg, bool is_static, std::vector<access::RawTransform>& out,
               const std::string& source, const std::string& position) {
  Reader r(msg, source, position);
  // A TransformStamped is at least 8 + 4 + 4 + 7 * 8 bytes.
  const std::uint32_t n = r.count(72);
  for (std::uint32_t k = 0; k < n; ++k) {
    access::RawTransform t;
    const access::CloudHeader h = header(r);
    t.stamp = h.stamp;
    t.parent = h.frame_id;
    t.child = r.string();
    vector3(r, t.t);
    quaternion(r, t.q);
    t.is_static = is_static;
    out.push_back(std::move(t));
  }
}

access::RawTransform decode_pose(std::span<const std::uint8_t> msg, const std::string& type, const std::string& source,
                                 const std::string& position) {
  Reader r(msg, source, position);
  access::RawTransform t;
  const access::CloudHeader h = header(r);
  t.stamp = h.stamp;
  t.parent = h.frame_id;
  if (type == kOdometry || type == kTransformStamped) t.child = r.string();
  if (type != kOdometry && type != kPoseStamped && type != kTransformStamped) {
    throw InputError(source, position, "type " + type + " is not a pose (nav_msgs/msg/Odometry, geometry_msgs/msg/PoseStamped "
                                       "or geometry_msgs/msg/TransformStamped)");
  }
  // Pose: position then orientation; Transform: translation then rotation: the same layout.
  vector3(r, t.t);
  quaternion(r, t.q);
  return t;
}

access::RawImu decode_imu(std::span<const std::uint8_t> msg, const std::string& source, const std::string& position) {
  Reader r(msg, source, position);
  access::RawImu imu;
  imu.stamp = header(r).stamp;
  quaternion(r, imu.orientation);
  imu.orientation_covariance0 = r.f64();
  skip_doubles(r, 8);
  vector3(r, imu.gyro);
  skip_doubles(r, 9);
  vector3(r, imu.accel);
  skip_doubles(r, 9);
  return imu;
}

}  // namespace hmap::ros::cdr
