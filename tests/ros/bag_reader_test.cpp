// hmap::ros on bags written by ROS's own writer (Debian python3-rosbag, tests/ros/make_test_bags.py)
// from the real Ouster scans of ../shared/data/balm_os0; PointCloud2 layouts decoded by hand.

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

#include "common/bag_layout.hpp"
#include "common/test_data.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/ros/bag_reader.hpp"

namespace hmap {
namespace {

namespace fs = std::filesystem;
constexpr int kScans = 3;
constexpr std::size_t kStep = 10;

class BagReaderTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(test::data_dir() / "balm_os0")) return;
    dir_ = test::temp_dir("bags");
    const fs::path script = test::make_test_bags_script();
    // Debian's python (not a virtual env's) has the rosbag module.
    const std::string cmd = "/usr/bin/python3 " + script.string() + " " + test::data_dir().string() + " " + dir_.string() +
                            " " + std::to_string(kScans) + " " + std::to_string(kStep) + " 2>&1";
    made_ = std::system(cmd.c_str()) == 0;
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    if (!dir_.empty()) fs::remove_all(dir_, ec);
  }
  void SetUp() override {
#if !HMAP_ROS1
    GTEST_SKIP() << "hmap was built without ROS 1 bag support (Debian's librosbag-dev and message headers)";
#endif
    HMAP_REQUIRE_DATA("balm_os0");
    if (!made_) GTEST_SKIP() << "make_test_bags.py failed: is python3-rosbag (and python3-tf2-msgs) installed?";
  }
  static PointCloud expected_scan(int k) {
    CloudReadStats stats;
    char name[32];
    std::snprintf(name, sizeof name, "%06d.bin", k);
    const PointCloud all = read_kitti_bin(test::data_dir() / "balm_os0" / "velodyne" / name, &stats);
    EXPECT_EQ(stats.non_finite_dropped, 0U);
    PointCloud some;
    for (std::size_t i = 0; i < all.size(); i += kStep) some.push_back(all[i]);
    return some;
  }
  static std::string error_of(const std::function<void()>& f) {
    try {
      f();
    } catch (const InputError& e) {
      return e.what();
    } catch (const std::exception& e) {
      return std::string("<not an InputError: ") + e.what() + ">";
    }
    return "<no exception>";
  }
  /// The bytes of the small bag the suite writes.
  static std::string tiny_bag() {
    std::ifstream in(dir_ / "tiny.bag", std::ios::binary);
    std::stringstream buffer;
    buffer << in.rdbuf();
    return buffer.str();
  }
  static inline fs::path dir_;
  static inline bool made_ = false;
};

/// Translation error [m], plus the rotation-matrix error scaled down: poses.txt's 9-digit matrices
/// are orthonormal only to ~1e-3 and the bag writer's quaternion comes from the raw matrix, while
/// read_poses orthonormalizes it.
double max_pose_error(const Pose& a, const Pose& b) {
  return std::max((a.translation() - b.translation()).cwiseAbs().maxCoeff(),
                  1e-3 * (a.linear() - b.linear()).cwiseAbs().maxCoeff());
}

TEST_F(BagReaderTest, InfoListsTopicsAndCompression) {
  for (const auto& [name, compression] : {std::pair{"tf.bag", "none"}, {"tf_lz4.bag", "lz4"}, {"tf_bz2.bag", "bz2"}}) {
    const ros::BagInfo info = ros::read_bag_info(dir_ / name);
    EXPECT_EQ(info.version, 200U);
    EXPECT_EQ(info.compression, compression) << name;
    EXPECT_EQ(info.messages, static_cast<std::size_t>(kScans * 3 + 1));
    ASSERT_EQ(info.topics.size(), 3U);
    EXPECT_EQ(info.topics[0].name, "/os_cloud");
    EXPECT_EQ(info.topics[0].type, "sensor_msgs/PointCloud2");
    EXPECT_EQ(info.topics[0].messages, static_cast<std::size_t>(kScans));
    EXPECT_EQ(info.topics[1].name, "/tf");
  }
}

