// hmap::ros on ROS 2 recordings written by the ecosystem's own writers (tests/ros2: @mcap/core's
// McapWriter and @foxglove/rosmsg2-serialization's CDR, Python's sqlite3 for the rosbag2 .db3
// folder) from the real Ouster scans of ../shared/data/balm_os0: the same points and poses as the
// KITTI files themselves, whatever the container, compression or summary.

#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <fstream>
#include <sstream>
#include <vector>
#include <iterator>
#include <tuple>
#include <set>

#include <nlohmann/json.hpp>

#include "common/test_data.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/ros/bag_reader.hpp"
#include "hmap/ros/mcap_reader.hpp"

namespace hmap {
namespace ros2_recording_test {

namespace fs = std::filesystem;
constexpr int kScans = 3;
constexpr std::size_t kStep = 10;

class Ros2RecordingTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(test::data_dir() / "balm_os0")) return;
    const fs::path scripts = HMAP_ROS2_SCRIPTS_DIR;
    if (std::system("node --version > /dev/null 2>&1") != 0) {
      why_ = "node is not installed (Debian: nodejs)";
      return;
    }
    if (!fs::exists(scripts / "node_modules" / "@mcap" / "core")) {
      why_ = "the npm packages are absent: run `make ros2-test-deps` (npm ci --prefix tests/ros2)";
      return;
    }
    // Into the build folder, once for all the test processes CTest runs (each test is a process,
    // two at a time): under a lock, written again only when the scripts, their packages or the
    // data folder changed since the recordings there were made.
    dir_ = fs::path(HMAP_TEST_BUILD_DIR) / "ros2_recordings";
    const int lock = ::open((fs::path(HMAP_TEST_BUILD_DIR) / "ros2_recordings.lock").c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
    if (lock < 0 || ::flock(lock, LOCK_EX) != 0) {
      why_ = "cannot lock " + (fs::path(HMAP_TEST_BUILD_DIR) / "ros2_recordings.lock").string();
      return;
    }
    struct Unlock {
      int fd;
      ~Unlock() { ::close(fd); }
    } unlock{lock};
    std::string stamp = test::data_dir().string();
    for (const char* f : {"make_ros2_recordings.js", "make_db3.py", "package-lock.json"}) {
      stamp += " " + std::to_string(fs::last_write_time(scripts / f).time_since_epoch().count());
    }
    std::string made;
    std::getline(std::ifstream(dir_ / "stamp"), made);
    if (made != stamp) {
      std::error_code ec;
      fs::remove_all(dir_, ec);
      fs::create_directories(dir_);
      const std::string node = "node " + (scripts / "make_ros2_recordings.js").string() + " " + test::data_dir().string() +
                               " " + dir_.string() + " " + std::to_string(kScans) + " " + std::to_string(kStep) + " 2>&1";
      const std::string db3 = "/usr/bin/python3 " + (scripts / "make_db3.py").string() + " " +
                              (dir_ / "messages.json").string() + " " + (dir_ / "db3").string() + " 2>&1";
      if (std::system(node.c_str()) != 0) {
        why_ = "make_ros2_recordings.js failed";
        return;
      }
      if (std::system(db3.c_str()) != 0) {
        why_ = "make_db3.py failed";
        return;
      }
      std::ofstream(dir_ / "stamp") << stamp << "\n";
    }
    std::ifstream in(dir_ / "manifest.json");
    manifest_ = nlohmann::json::parse(in);
    made_ = true;
  }
  void SetUp() override {
    HMAP_REQUIRE_DATA("balm_os0");
    if (!made_) GTEST_SKIP() << "no ROS 2 test recordings: " << why_;
  }
  static PointCloud expected_scan(int k) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.bin", k);
    const PointCloud all = read_kitti_bin(test::data_dir() / "balm_os0" / "velodyne" / name);
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
  static std::size_t written(const std::string& file, const std::string& topic) {
    return manifest_["files"][file].value(topic, std::size_t{0});
  }
  static inline fs::path dir_;
  static inline bool made_ = false;
  static inline std::string why_;
  static inline nlohmann::json manifest_;
};

/// Translation error [m] plus the rotation-matrix error scaled down (poses.txt's matrices are
/// orthonormal to ~1e-3 only, the written quaternion comes from the raw matrix).
double max_pose_error(const Pose& a, const Pose& b) {
  return std::max((a.translation() - b.translation()).cwiseAbs().maxCoeff(),
                  1e-3 * (a.linear() - b.linear()).cwiseAbs().maxCoeff());
}

