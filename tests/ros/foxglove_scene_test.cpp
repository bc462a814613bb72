// The map as a Foxglove MCAP (src/hmap/ros/foxglove_scene.hpp), read back by our reader and, when
// node and tests/ros2's npm packages are there, by @mcap/core with every message decoded.

#include "hmap/ros/foxglove_scene.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>

#include "common/test_data.hpp"
#include "hmap/ros/cdr.hpp"
#include "hmap/ros/mcap_reader.hpp"
#include "hmap/view/map_scene.hpp"

namespace hmap::ros {
namespace {

namespace fs = std::filesystem;

Params small_params() {
  Params p;
  p.map.cell_size = 0.5;
  return p;
}

/// 30 x 20 columns over negative and positive keys, one or two HVoxels each, and a grid over
/// part of them with free, occupied and unknown cells.
struct SmallMap {
  HMap map{small_params()};
  OccupancyGrid grid{0.5, 0.12, 0.97};
  SmallMap() {
    for (int i = -15; i < 15; ++i) {
      for (int j = -10; j < 10; ++j) {
        auto c = map.column_for_update({i, j});
        c.push_back({0.0F, 0.1F, 3.0F, 0.5F});
        if ((i + j) % 3 == 0) c.push_back({1.0F + 0.1F * static_cast<float>(i + 15), 2.5F + 0.1F * static_cast<float>(i + 15), 5.0F, 0.7F});
        if (j < 5 && (i * j) % 4 != 1) grid.update({i, j}, (i + j) % 2 == 0 ? 2.0F : -2.0F);
      }
    }
  }
};

struct Read {
  std::map<std::string, std::vector<std::vector<std::uint8_t>>> by_topic;
  std::map<std::string, std::vector<std::uint64_t>> log_times;  ///< [ns] per topic, as by_topic
  std::map<std::string, std::string> schema_of;
  mcap::Info info;
};

std::vector<std::uint8_t> from_base64(const std::string& text) {
  std::vector<std::uint8_t> out;
  std::uint32_t acc = 0;
  int bits = 0;
  for (const char ch : text) {
    const char* at = std::strchr("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/", ch);
    if (ch == '=' || at == nullptr) break;
    acc = (acc << 6) | static_cast<std::uint32_t>(at - "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/");
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<std::uint8_t>(acc >> bits));
    }
  }
  return out;
}

Read read_all(const std::vector<std::uint8_t>& file) {
  const mcap::Reader reader(mcap::memory_source(file), "scene.mcap");
  EXPECT_TRUE(reader.info().indexed);
  Read out;
  std::set<std::uint16_t> all;
  for (const auto& [id, ch] : reader.info().channels) {
    all.insert(id);
    out.schema_of[ch.topic] = reader.info().schemas.at(ch.schema_id).name;
  }
  for (const auto& ref : reader.messages(all)) {
    const std::string& topic = reader.info().channels.at(ref.channel).topic;
    out.by_topic[topic].push_back(reader.read(ref));
    out.log_times[topic].push_back(ref.log_time);
  }
  out.info = reader.info();
  return out;
}

std::vector<std::uint8_t> write(const HMap& map, const OccupancyGrid* grid, FoxgloveSceneStats* stats,
                                FoxgloveSceneParams params = {}, const PoseList& trajectory = {},
                                const std::vector<std::uint64_t>& stamps_ns = {}) {
  std::vector<std::uint8_t> file;
  *stats = write_foxglove_mcap(map, grid, trajectory, stamps_ns,
                               [&](std::span<const std::uint8_t> b) { file.insert(file.end(), b.begin(), b.end()); }, params);
  return file;
}