TEST_F(BagReaderTest, TfChainInterpolatedAndEveryCompression) {
  const PoseList truth = read_poses(test::data_dir() / "balm_os0" / "poses.txt");
  Pose T_map_odom = Pose::Identity();
  T_map_odom.translation() = Eigen::Vector3d(1, 2, 0);
  for (const char* name : {"tf.bag", "tf_lz4.bag", "tf_bz2.bag"}) {
    ros::BagCloudOptions options;
    options.cloud_topic = "/os_cloud";
    const ros::BagCloudReader reader(dir_ / name, options);
    ASSERT_EQ(reader.frames().size(), static_cast<std::size_t>(kScans));
    for (int k = 0; k < kScans; ++k) {
      const auto& frame = reader.frames()[static_cast<std::size_t>(k)];
      EXPECT_EQ(frame.frame_id, "os_sensor");
      // /tf samples at t -+ 0.1 s straddle the true pose: interpolation gives it back.
      EXPECT_LT(max_pose_error(frame.T_map_cloud, T_map_odom * truth[static_cast<std::size_t>(k)]), 1e-5) << name << " " << k;
      CloudReadStats stats;
      const PointCloud points = reader.read(static_cast<std::size_t>(k), &stats);
      EXPECT_EQ(points, expected_scan(k)) << name;
      EXPECT_EQ(stats.non_finite_dropped, 0U);
    }
  }
  // --tf-frames odom: the chain stops at odom.
  ros::BagCloudOptions options;
  options.cloud_topic = "/os_cloud";
  options.map_frame = "odom";
  const ros::BagCloudReader reader(dir_ / "tf.bag", options);
  EXPECT_LT(max_pose_error(reader.frames()[1].T_map_cloud, truth[1]), 1e-5);
  options.map_frame = "nowhere";
  EXPECT_NE(error_of([&] { ros::BagCloudReader bad(dir_ / "tf.bag", options); }).find("not connected"), std::string::npos);
}

TEST_F(BagReaderTest, OdometryTopicGivesPoses) {
  const PoseList truth = read_poses(test::data_dir() / "balm_os0" / "poses.txt");
  ros::BagCloudOptions options;
  options.cloud_topic = "/os_cloud";
  options.pose_topic = "/odom";
  const ros::BagCloudReader reader(dir_ / "odom.bag", options);
  ASSERT_EQ(reader.frames().size(), static_cast<std::size_t>(kScans));
  for (int k = 0; k < kScans; ++k) {
    EXPECT_LT(max_pose_error(reader.frames()[static_cast<std::size_t>(k)].T_map_cloud, truth[static_cast<std::size_t>(k)]), 1e-6);
  }
  EXPECT_EQ(reader.read(2), expected_scan(2));
}

TEST_F(BagReaderTest, BigEndianOddLayoutAndOrganizedNanCloud) {
  ros::BagCloudOptions options;
  options.cloud_topic = "/cloud";
  options.pose_topic = "/odom";
  const ros::BagCloudReader reader(dir_ / "layout.bag", options);
  ASSERT_EQ(reader.frames().size(), 2U);
  EXPECT_EQ(reader.read(0), expected_scan(0));  // big-endian, z first, x as float64
  const PointCloud scan1 = expected_scan(1);
  CloudReadStats stats;
  const PointCloud organized = reader.read(1, &stats);
  const std::size_t used = scan1.size() / 4 * 4;  // 4 rows of equal width
  EXPECT_EQ(stats.points_read, used);
  EXPECT_EQ(stats.non_finite_dropped, (used + 6) / 7);
  PointCloud expected;
  for (std::size_t i = 0; i < used; ++i) {
    if (i % 7 != 0) expected.push_back(scan1[i]);
  }
  EXPECT_EQ(organized, expected);
}

TEST_F(BagReaderTest, CloudWithoutPoseIsOneLineNamingTopicAndStamp) {
  ros::BagCloudOptions options;
  options.cloud_topic = "/os_cloud";
  options.pose_topic = "/odom";
  const std::string e = error_of([&] { ros::BagCloudReader r(dir_ / "nopose.bag", options); });
  EXPECT_NE(e.find("nopose.bag: /os_cloud at stamp 1630577758.569490: no pose"), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);
  options.cloud_topic = "/nothing";
  EXPECT_NE(error_of([&] { ros::BagCloudReader r(dir_ / "odom.bag", options); }).find("topic /nothing has no messages"),
            std::string::npos);
  options.cloud_topic = "/odom";
  EXPECT_NE(error_of([&] { ros::BagCloudReader r(dir_ / "odom.bag", options); }).find("not sensor_msgs/PointCloud2"),
            std::string::npos);
}

