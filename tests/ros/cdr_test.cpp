// CDR decoding (src/hmap/ros/cdr.hpp) on hand-built messages: both byte orders, alignment counted
// from after the 4-byte encapsulation header, strings with their NUL, bounded sequences.

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <functional>
#include <cstring>

#include "hmap/core/error.hpp"
#include "hmap/ros/bag_reader.hpp"
#include "hmap/ros/cdr.hpp"

namespace hmap {
namespace {

/// Builds a CDR message the way rmw does: header, then fields aligned relative to its end.
class CdrWriter {
 public:
  explicit CdrWriter(bool big_endian) : big_(big_endian) {
    bytes_ = {0, static_cast<std::uint8_t>(big_endian ? 0 : 1), 0, 0};
  }
  template <typename T>
  CdrWriter& put(T v) {
    while ((bytes_.size() - 4) % sizeof(T) != 0) bytes_.push_back(0xEE);  // padding marked, never read
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big_ != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
    bytes_.insert(bytes_.end(), b, b + sizeof(T));
    return *this;
  }
  CdrWriter& str(const std::string& s) {
    put<std::uint32_t>(static_cast<std::uint32_t>(s.size() + 1));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    bytes_.push_back(0);
    return *this;
  }
  CdrWriter& raw(const std::vector<std::uint8_t>& b) {
    bytes_.insert(bytes_.end(), b.begin(), b.end());
    return *this;
  }
  CdrWriter& stamp(std::int32_t sec, std::uint32_t nsec, const std::string& frame) {
    return put(sec).put(nsec).str(frame);
  }
  [[nodiscard]] const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  bool big_;
  std::vector<std::uint8_t> bytes_;
};

const std::string kSource = "test.mcap";
const std::string kWhere = "/cloud";

/// A 2-point cloud, x y z float32 (+ a uint8 field forcing the next u32 to be aligned).
std::vector<std::uint8_t> cloud_message(bool big_endian, bool data_big_endian) {
  CdrWriter w(big_endian);
  w.stamp(100, 500000000, "lidar").put<std::uint32_t>(1).put<std::uint32_t>(2);
  w.put<std::uint32_t>(3);
  for (int a = 0; a < 3; ++a) w.str(std::string(1, static_cast<char>('x' + a))).put<std::uint32_t>(static_cast<std::uint32_t>(4 * a)).put<std::uint8_t>(7).put<std::uint32_t>(1);
  w.put<std::uint8_t>(data_big_endian ? 1 : 0).put<std::uint32_t>(12).put<std::uint32_t>(24);
  std::vector<std::uint8_t> data;
  for (float v : {1.5F, -2.0F, 3.25F, 4.0F, 5.0F, -6.5F}) {
    std::uint8_t b[4];
    std::memcpy(b, &v, 4);
    if (data_big_endian != (std::endian::native == std::endian::big)) std::reverse(b, b + 4);
    data.insert(data.end(), b, b + 4);
  }
  w.put<std::uint32_t>(static_cast<std::uint32_t>(data.size())).raw(data).put<std::uint8_t>(1);
  return w.bytes();
}

TEST(CdrTest, PointCloud2InBothByteOrders) {
  for (const bool big : {false, true}) {
    for (const bool data_big : {false, true}) {
      const auto msg = cloud_message(big, data_big);
      const auto header = ros::cdr::decode_cloud_header(msg, kSource, kWhere);
      EXPECT_DOUBLE_EQ(header.stamp, 100.5);
      EXPECT_EQ(header.frame_id, "lidar");
      const auto cloud = ros::cdr::decode_cloud(msg, kSource, kWhere);
      ASSERT_EQ(cloud.fields.size(), 3U);
      EXPECT_EQ(cloud.fields[2].name, "z");
      EXPECT_EQ(cloud.fields[2].offset, 8U);
      EXPECT_EQ(cloud.width, 2U);
      EXPECT_EQ(cloud.point_step, 12U);
      EXPECT_EQ(cloud.data.size(), 24U);
      ros::PointCloud2Data data;
      data.height = cloud.height;
      data.width = cloud.width;
      for (const auto& f : cloud.fields) data.fields.push_back({f.name, f.offset, f.datatype, f.count});
      data.is_bigendian = cloud.is_bigendian;
      data.point_step = cloud.point_step;
      data.row_step = cloud.row_step;
      data.data = cloud.data;
      PointCloud points;
      ros::decode_pointcloud2(data, points, nullptr, kSource, kWhere);
      ASSERT_EQ(points.size(), 2U) << big << data_big;
      EXPECT_EQ(points[0], Point3f(1.5F, -2.0F, 3.25F));
      EXPECT_EQ(points[1], Point3f(4.0F, 5.0F, -6.5F));
    }
  }
}

TEST(CdrTest, AlignmentCountsFromAfterTheHeader) {
  // Header "a" (stamp 8 bytes, string 4 + 2 = 6 -> offset 14), then a float64 at offset 16 relative
  // to the header's end (20 absolute): a decoder aligning on absolute offsets would read at 16.
  CdrWriter w(false);
  w.stamp(1, 0, "a").put<double>(7.0).put<double>(8.0).put<double>(9.0).put<double>(0.0).put<double>(0.0).put<double>(0.0).put<double>(1.0);
  ASSERT_EQ(w.bytes().size(), 4U + 16U + 7U * 8U);
  const auto pose = ros::cdr::decode_pose(w.bytes(), ros::cdr::kPoseStamped, kSource, kWhere);
  EXPECT_EQ(pose.parent, "a");
  EXPECT_DOUBLE_EQ(pose.t[0], 7.0);
  EXPECT_DOUBLE_EQ(pose.t[2], 9.0);
  EXPECT_DOUBLE_EQ(pose.q[3], 1.0);
}

TEST(CdrTest, TfMessageBigEndian) {
  CdrWriter w(true);
  w.put<std::uint32_t>(2);
  for (int k = 0; k < 2; ++k) {
    w.stamp(10 + k, 0, "odom").str("base" + std::to_string(k));
    for (double v : {1.0 * k, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0}) w.put<double>(v);
  }
  std::vector<ros::access::RawTransform> out;
  ros::cdr::decode_tf(w.bytes(), true, out, kSource, kWhere);
  ASSERT_EQ(out.size(), 2U);
  EXPECT_EQ(out[1].child, "base1");
  EXPECT_DOUBLE_EQ(out[1].stamp, 11.0);
  EXPECT_DOUBLE_EQ(out[1].t[0], 1.0);
  EXPECT_TRUE(out[1].is_static);
}

TEST(CdrTest, ImuFieldsInOrder) {
  CdrWriter w(false);
  w.stamp(5, 250000000, "imu");
  for (double v : {0.0, 0.0, 0.0, 1.0}) w.put<double>(v);
  for (int i = 0; i < 9; ++i) w.put<double>(i == 0 ? -1.0 : 0.0);
  for (double v : {0.1, 0.2, 0.3}) w.put<double>(v);
  for (int i = 0; i < 9; ++i) w.put<double>(0.0);
  for (double v : {1.0, 2.0, 9.81}) w.put<double>(v);
  for (int i = 0; i < 9; ++i) w.put<double>(0.0);
  const auto imu = ros::cdr::decode_imu(w.bytes(), kSource, kWhere);
  EXPECT_DOUBLE_EQ(imu.stamp, 5.25);
  EXPECT_DOUBLE_EQ(imu.orientation_covariance0, -1.0);
  EXPECT_DOUBLE_EQ(imu.gyro[2], 0.3);
  EXPECT_DOUBLE_EQ(imu.accel[2], 9.81);
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no InputError>";
}

TEST(CdrTest, DamagedMessagesAreInputErrors) {
  const auto msg = cloud_message(false, false);
  // Every prefix is refused (never read past the end).
  for (std::size_t n = 0; n < msg.size() - 1; ++n) {
    const std::vector<std::uint8_t> cut(msg.begin(), msg.begin() + static_cast<std::ptrdiff_t>(n));
    EXPECT_NE(error_of([&] { (void)ros::cdr::decode_cloud(cut, kSource, kWhere); }), "<no InputError>") << n;
  }
  // Unknown encapsulation (0x0003: parameter-list CDR).
  auto pl = msg;
  pl[1] = 3;
  EXPECT_NE(error_of([&] { (void)ros::cdr::decode_cloud(pl, kSource, kWhere); }).find("test.mcap: /cloud: unknown CDR encapsulation 0x0003"),
            std::string::npos);
  // A sequence claiming 4e9 fields: refused before any allocation.
  CdrWriter w(false);
  w.stamp(0, 0, "f").put<std::uint32_t>(1).put<std::uint32_t>(1).put<std::uint32_t>(4000000000U);
  EXPECT_NE(error_of([&] { (void)ros::cdr::decode_cloud(w.bytes(), kSource, kWhere); }).find("CDR sequence of 4000000000 elements"),
            std::string::npos);
}

TEST(CdrTest, BillionsOfEmptyRowsEndAtOnce) {
  // height 4e9 with width 0 (or row_step 0): no point, and no loop over the rows.
  ros::PointCloud2Data data;
  data.height = 4000000000U;
  data.width = 0;
  data.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}};
  data.point_step = 12;
  data.row_step = 0;
  PointCloud points;
  CloudReadStats stats;
  ros::decode_pointcloud2(data, points, &stats, kSource, kWhere);
  EXPECT_TRUE(points.empty());
  EXPECT_EQ(stats.points_read, 0U);
  // With points, the rows must fit the data: refused, not looped over.
  data.width = 1;
  data.row_step = 12;
  EXPECT_NE(error_of([&] { ros::decode_pointcloud2(data, points, nullptr, kSource, kWhere); }).find("data holds 0 bytes"),
            std::string::npos);
}

}  // namespace
}  // namespace hmap