const char* const kRecordings[] = {"zstd.mcap", "lz4.mcap", "none.mcap", "bigendian.mcap", "nosummary.mcap", "r2mcap", "db3"};

/// Every message of a file as (topic, log time, data), in the order messages() lists them.
std::vector<std::tuple<std::string, std::uint64_t, std::vector<std::uint8_t>>> all_messages(const ros::mcap::Reader& r) {
  std::set<std::uint16_t> ids;
  for (const auto& [id, ch] : r.info().channels) ids.insert(id);
  std::vector<std::tuple<std::string, std::uint64_t, std::vector<std::uint8_t>>> out;
  for (const auto& ref : r.messages(ids)) out.emplace_back(r.info().channels.at(ref.channel).topic, ref.log_time, r.read(ref));
  return out;
}

TEST_F(Ros2RecordingTest, MessageIndexesListWhatTheChunksHold) {
  // The writer's files with a summary carry a Message Index per channel and chunk: the listing
  // comes from them (no chunk decompressed to list), and must give what a linear scan of the same
  // messages gives (nosummary.mcap: the zstd file without summary, scanned record by record).
  const ros::mcap::Reader scanned(ros::mcap::file_source(dir_ / "nosummary.mcap"), "nosummary.mcap");
  ASSERT_FALSE(scanned.info().indexed);
  const auto expected = all_messages(scanned);
  ASSERT_EQ(expected.size(), scanned.info().messages);
  for (const std::string name : {"zstd.mcap", "lz4.mcap", "none.mcap"}) {
    const ros::mcap::Reader r(ros::mcap::file_source(dir_ / name), name);
    ASSERT_TRUE(r.info().indexed) << name;
    for (const auto& chunk : r.info().chunks) {
      EXPECT_EQ(chunk.message_indexes.size(), chunk.channels.size()) << name << ": a channel without its index";
    }
    EXPECT_EQ(all_messages(r), expected) << name;
  }
}

TEST_F(Ros2RecordingTest, AMessageIndexPointingAmissIsRefusedNamingTheFile) {
  // An entry's offset moved by one byte points into a record, not at one: refused on reading.
  std::ifstream in(dir_ / "none.mcap", std::ios::binary);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const ros::mcap::Reader good(ros::mcap::memory_source(bytes), "none.mcap");
  const auto& chunk = good.info().chunks.at(0);
  ASSERT_FALSE(chunk.message_indexes.empty());
  // Message Index: opcode, length (8), channel (2), entries' byte length (4), then (time, offset).
  const std::uint64_t entry = chunk.message_indexes.begin()->second + 9 + 2 + 4;
  bytes[static_cast<std::size_t>(entry + 8)] += 1;  // the offset's low byte
  // The Data End record's CRC, which covers the indexes, set to 0 (not written): the damage must
  // be found by the index check itself. The footer (opcode, length, summary start, ...) precedes
  // the closing magic; Data End's 13 bytes precede the summary.
  const std::size_t footer = bytes.size() - 8 - 20 - 9;
  std::uint64_t summary_start = 0;
  for (int i = 7; i >= 0; --i) summary_start = (summary_start << 8) | bytes[footer + 9 + static_cast<std::size_t>(i)];
  ASSERT_EQ(bytes[static_cast<std::size_t>(summary_start - 13)], 0x0F);
  std::fill_n(bytes.begin() + static_cast<std::ptrdiff_t>(summary_start - 13 + 9), 4, std::uint8_t{0});
  const ros::mcap::Reader bad(ros::mcap::memory_source(bytes), "damaged.mcap");
  std::set<std::uint16_t> ids{chunk.message_indexes.begin()->first};
  const auto refs = bad.messages(ids);
  ASSERT_FALSE(refs.empty());
  const std::string error = error_of([&] {
    for (const auto& ref : refs) (void)bad.read(ref);
  });
  EXPECT_NE(error.find("damaged.mcap"), std::string::npos) << error;
  EXPECT_NE(error.find("message index points"), std::string::npos) << error;
}

