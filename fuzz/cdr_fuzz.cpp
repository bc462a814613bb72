// Fuzzes the CDR decoding of ROS 2 messages (src/hmap/ros/cdr.hpp): the same bytes as each message
// type hmap reads, and a decoded PointCloud2's points (decode_pointcloud2). Any bytes give a
// message or one hmap::InputError; no read past the end, no allocation beyond the bytes given,
// and no loop longer than the data (a cloud of 4e9 empty rows).
#include "fuzz_target.hpp"
#include "hmap/ros/bag_reader.hpp"
#include "hmap/ros/cdr.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> msg(data, size);
  const std::string source = "fuzz.mcap";
  const std::string where = "message";
  const auto guarded = [](auto&& f) {
    try {
      f();
    } catch (const hmap::InputError& e) {
      hmap::fuzz::check_message(e);
    }
  };
  guarded([&] {
    const auto raw = hmap::ros::cdr::decode_cloud(msg, source, where);
    hmap::ros::PointCloud2Data cloud;
    cloud.height = raw.height;
    cloud.width = raw.width;
    for (const auto& f : raw.fields) cloud.fields.push_back({f.name, f.offset, f.datatype, f.count});
    cloud.is_bigendian = raw.is_bigendian;
    cloud.point_step = raw.point_step;
    cloud.row_step = raw.row_step;
    cloud.data = raw.data;
    hmap::PointCloud points;
    hmap::CloudReadStats stats;
    std::vector<float> times;
    hmap::ros::decode_pointcloud2(cloud, points, &stats, source, where, &times);
    hmap::fuzz::check_cloud(points, stats);
  });
  guarded([&] {
    std::vector<hmap::ros::access::RawTransform> tf;
    hmap::ros::cdr::decode_tf(msg, false, tf, source, where);
  });
  for (const char* type : {hmap::ros::cdr::kOdometry, hmap::ros::cdr::kPoseStamped, hmap::ros::cdr::kTransformStamped}) {
    guarded([&] { (void)hmap::ros::cdr::decode_pose(msg, type, source, where); });
  }
  guarded([&] { (void)hmap::ros::cdr::decode_imu(msg, source, where); });
  return 0;
}