TEST(FoxgloveSceneTest, EveryTopicReadsBackAsWritten) {
  const SmallMap m;
  FoxgloveSceneParams params;
  params.tile_cells = 8;
  params.mcap.chunk_bytes = 4096;
  FoxgloveSceneStats stats;
  const auto file = write(m.map, &m.grid, &stats, params);
  EXPECT_EQ(stats.bytes, file.size());
  const Read r = read_all(file);
  EXPECT_EQ(r.schema_of.at("/map"), "nav_msgs/msg/OccupancyGrid");
  EXPECT_EQ(r.schema_of.at("/grid"), "foxglove.Grid");
  EXPECT_EQ(r.schema_of.at("/tf"), "tf2_msgs/msg/TFMessage");
  EXPECT_EQ(r.schema_of.at("/hvoxels"), "foxglove.SceneUpdate");
  EXPECT_EQ(r.schema_of.at("/points"), "foxglove.PointCloud");
  for (const auto& [topic, n] : stats.messages) EXPECT_EQ(r.by_topic.at(topic).size(), n) << topic;

  // /map: the grid image's bytes, 255 (unknown) being ROS's int8 -1.
  ASSERT_EQ(r.by_topic.at("/map").size(), 1U);
  const auto& grid_msg = r.by_topic.at("/map")[0];
  const std::string src = "/map", pos = "message 0";
  cdr::Reader c(grid_msg, src, pos);
  EXPECT_EQ(c.i32(), 0);
  EXPECT_EQ(c.u32(), 0U);
  EXPECT_EQ(c.string(), "map");
  (void)c.i32();
  (void)c.u32();
  const std::uint32_t resolution_bits = c.u32();
  float resolution = 0.0F;
  std::memcpy(&resolution, &resolution_bits, 4);
  const view::GridImage image = view::grid_image(m.grid);
  EXPECT_FLOAT_EQ(resolution, 0.5F);
  EXPECT_EQ(c.u32(), static_cast<std::uint32_t>(image.width));
  EXPECT_EQ(c.u32(), static_cast<std::uint32_t>(image.height));
  EXPECT_DOUBLE_EQ(c.f64(), image.origin.x());
  EXPECT_DOUBLE_EQ(c.f64(), image.origin.y());
  for (const double expected : {0.0, 0.0, 0.0, 0.0, 1.0}) EXPECT_DOUBLE_EQ(c.f64(), expected);
  const std::uint32_t n = c.count(1);
  const auto data = c.bytes(n);
  EXPECT_EQ(std::vector<std::uint8_t>(data.begin(), data.end()), image.cells);
  EXPECT_NE(std::count(image.cells.begin(), image.cells.end(), view::kUnknownCell), 0);

  // /grid: the same cells as float32 probabilities, NaN where unknown.
  {
    const auto& g = r.by_topic.at("/grid")[0];
    const auto gj = nlohmann::json::parse(g.begin(), g.end());
    EXPECT_EQ(gj["column_count"].get<int>(), image.width);
    EXPECT_EQ(gj["row_stride"].get<int>(), 4 * image.width);
    EXPECT_DOUBLE_EQ(gj["pose"]["position"]["x"].get<double>(), image.origin.x());
    const auto floats = from_base64(gj["data"].get<std::string>());
    ASSERT_EQ(floats.size(), 4 * image.cells.size());
    for (std::size_t k = 0; k < image.cells.size(); ++k) {
      float v = 0.0F;
      std::memcpy(&v, floats.data() + 4 * k, 4);
      if (image.cells[k] == view::kUnknownCell) {
        EXPECT_TRUE(std::isnan(v)) << k;
      } else {
        EXPECT_FLOAT_EQ(v, static_cast<float>(image.cells[k]) / 100.0F) << k;
      }
    }
  }

  // /tf: world -> map.
  std::vector<access::RawTransform> tf;
  cdr::decode_tf(r.by_topic.at("/tf")[0], false, tf, src, pos);
  ASSERT_EQ(tf.size(), 1U);
  EXPECT_EQ(tf[0].parent, "world");
  EXPECT_EQ(tf[0].child, "map");

  // /hvoxels: one entity per tile, every HVoxel a cube, each at its cell and height.
  std::set<std::string> ids;
  std::size_t cubes = 0;
  for (const auto& bytes : r.by_topic.at("/hvoxels")) {
    const auto j = nlohmann::json::parse(bytes.begin(), bytes.end());
    ASSERT_EQ(j["entities"].size(), 1U);
    const auto& e = j["entities"][0];
    EXPECT_TRUE(ids.insert(e["id"].get<std::string>()).second);
    EXPECT_EQ(e["frame_id"], "map");
    for (const auto& cube : e["cubes"]) {
      const double x = cube["pose"]["position"]["x"], y = cube["pose"]["position"]["y"], z = cube["pose"]["position"]["z"];
      const HVoxel* v = m.map.hvoxel_at(x, y, z);
      ASSERT_NE(v, nullptr) << x << " " << y << " " << z;
      EXPECT_NEAR(cube["size"]["z"].get<double>(), v->z_max - v->z_min, 1e-4);
      EXPECT_DOUBLE_EQ(cube["size"]["x"].get<double>(), 0.5);
      ++cubes;
    }
  }
  EXPECT_EQ(cubes, m.map.stats().hvoxels);
  EXPECT_EQ(stats.cubes, cubes);
  EXPECT_EQ(ids.size(), 4U * 4U);  // tiles of 8 cells: i in [-15, 15) and j in [-10, 10) both span tiles -2..1

  // /points: the recovered points, 12 bytes each, base64.
  const auto& pts = r.by_topic.at("/points")[0];
  const auto pj = nlohmann::json::parse(pts.begin(), pts.end());
  EXPECT_EQ(from_base64(pj["data"].get<std::string>()).size(), recover_points(m.map, 0.5).size() * 12);
  EXPECT_EQ(stats.points, recover_points(m.map, 0.5).size());
}