TEST_F(Ros2RecordingTest, InfoCountsWhatWasWritten) {
  for (const std::string name : kRecordings) {
    const ros::BagInfo info = ros::read_bag_info(dir_ / name);
    const std::string file = name == "db3" || name == "r2mcap" ? "zstd.mcap" : name;
    ASSERT_EQ(info.topics.size(), 6U) << name;
    std::size_t total = 0;
    for (const auto& t : info.topics) {
      EXPECT_EQ(t.messages, written(file, t.name)) << name << " " << t.name;
      total += t.messages;
    }
    EXPECT_EQ(info.messages, total) << name;
    EXPECT_EQ(info.topics[0].name, "/imu");
    EXPECT_EQ(info.topics[0].messages, static_cast<std::size_t>(10 * kScans));
    EXPECT_EQ(info.topics[0].type, "sensor_msgs/msg/Imu");
    EXPECT_EQ(info.topics[2].name, "/os_cloud");
    EXPECT_EQ(info.topics[2].type, "sensor_msgs/msg/PointCloud2");
    EXPECT_TRUE(info.warnings.empty()) << name;
    // The first message is /tf_static at t_0 - 0.5 s, the last the last IMU message at t_2 + 90 ms
    // (balm_os0/times.txt: t_0 = 1630577758.569490, t_2 = 1630577759.568717).
    EXPECT_NEAR(info.start_time, 1630577758.069490, 1e-6) << name;
    EXPECT_NEAR(info.end_time, 1630577759.568717 + 0.09, 1e-6) << name;
  }
  EXPECT_EQ(ros::read_bag_info(dir_ / "zstd.mcap").compression, "zstd");
  EXPECT_EQ(ros::read_bag_info(dir_ / "lz4.mcap").compression, "lz4");
  EXPECT_EQ(ros::read_bag_info(dir_ / "none.mcap").compression, "none");
  // bigendian.mcap's clouds are big-endian CDR: their frame_id "os_sensor" follows its length 10
  // as 00 00 00 0a (the little-endian messages write 0a 00 00 00), which none.mcap never holds.
  const auto bytes_of = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string be_frame("\0\0\0\x0aos_sensor", 13);
  EXPECT_NE(bytes_of(dir_ / "bigendian.mcap").find(be_frame), std::string::npos);
  EXPECT_EQ(bytes_of(dir_ / "none.mcap").find(be_frame), std::string::npos);
  EXPECT_EQ(ros::read_bag_info(dir_ / "db3").compression, "none");
  EXPECT_EQ(ros::read_bag_info(dir_ / "zstd.mcap").format, "MCAP");
  EXPECT_EQ(ros::read_bag_info(dir_ / "db3").format, "rosbag2 (sqlite3, 1 file)");
  EXPECT_EQ(ros::read_bag_info(dir_ / "r2mcap").format, "rosbag2 (mcap, 1 file)");
  EXPECT_GE(ros::read_bag_info(dir_ / "zstd.mcap").chunks, static_cast<std::size_t>(kScans));
}

TEST_F(Ros2RecordingTest, SamePointsAndPosesAsTheKittiFiles) {
  const PoseList truth = read_poses(test::data_dir() / "balm_os0" / "poses.txt");
  Pose T_map_odom = Pose::Identity();
  T_map_odom.translation() = Eigen::Vector3d(1, 2, 0);
  for (const std::string name : kRecordings) {
    for (const char* pose_topic : {"", "/odom", "/pose"}) {
      ros::BagCloudOptions options;
      options.cloud_topic = "/os_cloud";
      options.pose_topic = pose_topic;
      const ros::BagCloudReader reader(dir_ / name, options);
      ASSERT_EQ(reader.frames().size(), static_cast<std::size_t>(kScans)) << name;
      for (int k = 0; k < kScans; ++k) {
        const auto& frame = reader.frames()[static_cast<std::size_t>(k)];
        EXPECT_EQ(frame.frame_id, "os_sensor");
        // /tf: map -> odom (static, translation 1 2 0) -> os_sensor (P_k); /odom and /pose: P_k.
        const Pose expected = *pose_topic == '\0' ? T_map_odom * truth[static_cast<std::size_t>(k)] : truth[static_cast<std::size_t>(k)];
        EXPECT_LT(max_pose_error(frame.T_map_cloud, expected), 1e-5) << name << " " << pose_topic << " " << k;
      }
    }
    ros::BagCloudOptions options;
    options.cloud_topic = "/os_cloud";
    const ros::BagCloudReader reader(dir_ / name, options);
    for (int k = 0; k < kScans; ++k) {
      CloudReadStats stats;
      std::vector<float> times;
      const PointCloud points = reader.read(static_cast<std::size_t>(k), &stats, &times);
      const PointCloud expected = expected_scan(k);
      EXPECT_EQ(points.size(), manifest_["points"][static_cast<std::size_t>(k)].get<std::size_t>()) << name;
      EXPECT_EQ(points, expected) << name << " scan " << k;  // float32 written and read back: bit for bit
      ASSERT_EQ(times.size(), points.size()) << name;
      // Per-point time t (uint32 ns) spread over 0..99 ms in point order.
      EXPECT_FLOAT_EQ(times.front(), 0.0F);
      EXPECT_NEAR(times.back(), 0.1, 1e-3);
      EXPECT_TRUE(std::is_sorted(times.begin(), times.end()));
    }
  }
}