TEST_F(BagReaderTest, DamagedBagsGiveInputErrors) {
  const std::string bytes = tiny_bag();
  const fs::path path = dir_ / "damaged.bag";
  const auto try_read = [&](const std::string& content, const std::string& what) {
    std::ofstream(path, std::ios::binary).write(content.data(), static_cast<std::streamsize>(content.size()));
    try {
      ros::BagCloudOptions options;
      options.cloud_topic = "/os_cloud";
      options.pose_topic = "/odom";
      const ros::BagCloudReader reader(path, options);
      for (std::size_t k = 0; k < reader.frames().size(); ++k) (void)reader.read(k);
      (void)ros::read_bag_info(path);
    } catch (const InputError&) {
    } catch (const std::exception& e) {
      ADD_FAILURE() << what << ": " << e.what();
    }
  };
  // Every prefix (every 7th length: the bag is mostly message definitions) and seeded damage.
  for (std::size_t length = 0; length < bytes.size(); length += 7) try_read(bytes.substr(0, length), "prefix " + std::to_string(length));
  std::mt19937 rng(99);
  std::uniform_int_distribution<std::size_t> position(0, bytes.size() - 1);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int trial = 0; trial < 200; ++trial) {
    std::string damaged = bytes;
    for (int k = 0; k < 1 + trial % 4; ++k) damaged[position(rng)] = static_cast<char>(byte(rng));
    try_read(damaged, "damage trial " + std::to_string(trial));
  }
}

TEST_F(BagReaderTest, ACutOffBagIsReadUpToItsLastWholeMessage) {
  // A bag cut at chosen bytes (inside the file header, inside a chunk's header, inside its data,
  // between chunks, inside the index) reads without its index: exactly the messages whole before
  // the cut (rosbag's index of the whole bag says where each one ends), one warning naming the
  // bag and the byte where the readable part ends, and every whole cloud as in the scan files,
  // with its pose. A cut before the first whole message is one InputError line.
  const PoseList truth = read_poses(test::data_dir() / "balm_os0" / "poses.txt");
  const fs::path path = dir_ / "cut.bag";
  for (const char* name : {"chunked.bag", "chunked_bz2.bag", "chunked_lz4.bag"}) {
    const test::BagLayout layout = test::BagLayout::of(dir_ / name);
    ASSERT_EQ(layout.messages.size(), static_cast<std::size_t>(4 * kScans)) << name;
    ASSERT_GE(layout.chunks.size(), static_cast<std::size_t>(kScans)) << name;
    const std::string bytes = test::read_bytes(dir_ / name);
    ASSERT_EQ(bytes.size(), layout.size);
    struct Cut {
      std::uint64_t at;
      std::uint64_t readable_end;  ///< 0: not known beforehand
    };
    std::vector<Cut> cuts = {{100, 0}, {layout.chunks[0].pos + 20, 0}};
    for (const auto& c : layout.chunks) {
      cuts.push_back({(c.pos + c.end) / 2, 0});  // inside its data
      cuts.push_back({c.end, c.end});           // between chunks: right after its data
      cuts.push_back({c.end + 3, c.end});       // inside the record after it
    }
    cuts.push_back({layout.size - 1, 0});  // inside the last record of the index
    int read_some = 0;
    int refused = 0;
    for (const Cut& cut : cuts) {
      SCOPED_TRACE(std::string(name) + " cut at byte " + std::to_string(cut.at));
      test::write_bytes(path, bytes.substr(0, cut.at));
      const std::size_t expected = layout.whole_before(cut.at);
      if (expected == 0) {
        const std::string e = error_of([&] { (void)ros::read_bag_info(path); });
        EXPECT_NE(e.find(path.string() + ": unreadable bag: no whole message"), std::string::npos) << e;
        EXPECT_EQ(e.find('\n'), std::string::npos) << e;
        ++refused;
        continue;
      }
      ++read_some;
      const ros::BagInfo info = ros::read_bag_info(path);
      EXPECT_EQ(info.messages, expected);
      for (const auto& topic : info.topics) EXPECT_EQ(topic.messages, layout.whole_before(cut.at, topic.name)) << topic.name;
      EXPECT_GE(info.scanned_to, layout.last_whole_at(cut.at));
      EXPECT_LE(info.scanned_to, cut.at);
      if (cut.readable_end != 0) {
        EXPECT_EQ(info.scanned_to, cut.readable_end);
      }
      EXPECT_EQ(info.file_size, cut.at);
      ASSERT_EQ(info.warnings.size(), 1U);
      const std::string& w = info.warnings[0];
      EXPECT_NE(w.find(path.string() + ": read linearly"), std::string::npos) << w;
      EXPECT_NE(w.find("ends at byte " + std::to_string(info.scanned_to) + " of " + std::to_string(cut.at)), std::string::npos) << w;
      EXPECT_NE(w.find("; " + std::to_string(expected) + (expected == 1 ? " whole message read" : " whole messages read")),
                std::string::npos) << w;
      EXPECT_EQ(w.find('\n'), std::string::npos);

      const std::size_t clouds = layout.whole_before(cut.at, "/os_cloud");
      if (clouds == 0) continue;
      ros::BagCloudOptions options;
      options.cloud_topic = "/os_cloud";
      options.pose_topic = "/odom";
      const ros::BagCloudReader reader(path, options);
      ASSERT_EQ(reader.frames().size(), clouds);
      ASSERT_EQ(reader.warnings().size(), 1U);
      EXPECT_EQ(reader.warnings()[0], w);
      for (std::size_t k = 0; k < clouds; ++k) {
        EXPECT_LT(max_pose_error(reader.frames()[k].T_map_cloud, truth[k]), 1e-6) << k;
        EXPECT_EQ(reader.read(k), expected_scan(static_cast<int>(k))) << k;
      }
    }
    EXPECT_GE(read_some, 3 * kScans) << name;  // the cuts reach past every chunk
    EXPECT_GE(refused, 2) << name;
  }
}

