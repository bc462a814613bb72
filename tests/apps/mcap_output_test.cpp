// hmap slam/map/export --mcap (apps/hmap/mcap_output.hpp) on the scans' real stamps: the /tf of
// each scan at its times.txt stamp, the map at the last, read back from the file the tool wrote.

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "apps/cli_run.hpp"
#include "common/test_data.hpp"

#ifdef HMAP_HAVE_ROS
#include "hmap/ros/cdr.hpp"
#include "hmap/ros/mcap_reader.hpp"
#endif

namespace hmap {
namespace {

using test::CmdResult;
using test::run;

#ifdef HMAP_HAVE_ROS

class McapOutputTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::temp_dir("mcap_output"); }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::filesystem::path dir_;
};

/// What an MCAP holds: per topic the log times [ns] and the data, in file order; the statistics.
struct Recording {
  std::map<std::string, std::vector<std::uint64_t>> log_times;
  std::map<std::string, std::vector<std::vector<std::uint8_t>>> data;
  ros::mcap::Info info;
};

Recording read_recording(const std::string& file) {
  const ros::mcap::Reader reader(ros::mcap::file_source(file), file);
  Recording out;
  std::set<std::uint16_t> all;
  for (const auto& [id, ch] : reader.info().channels) all.insert(id);
  for (const auto& ref : reader.messages(all)) {
    const std::string& topic = reader.info().channels.at(ref.channel).topic;
    out.log_times[topic].push_back(ref.log_time);
    out.data[topic].push_back(reader.read(ref));
  }
  out.info = reader.info();
  return out;
}

/// Unix times a few seconds apart, written to times.txt as text: whole seconds plus k/512 s
/// (exact in binary, 1953125 ns each), so that the ns each line means is known exactly.
std::vector<std::uint64_t> write_times(const std::filesystem::path& file, std::size_t n) {
  std::vector<std::uint64_t> ns;
  std::ofstream out(file);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint64_t sec = 1'700'000'000ULL + k / 2;
    const std::uint64_t fraction = (k % 2) * 256 + 3 * k + 1;  // of 512
    char line[64];
    std::snprintf(line, sizeof line, "%llu.%09llu\n", static_cast<unsigned long long>(sec),
                  static_cast<unsigned long long>(fraction * 1'953'125ULL));
    out << line;
    ns.push_back(sec * 1'000'000'000ULL + fraction * 1'953'125ULL);
  }
  return ns;
}