/// Three poses: along x, then turned 90 degrees about z, then lifted.
PoseList three_poses() {
  PoseList poses(3, Pose::Identity());
  poses[1].translation() = Eigen::Vector3d(1.5, 0.0, 0.0);
  poses[1].linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  poses[2].translation() = Eigen::Vector3d(1.5, -2.25, 0.125);
  return poses;
}

TEST(FoxgloveSceneTest, TheTrajectoryIsOnePosesInFrame) {
  const SmallMap m;
  const PoseList poses = three_poses();
  FoxgloveSceneStats stats;
  const Read r = read_all(write(m.map, &m.grid, &stats, {}, poses));
  EXPECT_EQ(r.schema_of.at("/trajectory"), "foxglove.PosesInFrame");
  ASSERT_EQ(r.by_topic.at("/trajectory").size(), 1U);
  const auto& bytes = r.by_topic.at("/trajectory")[0];
  const auto j = nlohmann::json::parse(bytes.begin(), bytes.end());
  EXPECT_EQ(j["frame_id"], "map");
  ASSERT_EQ(j["poses"].size(), 3U);
  for (std::size_t k = 0; k < 3; ++k) {
    const auto& p = j["poses"][k];
    const Eigen::Vector3d t(p["position"]["x"], p["position"]["y"], p["position"]["z"]);
    const Eigen::Quaterniond q(p["orientation"]["w"].get<double>(), p["orientation"]["x"].get<double>(),
                               p["orientation"]["y"].get<double>(), p["orientation"]["z"].get<double>());
    EXPECT_LT((t - poses[k].translation()).norm(), 1e-5) << k;
    EXPECT_LT(q.angularDistance(Eigen::Quaterniond(poses[k].rotation())), 1e-5) << k;
  }
}

/// A JSON message's "timestamp" {sec, nsec} in ns.
std::uint64_t json_ns(const nlohmann::json& stamp) {
  return stamp["sec"].get<std::uint64_t>() * 1'000'000'000ULL + stamp["nsec"].get<std::uint64_t>();
}