TEST_F(BagReaderTest, AKilledRecordingIsReadWithoutItsIndex) {
  // The writer killed (no close, no index) after its second scan: the messages of its closed
  // chunks, and of the open one when it is stored uncompressed, as the writer counted them.
  for (const char* name : {"killed.bag", "killed_lz4.bag"}) {
    SCOPED_TRACE(name);
    const std::size_t expected = std::stoul(test::read_bytes(dir_ / (std::string(name) + ".expected")));
    const ros::BagInfo info = ros::read_bag_info(dir_ / name);
    EXPECT_EQ(info.messages, expected);
    ASSERT_EQ(info.warnings.size(), 1U);
    EXPECT_NE(info.warnings[0].find("it has no index: its recorder was stopped before writing it"), std::string::npos)
        << info.warnings[0];
    ros::BagCloudOptions options;
    options.cloud_topic = "/os_cloud";
    options.pose_topic = "/odom";  // lz4: the /tf after the last cloud was in the open chunk, lost
    const ros::BagCloudReader reader(dir_ / name, options);
    ASSERT_EQ(reader.frames().size(), 2U);
    EXPECT_EQ(reader.read(1), expected_scan(1));
  }
  EXPECT_EQ(ros::read_bag_info(dir_ / "killed.bag").scanned_to, fs::file_size(dir_ / "killed.bag"));
  EXPECT_LT(ros::read_bag_info(dir_ / "killed_lz4.bag").scanned_to, fs::file_size(dir_ / "killed_lz4.bag"));
}

TEST_F(BagReaderTest, ACorruptLengthIsReadUpToItOrOneLine) {
  // A whole bag whose second chunk's header length is damaged: read up to that chunk, exactly;
  // the same damage in the first chunk leaves nothing, refused in one line. Every 4-byte length
  // field of the first records set to huge values gives a result or one line, never a crash.
  const std::string bytes = test::read_bytes(dir_ / "chunked.bag");
  const test::BagLayout layout = test::BagLayout::of(dir_ / "chunked.bag");
  ASSERT_GE(layout.chunks.size(), 2U);
  const fs::path path = dir_ / "corrupt.bag";
  const auto with_u32 = [&](std::uint64_t at, std::uint32_t value) {
    std::string damaged = bytes;
    std::memcpy(damaged.data() + at, &value, 4);
    test::write_bytes(path, damaged);
  };
  const std::uint64_t second = layout.chunks[1].pos;
  with_u32(second, 0xFFFFFFF0U);
  const ros::BagInfo info = ros::read_bag_info(path);
  EXPECT_EQ(info.messages, layout.whole_before(second));
  EXPECT_EQ(info.scanned_to, second);
  ASSERT_EQ(info.warnings.size(), 1U);
  EXPECT_NE(info.warnings[0].find("ends at byte " + std::to_string(second)), std::string::npos) << info.warnings[0];
  with_u32(layout.chunks[0].pos, 0xFFFFFFF0U);
  const std::string e = error_of([&] { (void)ros::read_bag_info(path); });
  EXPECT_NE(e.find("no whole message"), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);
  std::vector<std::uint64_t> positions;
  for (std::uint64_t at = 13; at < 13 + 64; ++at) positions.push_back(at);  // the file header record
  for (std::uint64_t at = layout.chunks[0].pos; at < layout.chunks[0].pos + 320; ++at) positions.push_back(at);
  for (const std::uint64_t at : positions) {
    for (const std::uint32_t value : {0xFFFFFFFFU, 0x7FFFFFFFU, static_cast<std::uint32_t>(bytes.size())}) {
      with_u32(at, value);
      try {
        const ros::BagInfo damaged = ros::read_bag_info(path);
        for (const auto& w : damaged.warnings) EXPECT_EQ(w.find('\n'), std::string::npos) << w;
      } catch (const InputError& error) {
        EXPECT_EQ(std::string(error.what()).find('\n'), std::string::npos) << error.what();
      }
    }
  }
}