TEST_F(Ros2RecordingTest, ImuTopicFoundAndRead) {
  for (const std::string name : {"zstd.mcap", "db3"}) {
    EXPECT_EQ(ros::bag_imu_topic(dir_ / name, "").value_or(""), "/imu");
    const ImuSamples imu = ros::read_bag_imu(dir_ / name, "/imu");
    ASSERT_EQ(imu.size(), static_cast<std::size_t>(10 * kScans));
    EXPECT_DOUBLE_EQ(imu[3].gyro.x(), 0.03);
    EXPECT_DOUBLE_EQ(imu[3].gyro.y(), -0.02);
    EXPECT_DOUBLE_EQ(imu[3].accel.z(), 9.81);
    EXPECT_FALSE(imu[3].orientation.has_value());  // covariance[0] = -1: none
    EXPECT_NEAR(imu[1].t - imu[0].t, 0.01, 1e-6);
  }
}

TEST_F(Ros2RecordingTest, TruncatedFileReadsUpToItsLastWholeMessageAndSaysSo) {
  const ros::BagInfo info = ros::read_bag_info(dir_ / "truncated.mcap");
  ASSERT_EQ(info.warnings.size(), 1U);
  EXPECT_NE(info.warnings[0].find("truncated.mcap: the recording is cut off at byte"), std::string::npos) << info.warnings[0];
  // The same messages as @mcap/core's own stream reader reads from the cut file.
  std::size_t total = 0;
  for (const auto& t : info.topics) {
    EXPECT_EQ(t.messages, written("truncated.mcap", t.name)) << t.name;
    total += t.messages;
  }
  EXPECT_NE(info.warnings[0].find("read the " + std::to_string(total) + " whole messages"), std::string::npos);
  const std::size_t clouds = written("truncated.mcap", "/os_cloud");
  ASSERT_EQ(clouds, static_cast<std::size_t>(kScans - 1));
  ros::BagCloudOptions options;
  options.cloud_topic = "/os_cloud";
  options.pose_topic = "/odom";
  const ros::BagCloudReader reader(dir_ / "truncated.mcap", options);
  EXPECT_EQ(reader.warnings(), info.warnings);
  ASSERT_EQ(reader.frames().size(), clouds);
  for (std::size_t k = 0; k < clouds; ++k) EXPECT_EQ(reader.read(k), expected_scan(static_cast<int>(k)));
}

TEST_F(Ros2RecordingTest, BadInputRefusedInOneLineNamingTheFile) {
  const auto one_line = [](const std::string& e) { return e.find('\n') == std::string::npos; };
  ros::BagCloudOptions options;
  options.cloud_topic = "/os_cloud";
  const std::string crc = error_of([&] { ros::BagCloudReader r(dir_ / "badcrc.mcap", options); });
  EXPECT_EQ(crc.rfind((dir_ / "badcrc.mcap").string() + ": ", 0), 0U) << crc;
  EXPECT_NE(crc.find("CRC mismatch"), std::string::npos) << crc;
  EXPECT_TRUE(one_line(crc));
  const std::string json = error_of([&] { ros::BagCloudReader r(dir_ / "json.mcap", options); });
  EXPECT_NE(json.find("json.mcap: topic /os_cloud: message encoding \"json\" is not one hmap reads (cdr)"), std::string::npos) << json;
  EXPECT_TRUE(one_line(json));
  options.cloud_topic = "/odom";
  const std::string type = error_of([&] { ros::BagCloudReader r(dir_ / "zstd.mcap", options); });
  EXPECT_NE(type.find("has type nav_msgs/msg/Odometry, not sensor_msgs/msg/PointCloud2"), std::string::npos) << type;
  options.cloud_topic = "/nothing";
  EXPECT_NE(error_of([&] { ros::BagCloudReader r(dir_ / "db3", options); }).find("has no topic /nothing"), std::string::npos);
  // A rosbag2 folder without its metadata.yaml.
  const fs::path bare = dir_ / "bare";
  fs::create_directories(bare);
  const std::string meta = error_of([&] { (void)ros::read_bag_info(bare); });
  EXPECT_NE(meta.find("bare: is a folder without metadata.yaml"), std::string::npos) << meta;
}

}  // namespace ros2_recording_test
}  // namespace hmap
