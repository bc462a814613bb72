// `hmap bag-info` and `hmap map --bag` on a ROS 1 bag cut off (its recorder killed before it wrote
// the index): the readable part is read with one warning line and exit 0; nothing readable is one
// error line and exit 2. The bags are written by ROS's own writer (tests/ros/make_test_bags.py).

#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "apps/cli_run.hpp"
#include "common/bag_layout.hpp"
#include "common/test_data.hpp"

namespace hmap {
namespace {

namespace fs = std::filesystem;
using test::CmdResult;
using test::run;

/// The lines of `out` that contain `part`.
std::size_t lines_with(const std::string& out, const std::string& part) {
  std::istringstream in(out);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) n += line.find(part) != std::string::npos ? 1 : 0;
  return n;
}

class BagCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(test::data_dir() / "balm_os0")) return;
    dir_ = test::temp_dir("bag_cli");
    const std::string cmd = "/usr/bin/python3 " + test::make_test_bags_script().string() + " " + test::data_dir().string() +
                            " " + dir_.string() + " 3 10 >/dev/null 2>&1";
    made_ = std::system(cmd.c_str()) == 0;
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    if (!dir_.empty()) fs::remove_all(dir_, ec);
  }
  void SetUp() override {
    HMAP_REQUIRE_DATA("balm_os0");
    if (!made_) GTEST_SKIP() << "make_test_bags.py failed: is python3-rosbag (and python3-tf2-msgs) installed?";
    const CmdResult whole = run("bag-info " + (dir_ / "chunked_lz4.bag").string());
    if (whole.code != 0) GTEST_SKIP() << "this hmap reads no ROS 1 bag: " << whole.out;
  }
  static inline fs::path dir_;
  static inline bool made_ = false;
};

TEST_F(BagCliTest, ACutOffBagIsReadWithOneWarningAndNothingReadableIsExitTwo) {
  for (const char* name : {"chunked.bag", "chunked_lz4.bag"}) {
    SCOPED_TRACE(name);
    const test::BagLayout layout = test::BagLayout::of(dir_ / name);
    ASSERT_GE(layout.chunks.size(), 3U);
    const std::string bytes = test::read_bytes(dir_ / name);
    const fs::path cut = dir_ / "cut.bag";
    // Inside the third chunk's data: the first two chunks' messages (and, stored uncompressed,
    // the third's whole ones before the cut).
    const std::uint64_t at = (layout.chunks[2].pos + layout.chunks[2].end) / 2;
    test::write_bytes(cut, bytes.substr(0, at));
    const std::size_t expected = layout.whole_before(at);
    ASSERT_GT(expected, 1U);
    const CmdResult info = run("bag-info " + cut.string());
    EXPECT_EQ(info.code, 0) << info.out;
    EXPECT_EQ(lines_with(info.out, "hmap: warning: "), 1U) << info.out;
    EXPECT_EQ(lines_with(info.out, "hmap: warning: " + cut.string() + ": read linearly"), 1U) << info.out;
    EXPECT_EQ(lines_with(info.out, "; " + std::to_string(expected) + " whole messages read"), 1U) << info.out;
    EXPECT_EQ(lines_with(info.out, "messages:    " + std::to_string(expected)), 1U) << info.out;
    EXPECT_EQ(lines_with(info.out, "index:       none usable: read linearly, cut off at byte "), 1U) << info.out;
    EXPECT_EQ(lines_with(info.out, " of " + std::to_string(at)), 2U) << info.out;  // the warning and the index line

    const std::string map = "map --bag " + cut.string() + " --cloud-topic /os_cloud --pose-topic /odom --preset outdoor --out " +
                            (dir_ / "cut.hmap").string();
    const CmdResult mapped = run(map);
    EXPECT_EQ(mapped.code, 0) << mapped.out;
    EXPECT_EQ(lines_with(mapped.out, "hmap: warning: "), 1U) << mapped.out;
    EXPECT_EQ(lines_with(mapped.out, std::to_string(layout.whole_before(at, "/os_cloud")) + " clouds of /os_cloud"), 1U)
        << mapped.out;
    EXPECT_TRUE(fs::exists(dir_ / "cut.hmap"));
    fs::remove(dir_ / "cut.hmap");

    // Cut inside the first chunk's header: not one whole message.
    test::write_bytes(cut, bytes.substr(0, layout.chunks[0].pos + 20));
    for (const std::string& command : {"bag-info " + cut.string(), map}) {
      const CmdResult none = run(command);
      EXPECT_EQ(none.code, 2) << none.out;
      EXPECT_EQ(test::lines(none.out), 1U) << none.out;
      EXPECT_EQ(lines_with(none.out, "hmap: error: " + cut.string() + ": unreadable bag: no whole message"), 1U) << none.out;
    }
    EXPECT_FALSE(fs::exists(dir_ / "cut.hmap"));
  }
}

TEST_F(BagCliTest, WithoutCloudTopicTheBagsOnlyPointCloud2TopicIsRead) {
  // One PointCloud2 topic: taken without --cloud-topic, said so, and the map is the one the topic
  // named gives, byte for byte.
  const fs::path bag = dir_ / "chunked_lz4.bag";
  const std::string rest = " --pose-topic /odom --preset outdoor --out ";
  const CmdResult named = run("map --bag " + bag.string() + " --cloud-topic /os_cloud" + rest + (dir_ / "named.hmap").string());
  ASSERT_EQ(named.code, 0) << named.out;
  const CmdResult chosen = run("map --bag " + bag.string() + rest + (dir_ / "chosen.hmap").string());
  ASSERT_EQ(chosen.code, 0) << chosen.out;
  EXPECT_EQ(lines_with(chosen.out, "clouds of /os_cloud (its only PointCloud2 topic) in " + bag.string()), 1U) << chosen.out;
  EXPECT_EQ(lines_with(named.out, "its only PointCloud2 topic"), 0U) << named.out;
  EXPECT_EQ(test::read_bytes(dir_ / "chosen.hmap"), test::read_bytes(dir_ / "named.hmap"));

  // Two: one line naming both, exit 2, no map. None: one line, exit 2.
  const fs::path two_out = dir_ / "two.hmap";
  const CmdResult two = run("map --bag " + (dir_ / "two_clouds.bag").string() + rest + two_out.string());
  EXPECT_EQ(two.code, 2) << two.out;
  EXPECT_EQ(lines_with(two.out, "hmap: error: "), 1U) << two.out;
  EXPECT_EQ(lines_with(two.out, "has 2 PointCloud2 topics (/os_cloud, /os_cloud_b): choose one with --cloud-topic"), 1U)
      << two.out;
  EXPECT_FALSE(fs::exists(two_out));
  const CmdResult none = run("map --bag " + (dir_ / "imu_two.bag").string() + rest + (dir_ / "none.hmap").string());
  EXPECT_EQ(none.code, 2) << none.out;
  EXPECT_EQ(lines_with(none.out, "hmap: error: "), 1U) << none.out;
  EXPECT_EQ(lines_with(none.out, "no sensor_msgs/PointCloud2 topic"), 1U) << none.out;
}

}  // namespace
}  // namespace hmap