// slam --kitti on a simulated sequence whose times.txt holds Unix stamps: one /tf per scan at its
// stamp (log time and header), every other message at the last, the statistics from the first to
// the last. export --trajectory of the slam's poses.txt has no stamps: all at 0.
TEST_F(McapOutputTest, SlamStampsEachScansTfWithTimesTxt) {
  const CmdResult sim = run("simulate --scene office --sensor kinect --frames 6 --stride 5 --seed 3 --out " + path("seq"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  const std::vector<std::uint64_t> stamps = write_times(dir_ / "seq" / "times.txt", 6);
  const CmdResult s = run("slam --kitti " + path("seq") + " --preset indoor --out " + path("s") + " --mcap " + path("s.mcap"));
  ASSERT_EQ(s.code, 0) << s.out;
  char span[96];
  std::snprintf(span, sizeof span, "stamped %.3f to %.3f s", static_cast<double>(stamps.front()) / 1e9,
                static_cast<double>(stamps.back()) / 1e9);
  EXPECT_NE(s.out.find(span), std::string::npos) << span << "\n" << s.out;

  const Recording r = read_recording(path("s.mcap"));
  ASSERT_EQ(r.log_times.at("/tf"), stamps);
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    const std::string src = "/tf", pos = "message " + std::to_string(k);
    ros::cdr::Reader c(r.data.at("/tf")[k], src, pos);
    ASSERT_EQ(c.u32(), 2U);  // world -> map, map -> sensor
    const auto sec = static_cast<std::uint64_t>(c.i32());
    EXPECT_EQ(sec * 1'000'000'000ULL + c.u32(), stamps[k]) << k;
  }
  for (const auto& [topic, times] : r.log_times) {
    if (topic == "/tf") continue;
    for (const std::uint64_t t : times) EXPECT_EQ(t, stamps.back()) << topic;
  }
  EXPECT_EQ(r.log_times.size(), 6U);  // /tf /map /grid /hvoxels /points /trajectory
  EXPECT_EQ(r.info.start_time, stamps.front());
  EXPECT_EQ(r.info.end_time, stamps.back());
  std::uint64_t total = 0;
  for (const auto& [id, ch] : r.info.channels) {
    EXPECT_EQ(r.info.message_counts.at(id), r.log_times.at(ch.topic).size()) << ch.topic;
    total += r.log_times.at(ch.topic).size();
  }
  EXPECT_EQ(r.info.messages, total);

  // The slam's folder has no times.txt beside its KITTI poses.txt: no stamps.
  const CmdResult e = run("export " + path("s/map.hmap") + " --mcap " + path("e.mcap") + " --trajectory " + path("s/poses.txt"));
  ASSERT_EQ(e.code, 0) << e.out;
  EXPECT_NE(e.out.find("no stamps (all at time 0)"), std::string::npos) << e.out;
  const Recording plain = read_recording(path("e.mcap"));
  EXPECT_EQ(plain.log_times.at("/tf"), std::vector<std::uint64_t>(6, 0));
  EXPECT_EQ(plain.info.end_time, 0U);
}

// export --trajectory and map --poses: a TUM file's own times; a times.txt beside a KITTI file that
// does not hold one line per pose refused with one line naming it.
TEST_F(McapOutputTest, ExportTakesTumTimesAndRefusesAShortTimesTxt) {
  const CmdResult sim = run("simulate --scene office --sensor kinect --frames 3 --stride 5 --seed 3 --out " + path("seq"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  ASSERT_EQ(run("map --kitti " + path("seq") + " --preset indoor --out " + path("m.hmap")).code, 0);
  std::ofstream(path("tum.txt")) << "# t x y z qx qy qz qw\n"
                                    "1700000000.5 0 0 0 0 0 0 1\n"
                                    "1700000001.25 1 0 0 0 0 0 1\n"
                                    "1700000003.0 2 0 0 0 0 0 1\n";
  const CmdResult tum = run("export " + path("m.hmap") + " --mcap " + path("tum.mcap") + " --trajectory " + path("tum.txt"));
  ASSERT_EQ(tum.code, 0) << tum.out;
  const Recording r = read_recording(path("tum.mcap"));
  EXPECT_EQ(r.log_times.at("/tf"),
            (std::vector<std::uint64_t>{1'700'000'000'500'000'000ULL, 1'700'000'001'250'000'000ULL, 1'700'000'003'000'000'000ULL}));
  EXPECT_EQ(r.log_times.at("/trajectory"), std::vector<std::uint64_t>{1'700'000'003'000'000'000ULL});
  // map with scan files and the TUM file as --poses: the scans take its times.
  std::string scans;
  for (int k = 0; k < 3; ++k) scans += " " + path("seq/velodyne/00000" + std::to_string(k) + ".bin");
  const CmdResult m = run("map" + scans + " --poses " + path("tum.txt") + " --preset indoor --out " + path("t.hmap") +
                          " --mcap " + path("t.mcap"));
  ASSERT_EQ(m.code, 0) << m.out;
  EXPECT_EQ(read_recording(path("t.mcap")).log_times.at("/tf"), r.log_times.at("/tf"));

  std::filesystem::create_directories(dir_ / "short");
  std::filesystem::copy_file(dir_ / "seq" / "poses.txt", dir_ / "short" / "poses.txt");
  std::ofstream(dir_ / "short" / "times.txt") << "0.0\n0.1\n";
  const CmdResult bad = run("export " + path("m.hmap") + " --mcap " + path("bad.mcap") + " --trajectory " + path("short/poses.txt"));
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_EQ(test::lines(bad.out), 1U) << bad.out;
  EXPECT_NE(bad.out.find("times.txt"), std::string::npos) << bad.out;
  EXPECT_NE(bad.out.find("2 timestamps for the 3 poses"), std::string::npos) << bad.out;
  EXPECT_FALSE(std::filesystem::exists(path("bad.mcap")));
}

#endif  // HMAP_HAVE_ROS

}  // namespace
}  // namespace hmap