TEST(PointCloud2Decode, LayoutChecks) {
  std::vector<std::uint8_t> data(2 * 12, 0);
  const float values[6] = {1, 2, 3, 4, 5, 6};
  std::memcpy(data.data(), values, sizeof values);
  ros::PointCloud2Data cloud;
  cloud.width = 2;
  cloud.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}};
  cloud.point_step = 12;
  cloud.row_step = 24;
  cloud.data = data;
  PointCloud points;
  ros::decode_pointcloud2(cloud, points, nullptr, "b.bag", "/c at stamp 1");
  ASSERT_EQ(points.size(), 2U);
  EXPECT_EQ(points[1], Point3f(4, 5, 6));
  const auto fails = [&](ros::PointCloud2Data c, const std::string& part) {
    try {
      ros::decode_pointcloud2(c, points, nullptr, "b.bag", "/c at stamp 1");
      ADD_FAILURE() << "no error for " << part;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("b.bag: /c at stamp 1: " + part), std::string::npos) << e.what();
    }
  };
  auto c = cloud;
  c.fields.pop_back();
  fails(c, "the cloud has no z field");
  c = cloud;
  c.fields[1].offset = 10;
  fails(c, "field y at offset 10 lies outside");
  c = cloud;
  c.row_step = 20;
  fails(c, "row_step 20 is less than");
  c = cloud;
  c.height = 1000000;  // an absurd row count is refused, not allocated
  fails(c, "data holds 24 bytes");
  c = cloud;
  c.fields[0].datatype = 9;
  fails(c, "field x has unknown datatype 9");
}

TEST_F(BagReaderTest, ImuTopicAndPerPointTime) {
  const fs::path bag = dir_ / "imu.bag";
  // The only Imu topic is found by itself; named, it is checked.
  EXPECT_EQ(ros::bag_imu_topic(bag, "").value_or(""), "/imu");
  EXPECT_EQ(ros::bag_imu_topic(bag, "/imu").value_or(""), "/imu");
  EXPECT_NE(error_of([&] { (void)ros::bag_imu_topic(bag, "/odom"); }).find("not a sensor_msgs/Imu topic"), std::string::npos);
  EXPECT_FALSE(ros::bag_imu_topic(dir_ / "odom.bag", "").has_value());
  EXPECT_NE(error_of([&] { (void)ros::bag_imu_topic(dir_ / "imu_two.bag", ""); }).find("--imu-topic"), std::string::npos);
  const ImuSamples imu = ros::read_bag_imu(bag, "/imu");
  ASSERT_GT(imu.size(), 100U);
  EXPECT_NEAR(imu[1].t - imu[0].t, 0.01, 1e-6);
  EXPECT_DOUBLE_EQ(imu[5].gyro.x(), 0.05);
  EXPECT_DOUBLE_EQ(imu[5].gyro.z(), 0.3);
  EXPECT_DOUBLE_EQ(imu[5].accel.z(), 9.81);
  EXPECT_FALSE(imu[5].orientation.has_value());  // covariance[0] = -1: no orientation
  // The clouds carry their uint32 ns field t as seconds beside the points; without asking, none.
  ros::BagCloudOptions o;
  o.cloud_topic = "/os_cloud";
  o.pose_topic = "/odom";
  const ros::BagCloudReader reader(bag, o);
  std::vector<float> times;
  const PointCloud cloud = reader.read(1, nullptr, &times);
  ASSERT_EQ(times.size(), cloud.size());
  EXPECT_EQ(cloud, expected_scan(1));
  EXPECT_FLOAT_EQ(times.front(), 0.0F);
  EXPECT_NEAR(times.back(), 0.099F, 1e-6);
  std::vector<float> none;
  (void)ros::BagCloudReader(dir_ / "odom.bag", o).read(0, nullptr, &none);
  EXPECT_TRUE(none.empty());
}

}  // namespace
}  // namespace hmap