// Stamped poses: one /tf per pose at its stamp, header and log time, holding world -> map and
// map -> sensor at the pose; everything else at the latest stamp (here the first pose's: the
// stamps need not be sorted); the statistics span them.
TEST(FoxgloveSceneTest, EachPoseIsATfAtItsStampAndTheMapIsAtTheLatest) {
  const SmallMap m;
  const PoseList poses = three_poses();
  // Unix times in ns, past what a double holds exactly.
  const std::uint64_t t0 = 1'700'000'000'000'000'001ULL;
  const std::vector<std::uint64_t> stamps = {t0 + 500'000'007, t0, t0 + 350'000'000};
  const std::uint64_t latest = stamps[0];
  FoxgloveSceneParams params;
  params.tile_cells = 8;
  params.mcap.chunk_bytes = 4096;  // several chunks
  FoxgloveSceneStats stats;
  const Read r = read_all(write(m.map, &m.grid, &stats, params, poses, stamps));
  EXPECT_GT(r.info.chunks.size(), 2U);

  ASSERT_EQ(r.log_times.at("/tf"), stamps);
  EXPECT_EQ(stats.messages.at("/tf"), 3U);
  for (std::size_t k = 0; k < 3; ++k) {
    // Both transforms' header stamps, read from the CDR as written (int32 sec, uint32 nanosec).
    const auto& msg = r.by_topic.at("/tf")[k];
    const std::string src = "/tf", pos = "message " + std::to_string(k);
    cdr::Reader c(msg, src, pos);
    ASSERT_EQ(c.u32(), 2U);
    for (const auto& [parent, child] : {std::pair<std::string, std::string>{"world", "map"}, {"map", "sensor"}}) {
      const auto sec = static_cast<std::uint64_t>(c.i32());
      const auto nsec = static_cast<std::uint64_t>(c.u32());
      EXPECT_EQ(sec * 1'000'000'000ULL + nsec, stamps[k]) << k;
      EXPECT_EQ(c.string(), parent);
      EXPECT_EQ(c.string(), child);
      double v[7];
      for (double& x : v) x = c.f64();
      const Pose T = parent == "world" ? Pose::Identity() : poses[k];
      EXPECT_LT((Eigen::Vector3d(v[0], v[1], v[2]) - T.translation()).norm(), 1e-12) << k;
      EXPECT_LT(Eigen::Quaterniond(v[6], v[3], v[4], v[5]).angularDistance(Eigen::Quaterniond(T.rotation())), 1e-9) << k;
    }
  }
  for (const char* topic : {"/map", "/grid", "/hvoxels", "/points", "/trajectory"}) {
    ASSERT_FALSE(r.log_times.at(topic).empty()) << topic;
    for (const std::uint64_t t : r.log_times.at(topic)) EXPECT_EQ(t, latest) << topic;
  }
  // The stamps inside the messages: OccupancyGrid's header and map_load_time, the JSON timestamps.
  {
    const std::string src = "/map", pos = "message 0";
    cdr::Reader c(r.by_topic.at("/map")[0], src, pos);
    const auto sec = static_cast<std::uint64_t>(c.i32());
    EXPECT_EQ(sec * 1'000'000'000ULL + c.u32(), latest);
    EXPECT_EQ(c.string(), "map");
    const auto load_sec = static_cast<std::uint64_t>(c.i32());
    EXPECT_EQ(load_sec * 1'000'000'000ULL + c.u32(), latest);
  }
  for (const char* topic : {"/grid", "/points", "/trajectory"}) {
    const auto& bytes = r.by_topic.at(topic)[0];
    EXPECT_EQ(json_ns(nlohmann::json::parse(bytes.begin(), bytes.end())["timestamp"]), latest) << topic;
  }
  for (const auto& bytes : r.by_topic.at("/hvoxels")) {
    EXPECT_EQ(json_ns(nlohmann::json::parse(bytes.begin(), bytes.end())["entities"][0]["timestamp"]), latest);
  }
  // The statistics: from the earliest stamp to the latest, every message counted on its channel.
  EXPECT_EQ(r.info.start_time, t0);
  EXPECT_EQ(r.info.end_time, latest);
  std::uint64_t total = 0;
  for (const auto& [id, ch] : r.info.channels) {
    EXPECT_EQ(r.info.message_counts.at(id), stats.messages.at(ch.topic)) << ch.topic;
    total += stats.messages.at(ch.topic);
  }
  EXPECT_EQ(r.info.messages, total);
  for (const mcap::ChunkInfo& c : r.info.chunks) {
    EXPECT_EQ(c.start_time, c.index_start_time);
    EXPECT_EQ(c.end_time, c.index_end_time);
    EXPECT_LE(t0, c.start_time);
    EXPECT_LE(c.end_time, latest);
  }
}

// Without stamps every message is at 0, still one /tf per pose; a stamp count other than the
// poses' is refused.
TEST(FoxgloveSceneTest, WithoutStampsEverythingIsAtZero) {
  const SmallMap m;
  FoxgloveSceneStats stats;
  const Read r = read_all(write(m.map, &m.grid, &stats, {}, three_poses()));
  EXPECT_EQ(r.log_times.at("/tf").size(), 3U);
  for (const auto& [topic, times] : r.log_times) {
    for (const std::uint64_t t : times) EXPECT_EQ(t, 0U) << topic;
  }
  EXPECT_EQ(r.info.end_time, 0U);
  EXPECT_THROW(write(m.map, &m.grid, &stats, {}, three_poses(), {1, 2}), Error);
}

// Seconds to ns: whole seconds and the fraction apart, so a Unix time keeps its nanoseconds
// (t · 1e9 in one double rounds to 256 ns there); negative, non-finite and past-int32 refused.
TEST(FoxgloveSceneTest, StampsInSecondsBecomeNanoseconds) {
  // 1/512 s = 1953125 ns exactly, and these are exact doubles.
  const std::vector<double> s = {0.0, 1.5, 1700000000.0 + 3.0 / 512.0, 1700000000.0 + 511.0 / 512.0};
  const std::vector<std::uint64_t> ns = stamps_ns_of(s, "times.txt");
  EXPECT_EQ(ns, (std::vector<std::uint64_t>{0, 1'500'000'000ULL, 1'700'000'000'005'859'375ULL, 1'700'000'000'998'046'875ULL}));
  for (const double bad : {-0.5, std::nan(""), 2147483648.0, 1e300}) {
    try {
      (void)stamps_ns_of(std::vector<double>{1.0, bad}, "times.txt");
      ADD_FAILURE() << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("times.txt: stamp 2"), std::string::npos) << e.what();
    }
  }
}

TEST(FoxgloveSceneTest, TheSameMapGivesTheSameBytes) {
  const SmallMap a;
  // The same columns inserted in the reverse order of a's walk.
  std::vector<std::pair<CellKey, std::vector<HVoxel>>> columns;
  a.map.for_each_column([&](const CellKey& key, const ColumnView& c) { columns.emplace_back(key, std::vector<HVoxel>(c.begin(), c.end())); });
  HMap b(small_params());
  for (auto it = columns.rbegin(); it != columns.rend(); ++it) {
    auto c = b.column_for_update(it->first);
    for (const HVoxel& v : it->second) c.push_back(v);
  }
  FoxgloveSceneStats stats;
  EXPECT_EQ(write(a.map, &a.grid, &stats), write(b, &a.grid, &stats));
}

TEST(FoxgloveSceneTest, TheEmptyMapIsAFileWithItsFrameOnly) {
  const HMap map(small_params());
  FoxgloveSceneStats stats;
  const auto file = write(map, nullptr, &stats);
  const Read r = read_all(file);
  EXPECT_EQ(r.by_topic.size(), 1U);
  EXPECT_EQ(r.by_topic.at("/tf").size(), 1U);
  EXPECT_EQ(stats.cubes, 0U);
}

TEST(FoxgloveSceneTest, RefusesBadParameters) {
  const HMap map(small_params());
  FoxgloveSceneStats stats;
  FoxgloveSceneParams p;
  p.tile_cells = 0;
  EXPECT_THROW(write(map, nullptr, &stats, p), Error);
  p = {};
  p.parent_frame = p.frame;
  EXPECT_THROW(write(map, nullptr, &stats, p), Error);
  p = {};
  p.sensor_frame = p.frame;
  EXPECT_THROW(write(map, nullptr, &stats, p), Error);
  // A stamp past int32 seconds (builtin_interfaces/Time) would wrap in the ROS headers.
  const PoseList one(1, Pose::Identity());
  EXPECT_THROW(write(map, nullptr, &stats, {}, one, {2'147'483'647ULL * 1'000'000'000ULL}), Error);
  EXPECT_NO_THROW(write(map, nullptr, &stats, {}, one, {2'147'483'646ULL * 1'000'000'000ULL}));
}

/// The ecosystem's reader (tests/ros2/read_mcap.js: @mcap/core's indexed and streaming readers,
/// CDR by @foxglove/rosmsg2-serialization, JSON.parse) on the same file, with stamped poses: the
/// script checks every stamp inside a message against its log time, the statistics and each
/// chunk's times and Message Indexes against the messages; here the log times against the stamps.
TEST(FoxgloveSceneTest, McapCoreReadsAndDecodesEveryMessage) {
  const fs::path scripts = HMAP_ROS2_SCRIPTS_DIR;
  if (std::system("node --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "node is not installed (Debian: nodejs)";
  if (!fs::exists(scripts / "node_modules" / "@mcap" / "core")) {
    GTEST_SKIP() << "the npm packages are absent: run `make ros2-test-deps` (npm ci --prefix tests/ros2)";
  }
  const SmallMap m;
  FoxgloveSceneParams params;
  params.tile_cells = 8;
  params.mcap.chunk_bytes = 4096;
  FoxgloveSceneStats stats;
  const std::vector<std::uint64_t> stamps = {1'700'000'000'000'000'001ULL, 1'700'000'000'250'000'003ULL,
                                             1'700'000'001'000'000'007ULL};
  const auto file = write(m.map, &m.grid, &stats, params, three_poses(), stamps);
  const fs::path dir = test::temp_dir("foxglove_scene");
  const fs::path path = dir / "scene.mcap";
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(file.data()), static_cast<std::streamsize>(file.size()));
  const std::string cmd = "node " + (scripts / "read_mcap.js").string() + " " + path.string() + " > " + (dir / "out.json").string();
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(dir / "out.json");
  const auto j = nlohmann::json::parse(in);
  for (const auto& [topic, n] : stats.messages) EXPECT_EQ(j["topics"][topic]["messages"].get<std::uint64_t>(), n) << topic;
  EXPECT_EQ(j["topics"].size(), stats.messages.size());
  EXPECT_EQ(j["cubes"].get<std::uint64_t>(), stats.cubes);
  EXPECT_EQ(j["points"].get<std::uint64_t>(), stats.points);
  const view::GridImage image = view::grid_image(m.grid);
  EXPECT_EQ(j["grid"]["width"].get<int>(), image.width);
  EXPECT_EQ(j["grid"]["height"].get<int>(), image.height);
  EXPECT_EQ(j["grid"]["unknown"].get<long>(), std::count(image.cells.begin(), image.cells.end(), view::kUnknownCell));
  EXPECT_EQ(j["foxglove_grid_cells"].get<std::size_t>(), image.cells.size());
  EXPECT_EQ(j["poses"].get<int>(), 3);
  EXPECT_EQ(j["tf"][0], "world->map");
  EXPECT_EQ(j["tf"][1], "map->sensor");
  EXPECT_EQ(j["streamed_messages"].get<std::uint64_t>(), j["messages"].get<std::uint64_t>());
  EXPECT_EQ(j["statistics_messages"].get<std::uint64_t>(), j["messages"].get<std::uint64_t>());
  // Log times (decimal strings: past 2^53): /tf at each pose's stamp, the rest at the last.
  std::vector<std::string> tf_times;
  for (const std::uint64_t t : stamps) tf_times.push_back(std::to_string(t));
  EXPECT_EQ(j["log_times"]["/tf"].get<std::vector<std::string>>(), tf_times);
  for (const auto& [topic, times] : j["log_times"].items()) {
    if (topic == "/tf") continue;
    for (const auto& t : times) EXPECT_EQ(t.get<std::string>(), std::to_string(stamps.back())) << topic;
  }
  EXPECT_EQ(j["statistics"]["start"].get<std::string>(), std::to_string(stamps.front()));
  EXPECT_EQ(j["statistics"]["end"].get<std::string>(), std::to_string(stamps.back()));
  // Stamps inside the messages checked: two per /tf, one per other message (per entity for /hvoxels).
  EXPECT_EQ(j["stamps_checked"].get<std::uint64_t>(), j["messages"].get<std::uint64_t>() + 3);
  EXPECT_GT(j["chunks_checked"].get<int>(), 2);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hmap::ros
