// The hmap command line end to end: exit codes, one-line errors, outputs that load.

#include <gtest/gtest.h>

#include <set>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>
#include <sys/wait.h>

#include "apps/cli_run.hpp"
#include "common/test_data.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/maps/map_merge.hpp"
#include "hmap/io/pcd.hpp"

namespace hmap {
namespace {

using test::CmdResult;
using test::lines;
using test::run;

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::temp_dir("cli"); }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::filesystem::path dir_;
};

TEST_F(CliTest, NoArgumentsIsAnError) {
  const CmdResult r = run("");
  EXPECT_EQ(r.code, 2);
}

TEST_F(CliTest, MapWithoutPosesPointsToSlam) {
  std::ofstream(path("a.xyz")) << "1 2 3\n4 5 6\n";
  const CmdResult r = run("map " + path("a.xyz") + " --out " + path("m.hmap"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("hmap slam"), std::string::npos) << r.out;
  EXPECT_EQ(lines(r.out), 1U) << r.out;
  EXPECT_FALSE(std::filesystem::exists(path("m.hmap")));
}

TEST_F(CliTest, MissingScanFileIsNamed) {
  std::ofstream(path("p.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const CmdResult r = run("map " + path("nope.pcd") + " --poses " + path("p.txt") + " --out " + path("m.hmap"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("nope.pcd"), std::string::npos) << r.out;
  EXPECT_EQ(lines(r.out), 1U) << r.out;
}

TEST_F(CliTest, PoseCountMismatchNamesBothCounts) {
  std::ofstream(path("a.xyz")) << "1 2 3\n";
  std::ofstream(path("b.xyz")) << "1 2 3\n";
  std::ofstream(path("p.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const CmdResult r = run("map " + path("a.xyz") + " " + path("b.xyz") + " --poses " + path("p.txt") + " --out " + path("m.hmap"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("p.txt"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("1 poses for 2 scans"), std::string::npos) << r.out;
}

TEST_F(CliTest, NegativeCellSizeIsRefused) {
  std::ofstream(path("a.xyz")) << "1 2 3\n";
  std::ofstream(path("p.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const CmdResult r = run("map " + path("a.xyz") + " --poses " + path("p.txt") + " --cell -0.1 --out " + path("m.hmap"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("map.cell_size"), std::string::npos) << r.out;
  EXPECT_EQ(lines(r.out), 1U) << r.out;
}

TEST_F(CliTest, AbsurdRangeIsRefused) {
  std::ofstream(path("a.xyz")) << "1 2 3\n";
  std::ofstream(path("p.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const CmdResult r = run("map " + path("a.xyz") + " --poses " + path("p.txt") + " --max-range 1e9 --out " + path("m.hmap"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("map.max_range"), std::string::npos) << r.out;
}

TEST_F(CliTest, UnknownConfigKeyNamesFileAndLine) {
  std::ofstream(path("c.yaml")) << "map:\n  cell_size: 0.1\n  cel_size: 0.2\n";
  std::ofstream(path("a.xyz")) << "1 2 3\n";
  std::ofstream(path("p.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const CmdResult r = run("map " + path("a.xyz") + " --poses " + path("p.txt") + " --config " + path("c.yaml") + " --out " + path("m.hmap"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("c.yaml: line 3"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("map.cel_size"), std::string::npos) << r.out;
}

TEST_F(CliTest, CorruptMapIsRejected) {
  std::ofstream(path("bad.hmap")) << "not a map at all";
  const CmdResult r = run("info " + path("bad.hmap"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("bad.hmap"), std::string::npos) << r.out;
  EXPECT_EQ(lines(r.out), 1U) << r.out;
}

TEST_F(CliTest, MapInfoExportOnRealScans) {
  HMAP_REQUIRE_DATA("balm_os0");
  const std::string seq = (test::data_dir() / "balm_os0").string();
  const CmdResult m = run("map --kitti " + seq + " --scans 4 --cell 0.2 --out " + path("m.hmap"));
  ASSERT_EQ(m.code, 0) << m.out;
  EXPECT_NE(m.out.find("Mapped 4 scans"), std::string::npos) << m.out;
  const HMap loaded = load_hmap(path("m.hmap"));
  EXPECT_GT(loaded.stats().hvoxels, 1000U);

  const CmdResult info = run("info --json " + path("m.hmap"));
  ASSERT_EQ(info.code, 0) << info.out;
  const auto j = nlohmann::json::parse(info.out);
  EXPECT_EQ(j.at("cells").get<std::size_t>(), loaded.stats().cells);
  EXPECT_EQ(j.at("hvoxels").get<std::size_t>(), loaded.stats().hvoxels);
  EXPECT_GT(j.at("memory_bytes").get<std::size_t>(), 0U);
  EXPECT_DOUBLE_EQ(j.at("parameters").at("map.cell_size").get<double>(), 0.2);

  const CmdResult boxes = run("export " + path("m.hmap") + " --ply " + path("boxes.ply"));
  ASSERT_EQ(boxes.code, 0) << boxes.out;
  const CmdResult pts = run("export " + path("m.hmap") + " --ply " + path("pts.ply") + " --points");
  ASSERT_EQ(pts.code, 0) << pts.out;
  std::ifstream ply(path("boxes.ply"));
  std::string first;
  std::getline(ply, first);
  EXPECT_EQ(first, "ply");
}

TEST_F(CliTest, BenchPrintsOneJsonObjectPerSystem) {
  HMAP_REQUIRE_DATA("kitti_hdl64_seq16");
  const std::string seq = (test::data_dir() / "kitti_hdl64_seq16").string();
  const CmdResult r = run("bench --kitti " + seq + " --scans 1 --cell 0.4 --max-range 30 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  std::istringstream in(r.out);
  std::string line;
  std::vector<std::string> systems;
  while (std::getline(in, line)) {
    const auto j = nlohmann::json::parse(line);
    systems.push_back(j.at("system").get<std::string>());
    EXPECT_EQ(j.at("scans").get<int>(), 1);
    EXPECT_GT(j.at("points").get<double>(), 100000.0);
    EXPECT_GT(j.at("ms_per_scan").get<double>(), 0.0);
    EXPECT_GT(j.at("cpu_ms_per_scan").get<double>(), 0.0);  // all threads' user + system time
    EXPECT_GT(j.at("points_per_s").get<double>(), 0.0);
    EXPECT_GT(j.at("memory_bytes").get<double>(), 0.0);
    EXPECT_TRUE(j.contains("heap_bytes"));
  }
  EXPECT_EQ(systems, (std::vector<std::string>{"hmap", "octomap"}));
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

TEST_F(CliTest, SimulateWritesASequenceThatMapsAndEvaluates) {
  const CmdResult sim = run("simulate --scene office --sensor kinect --frames 6 --stride 5 --seed 3 --out " + path("seq"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  for (const char* f : {"poses.txt", "times.txt", "odometry.txt", "truth.ply", "truth_seen.ply", "velodyne/000005.bin"}) {
    EXPECT_TRUE(std::filesystem::exists(dir_ / "seq" / f)) << f;
  }
  const CmdResult m = run("map --kitti " + path("seq") + " --preset indoor --out " + path("m.hmap"));
  ASSERT_EQ(m.code, 0) << m.out;
  const CmdResult e = run("eval map --map " + path("m.hmap") + " --truth " + path("seq") + " --json");
  ASSERT_EQ(e.code, 0) << e.out;
  const auto j = nlohmann::json::parse(e.out);
  // Office, Kinect, 5 cm cells: measured 1.00 / 0.96 within one voxel, Chamfer 0.023 m.
  EXPECT_GT(j.at("tolerant").at("precision").get<double>(), 0.95);
  EXPECT_GT(j.at("tolerant").at("recall").get<double>(), 0.9);
  EXPECT_LT(j.at("chamfer_m").get<double>(), 0.05);
  // Same seed, same bytes.
  const CmdResult again = run("simulate --scene office --sensor kinect --frames 6 --stride 5 --seed 3 --out " + path("seq2"));
  ASSERT_EQ(again.code, 0) << again.out;
  std::ifstream a(dir_ / "seq" / "velodyne" / "000003.bin", std::ios::binary);
  std::ifstream b(dir_ / "seq2" / "velodyne" / "000003.bin", std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(a), {}), std::string(std::istreambuf_iterator<char>(b), {}));
}

TEST_F(CliTest, EvalTrajReportsTheKnownOffset) {
  std::ofstream(path("gt.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n1 0 0 2 0 1 0 0 0 0 1 0\n";
  std::ofstream(path("est.txt")) << "1 0 0 0 0 1 0 0.5 0 0 1 0\n1 0 0 1 0 1 0 0.5 0 0 1 0\n1 0 0 2 0 1 0 0.5 0 0 1 0\n";
  const CmdResult r = run("eval traj --gt " + path("gt.txt") + " --est " + path("est.txt") + " --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_NEAR(j.at("ate_rmse_m").get<double>(), 0.5, 1e-9);
  EXPECT_NEAR(j.at("ate_rmse_aligned_m").get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(j.at("rpe_trans_pct").get<double>(), 0.0, 1e-9);
  EXPECT_TRUE(j.contains("rpe_rot_deg_per_m"));
  std::ofstream(path("short.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const CmdResult bad = run("eval traj --gt " + path("gt.txt") + " --est " + path("short.txt"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.out.find("short.txt"), std::string::npos) << bad.out;
}

TEST_F(CliTest, EvalTrajDrawsTheTrajectoriesWhenAsked) {
  std::ofstream(path("gt.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n1 0 0 2 0 1 0 0 0 0 1 0\n";
  std::ofstream(path("est.txt")) << "1 0 0 0 0 1 0 0.5 0 0 1 0\n1 0 0 1 0 1 0 0.5 0 0 1 0\n1 0 0 2 0 1 0 0.7 0 0 1 0\n";
  std::ofstream(path("peer.txt")) << "1 0 0 5 0 1 0 5 0 0 1 0\n1 0 0 6 0 1 0 5 0 0 1 0\n";
  const CmdResult r = run("eval traj --gt " + path("gt.txt") + " --est " + path("est.txt") + " --plot " + path("t.png") +
                          " --plot-path " + path("peer.txt") + "=peer");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("ATE RMSE"), std::string::npos) << r.out;  // the figures as without --plot
  // Every path from its first pose: x in [0, 2], y in [0, 0.2], widened by 1 m: 4 m x 2.2 m, 1200
  // px wide (the PNG's IHDR: width and height, big-endian, at bytes 16 and 20), the legend beside.
  std::ifstream png(path("t.png"), std::ios::binary);
  std::array<unsigned char, 24> head{};
  png.read(reinterpret_cast<char*>(head.data()), head.size());
  ASSERT_TRUE(png.good());
  const auto be32 = [&](int at) {
    return (std::uint32_t{head[at]} << 24) | (std::uint32_t{head[at + 1]} << 16) | (std::uint32_t{head[at + 2]} << 8) | head[at + 3];
  };
  EXPECT_GT(be32(16), 1200U);
  EXPECT_GE(be32(20), 660U);
  // Bad requests: one line, exit 2, nothing written.
  const CmdResult not_png = run("eval traj --gt " + path("gt.txt") + " --est " + path("est.txt") + " --plot " + path("t.jpg"));
  EXPECT_EQ(not_png.code, 2);
  EXPECT_NE(not_png.out.find("t.jpg: --plot writes a PNG picture; give a name ending in .png"), std::string::npos) << not_png.out;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "t.jpg"));
  const CmdResult no_label = run("eval traj --gt " + path("gt.txt") + " --est " + path("est.txt") + " --plot " + path("u.png") +
                                 " --plot-path " + path("peer.txt") + "=");
  EXPECT_EQ(no_label.code, 2);
  EXPECT_NE(no_label.out.find("expected FILE or FILE=LABEL"), std::string::npos) << no_label.out;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "u.png"));
  const CmdResult missing = run("eval traj --gt " + path("gt.txt") + " --est " + path("est.txt") + " --plot " + path("v.png") +
                                " --plot-path " + path("none.txt"));
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.out.find("none.txt"), std::string::npos) << missing.out;
  const CmdResult without_plot = run("eval traj --gt " + path("gt.txt") + " --est " + path("est.txt") + " --plot-path " + path("peer.txt"));
  EXPECT_EQ(without_plot.code, 2);  // --plot-path needs --plot
  EXPECT_NE(without_plot.out.find("--plot-path requires --plot"), std::string::npos) << without_plot.out;
}

TEST_F(CliTest, DemoWritesMapPicturesAndReport) {
  const CmdResult r = run("demo --frames 20 --out " + path("demo"));
  ASSERT_EQ(r.code, 0) << r.out;
#ifdef HMAP_HAVE_VIEW
  EXPECT_NE(r.out.find("hmap view " + path("demo") + "/map.hmap"), std::string::npos) << r.out;  // how to see it
#endif
  for (const char* f : {"report.md", "map.hmap", "map_hvoxels.ply", "map_top.png", "map_oblique.png", "sequence/poses.txt"}) {
    EXPECT_TRUE(std::filesystem::exists(dir_ / "demo" / f)) << f;
  }
  const CmdResult render = run("render " + path("demo/map.hmap") + " --trajectory " + path("demo/sequence/poses.txt") +
                               " --out " + path("t.png"));
  EXPECT_EQ(render.code, 0) << render.out;
  // The 2D occupancy as map_server reads it (the ground search starts in the middle of the map).
  const CmdResult pgm = run("export " + path("demo/map.hmap") + " --pgm " + path("grid"));
  ASSERT_EQ(pgm.code, 0) << pgm.out;
  std::ifstream yaml(dir_ / "grid.yaml");
  const std::string y((std::istreambuf_iterator<char>(yaml)), {});
  EXPECT_NE(y.find("image: grid.pgm"), std::string::npos) << y;
  std::ifstream img(dir_ / "grid.pgm", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(img)), {});
  EXPECT_EQ(bytes.substr(0, 3), "P5\n");
  EXPECT_NE(bytes.find(static_cast<char>(0)), std::string::npos) << "some cell is occupied";
  EXPECT_NE(bytes.find(static_cast<char>(254)), std::string::npos) << "some cell is free";
}

}  // namespace
}  // namespace hmap

#include <octomap/OcTree.h>

namespace hmap {
namespace {

TEST_F(CliTest, ExportsAnOctoMapThatOctomapReadsBack) {
  HMap map(indoor_preset());
  map.column_for_update({3, -2}).push_back({0.0F, 0.4F, 50.0F, 0.9F});
  map.column_for_update({3, -2}).push_back({1.0F, 1.02F, 5.0F, 0.5F});
  map.column_for_update({-7, 5}).push_back({-0.3F, -0.3F, 1.0F, 0.3F});
  save_hmap(path("m.hmap"), map);
  const CmdResult r = run("export " + path("m.hmap") + " --bt " + path("m.bt"));
  ASSERT_EQ(r.code, 0) << r.out;
  octomap::OcTree tree(path("m.bt"));
  EXPECT_DOUBLE_EQ(tree.getResolution(), map.cell_size());
  const auto occupied = [&](double x, double y, double z) {
    const octomap::OcTreeNode* n = tree.search(x, y, z);
    return n != nullptr && tree.isNodeOccupied(n);
  };
  const Eigen::Vector2d a = map.cell_center({3, -2});
  const Eigen::Vector2d b = map.cell_center({-7, 5});
  for (double z = 0.01; z < 0.4; z += 0.05) EXPECT_TRUE(occupied(a.x(), a.y(), z)) << z;
  EXPECT_TRUE(occupied(a.x(), a.y(), 1.01));
  EXPECT_FALSE(occupied(a.x(), a.y(), 0.7));  // the gap between the two HVoxels
  EXPECT_TRUE(occupied(b.x(), b.y(), static_cast<double>(-0.3F)));  // the HVoxel's own float height
  EXPECT_FALSE(occupied(b.x() + 1.0, b.y(), -0.3));
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

// The hybrid map end to end on a small simulated office (Kinect, tables): `map` keeps the ground
// patches and the 2D grid in the file, `export --pgm` writes that grid, `render` draws its layers,
// and `compare` scores HMAP against the 2.5D map on the same scans.
TEST_F(CliTest, HybridMapExportsItsGridAndCompareScoresIt) {
  const CmdResult sim = run("simulate --scene office --sensor kinect --frames 12 --stride 4 --seed 2 --out " + path("seq"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  const CmdResult m = run("map --kitti " + path("seq") + " --preset indoor --set occupancy.z_plus=0.5 --out " + path("m.hmap"));
  ASSERT_EQ(m.code, 0) << m.out;
  const MapFile file = load_map_file(path("m.hmap"));
  ASSERT_TRUE(file.grid.has_value());
  EXPECT_GT(file.grid->known_cells(), 1000U);
  EXPECT_FALSE(file.ground.empty());

  const CmdResult pgm = run("export " + path("m.hmap") + " --pgm " + path("grid"));
  ASSERT_EQ(pgm.code, 0) << pgm.out;
  EXPECT_NE(pgm.out.find("the map's own 2D grid and its columns judged"), std::string::npos) << pgm.out;
  // The traversability layers beside it: a costmap whose lethal cells cover the grid's occupied ones,
  // and the ground height as a GeoTIFF.
  const CmdResult cost = run("export " + path("m.hmap") + " --costmap " + path("cost") + " --geotiff " + path("g.tif") +
                             " --inflation 0.1");
  ASSERT_EQ(cost.code, 0) << cost.out;
  EXPECT_NE(cost.out.find("lethal"), std::string::npos) << cost.out;
  EXPECT_NE(cost.out.find("ground height of"), std::string::npos) << cost.out;
  {
    std::ifstream g(dir_ / "grid.pgm", std::ios::binary), c(dir_ / "cost.pgm", std::ios::binary);
    const std::string gb((std::istreambuf_iterator<char>(g)), {}), cb((std::istreambuf_iterator<char>(c)), {});
    const auto body = [](const std::string& b) { std::size_t at = 0; for (int n = 0; n < 4; ++n) at = b.find('\n', at) + 1; return b.substr(at); };
    const std::string gp = body(gb), cp = body(cb);
    ASSERT_EQ(gp.size(), cp.size());  // the same box of cells
    std::size_t occupied = 0;
    for (std::size_t k = 0; k < gp.size(); ++k) {
      if (gp[k] != '\0') continue;
      ++occupied;
      EXPECT_EQ(cp[k], '\0') << "occupied cell " << k << " is not lethal in the costmap";
    }
    EXPECT_GT(occupied, 0U);
  }
  const CmdResult bad_slope = run("export " + path("m.hmap") + " --costmap " + path("bad") + " --max-slope 0");
  EXPECT_EQ(bad_slope.code, 2) << bad_slope.out;
  EXPECT_NE(bad_slope.out.find("max_slope"), std::string::npos) << bad_slope.out;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "bad.pgm"));
  const CmdResult kept = run("export " + path("m.hmap") + " --pgm " + path("kept") + " --grid kept");
  ASSERT_EQ(kept.code, 0) << kept.out;
  EXPECT_NE(kept.out.find("kept scan by scan"), std::string::npos) << kept.out;
  // The combined grid holds every obstacle of the kept one, and more.
  const auto black_pixels = [&](const char* name) {
    std::ifstream f(dir_ / name, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(f)), {});
    return std::count(bytes.begin(), bytes.end(), '\0');  // 0 never occurs in the ASCII header
  };
  EXPECT_GE(black_pixels("grid.pgm"), black_pixels("kept.pgm"));
  EXPECT_GT(black_pixels("kept.pgm"), 0);
  for (const char* layer : {"occupancy", "ground"}) {
    const CmdResult r = run("render " + path("m.hmap") + " --layer " + layer + " --out " + path(std::string(layer) + ".png"));
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_TRUE(std::filesystem::exists(dir_ / (std::string(layer) + ".png"))) << layer;
  }
  // A map built without the hybrid layers says so instead of drawing nothing.
  const CmdResult plain = run("map --kitti " + path("seq") + " --preset indoor --hvoxels-only --scans 2 --out " + path("p.hmap"));
  ASSERT_EQ(plain.code, 0) << plain.out;
  EXPECT_FALSE(load_map_file(path("p.hmap")).grid.has_value());
  const CmdResult no_grid = run("render " + path("p.hmap") + " --layer occupancy --out " + path("x.png"));
  EXPECT_EQ(no_grid.code, 2);
  EXPECT_NE(no_grid.out.find("p.hmap"), std::string::npos) << no_grid.out;
  EXPECT_EQ(lines(no_grid.out), 1U) << no_grid.out;

  // A robot 0.5 m tall passes under the tables: HMAP's grid (z+ = 0.5 m) sees the floor under
  // them free, the 2.5D map (one height per cell: the table top) blocks it.
  // One run with --json: its lines go to stdout, report.json and the pictures to --out. (The
  // compare costs minutes under ASan; running it once keeps the sanitizer job short.)
  const CmdResult c = run("compare --kitti " + path("seq") + " --truth " + path("seq") +
                          " --preset indoor --robot-height 0.5 --set occupancy.z_plus=0.5 --elevation-ceiling 1.0 "
                          "--max-pixels 200 --json --out " + path("cmp"));
  ASSERT_EQ(c.code, 0) << c.out;
  for (const char* f : {"report.md", "report.json", "compare_top.png", "compare_oblique.png", "hmap.hmap"}) {
    EXPECT_TRUE(std::filesystem::exists(dir_ / "cmp" / f)) << f;
  }
  std::ifstream in(dir_ / "cmp" / "report.json");
  const auto j = nlohmann::json::parse(in);
  for (const char* s : {"HMAP", "2.5D [9]", "OctoMap"}) ASSERT_TRUE(j.at("systems").contains(s)) << s;
  const auto& hm = j.at("grid_2d").at("hmap");
  const auto& el = j.at("grid_2d").at("elevation_25d");
  ASSERT_GT(hm.at("overhang_cells").get<std::size_t>(), 20U);
  EXPECT_GT(hm.at("overhang_free").get<double>(), el.at("overhang_free").get<double>() + 0.3);
  EXPECT_GE(hm.at("accuracy").get<double>(), el.at("accuracy").get<double>());
  EXPECT_GT(j.at("systems").at("HMAP").at("recall_1voxel").get<double>(),
            j.at("systems").at("2.5D [9]").at("recall_1voxel").get<double>());
  ASSERT_TRUE(j.at("grid_2d").contains("octomap_projected"));

  // --json: one line per system and grid, the same numbers as report.json.
  const CmdResult& cj = c;
  std::istringstream json_lines(cj.out);
  std::string text;
  std::set<std::string> grids;
  while (std::getline(json_lines, text)) {
    if (text.empty() || text.front() != '{') continue;  // progress on a terminal only; nothing else expected
    const auto line = nlohmann::json::parse(text);
    const std::string key = line.at("system").get<std::string>() + "/" + line.at("grid").get<std::string>();
    grids.insert(key);
    if (line.at("grid") == "3d") continue;
    for (const char* field : {"blocked_found", "free_found", "overhang_free", "accuracy"}) {
      ASSERT_TRUE(line.contains(field)) << key << " " << field;
    }
    if (key == "HMAP/kept") {
      EXPECT_DOUBLE_EQ(line.at("overhang_free").get<double>(), hm.at("overhang_free").get<double>());
    }
  }
  for (const char* g : {"HMAP/kept", "HMAP/judged", "HMAP/both", "2.5D [9]/judged", "OctoMap/projected", "HMAP/3d",
                        "2.5D [9]/3d", "OctoMap/3d"}) {
    EXPECT_TRUE(grids.contains(g)) << g << " missing from\n" << cj.out;
  }
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

// RGB-D frames feed every command, not only `map`: SLAM takes the camera poses' attitude, PVOX
// the poses as its measurements.
// slam --loop-closure: a short drive closes nothing, says so and writes the (empty) table of
// closures; conflicting flags and a bad loop parameter are one line each.
TEST_F(CliTest, SlamLoopClosureFlagsAndSummary) {
  const CmdResult sim = run("simulate --scene parking --sensor vlp16 --frames 6 --stride 5 --out " + path("seq"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  const CmdResult on = run("slam --kitti " + path("seq") + " --loop-closure --out " + path("slam"));
  ASSERT_EQ(on.code, 0) << on.out;
  EXPECT_NE(on.out.find("Loop closure: "), std::string::npos) << on.out;
  EXPECT_NE(on.out.find(" 0 loops closed"), std::string::npos) << on.out;
  std::ifstream csv(dir_ / "slam" / "loop_closures.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header.rfind("keyframe_old,keyframe_new,scan_old,scan_new,", 0), 0U) << header;
  const CmdResult off = run("slam --kitti " + path("seq") + " --no-loop-closure --out " + path("slam_off"));
  ASSERT_EQ(off.code, 0) << off.out;
  EXPECT_EQ(off.out.find("Loop closure: "), std::string::npos) << off.out;
  const CmdResult both = run("slam --kitti " + path("seq") + " --loop-closure --no-loop-closure --out " + path("x"));
  EXPECT_EQ(both.code, 2);
  EXPECT_EQ(lines(both.out), 1U) << both.out;
  const CmdResult bad = run("slam --kitti " + path("seq") + " --set slam.loop_min_score=2 --out " + path("x"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_EQ(lines(bad.out), 1U) << bad.out;
  EXPECT_NE(bad.out.find("slam.loop_min_score"), std::string::npos) << bad.out;
}

namespace {

/// One column of a CSV file with a header line, as text, row by row. A test failure when the
/// column is missing or a row has another number of cells than the header.
std::vector<std::string> csv_column(const std::filesystem::path& file, const std::string& name) {
  const auto cells = [](const std::string& line) {
    std::vector<std::string> out;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) out.push_back(c);
    return out;
  };
  std::ifstream csv(file);
  std::string header;
  std::getline(csv, header);
  const std::vector<std::string> names = cells(header);
  const auto at = std::find(names.begin(), names.end(), name);
  EXPECT_NE(at, names.end()) << file << ": " << header;
  std::vector<std::string> values;
  if (at == names.end()) return values;
  for (std::string line; std::getline(csv, line);) {
    const std::vector<std::string> row = cells(line);
    EXPECT_EQ(row.size(), names.size()) << file << ": " << line;
    if (row.size() == names.size()) values.push_back(row[static_cast<std::size_t>(at - names.begin())]);
  }
  return values;
}

}  // namespace

// slam --set slam.wall_refine=1: the summary says how many matches the walls refined, matches.csv
// has a wall_* row per scan (the first scan: none); a bad value is one line naming the parameter.
TEST_F(CliTest, SlamWallRefinementSummaryAndColumns) {
  const CmdResult sim = run("simulate --scene office --sensor os0-64 --frames 6 --stride 3 --out " + path("seq"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  const CmdResult on = run("slam --kitti " + path("seq") + " --set slam.wall_refine=1 --no-loop-closure --out " + path("w"));
  ASSERT_EQ(on.code, 0) << on.out;
  EXPECT_NE(on.out.find("Walls (slam.wall_refine): "), std::string::npos) << on.out;
  const std::vector<std::string> refined = csv_column(dir_ / "w" / "matches.csv", "wall_refined");
  ASSERT_EQ(refined.size(), 6U);
  EXPECT_EQ(refined[0], "0");  // the first scan defines the map
  EXPECT_GE(std::count(refined.begin(), refined.end(), "1"), 1);  // the office's walls refine the matches
  const CmdResult off = run("slam --kitti " + path("seq") + " --no-loop-closure --out " + path("off"));
  ASSERT_EQ(off.code, 0) << off.out;
  EXPECT_EQ(off.out.find("Walls (slam.wall_refine)"), std::string::npos) << off.out;
  const CmdResult bad = run("slam --kitti " + path("seq") + " --set slam.wall_band_height=0 --out " + path("x"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_EQ(lines(bad.out), 1U) << bad.out;
  EXPECT_NE(bad.out.find("slam.wall_band_height"), std::string::npos) << bad.out;
}

// slam.wall_tilt_drift (on by default): matches.csv says per scan how far the walls' lean turned
// the tilt and over how many walls, the summary on how many scans; off (0) both columns are 0 on
// every row.
TEST_F(CliTest, SlamWallTiltColumns) {
  const CmdResult sim = run("simulate --scene office --sensor os0-64 --frames 6 --stride 3 --out " + path("seq"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  const CmdResult on = run("slam --kitti " + path("seq") + " --no-loop-closure --out " + path("on"));
  ASSERT_EQ(on.code, 0) << on.out;
  const std::vector<std::string> tilt = csv_column(dir_ / "on" / "matches.csv", "wall_tilt");
  const std::vector<std::string> walls = csv_column(dir_ / "on" / "matches.csv", "wall_tilt_walls");
  ASSERT_EQ(tilt.size(), 6U);
  ASSERT_EQ(walls.size(), 6U);
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_GT(std::stod(walls[k]), 10.0) << k;  // the office's walls, on every scan (the first levels the map)
    const double t = std::stod(tilt[k]);
    EXPECT_TRUE(t >= 0.0 && t < 0.05) << k << ": " << tilt[k];
  }
  EXPECT_NE(on.out.find("the walls' lean held it to gravity on 6 of 6 scans"), std::string::npos) << on.out;
  const CmdResult off = run("slam --kitti " + path("seq") + " --set slam.wall_tilt_drift=0 --no-loop-closure --out " + path("off"));
  ASSERT_EQ(off.code, 0) << off.out;
  for (const std::string& v : csv_column(dir_ / "off" / "matches.csv", "wall_tilt")) EXPECT_EQ(std::stod(v), 0.0);
  for (const std::string& v : csv_column(dir_ / "off" / "matches.csv", "wall_tilt_walls")) EXPECT_EQ(v, "0");
  EXPECT_NE(off.out.find("estimated from the scans (floor normal + map surfaces)."), std::string::npos) << off.out;
}

TEST_F(CliTest, SlamAndPvoxReadRgbdFrames) {
  HMAP_REQUIRE_DATA("rgbd_7scenes");
  const std::string rgbd = (test::data_dir() / "rgbd_7scenes").string();
  const CmdResult s = run("slam --rgbd " + rgbd + " --preset indoor --scans 4 --out " + path("slam"));
  ASSERT_EQ(s.code, 0) << s.out;
  std::ifstream poses(dir_ / "slam" / "poses.txt");
  std::size_t n = 0;
  for (std::string line; std::getline(poses, line);) n += line.empty() ? 0 : 1;
  EXPECT_EQ(n, 4U);
  const CmdResult p = run("pvox --rgbd " + rgbd + " --max-scans 2 --out " + path("pvox"));
  ASSERT_EQ(p.code, 0) << p.out;
  EXPECT_TRUE(std::filesystem::exists(dir_ / "pvox" / "map.pvox"));
  // --odometry source without a sensor source is refused in one line.
  const CmdResult bad = run("slam --kitti " + path("none") + " --odometry source --out " + path("x"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_EQ(lines(bad.out), 1U) << bad.out;
  EXPECT_NE(bad.out.find("--odometry source needs an RGB-D folder or a bag"), std::string::npos) << bad.out;
  // So is --gt source.
  const CmdResult bad_gt = run("slam --kitti " + path("none") + " --gt source --out " + path("x"));
  EXPECT_EQ(bad_gt.code, 2);
  EXPECT_EQ(lines(bad_gt.out), 1U) << bad_gt.out;
  EXPECT_NE(bad_gt.out.find("--gt source needs an RGB-D folder or a bag"), std::string::npos) << bad_gt.out;
}

TEST_F(CliTest, SlamOnDepthFramesFromTheScansAloneWithTheFolderAsTruth) {
  // --attitude-from scans: the 7-Scenes poses (KinectFusion's, the ground truth) are not used; the
  // first frame is levelled by its floor and said so. --gt source writes them as truth.txt.
  HMAP_REQUIRE_DATA("rgbd_7scenes");
  const std::string rgbd = (test::data_dir() / "rgbd_7scenes").string();
  const CmdResult s = run("slam --rgbd " + rgbd + " --scans 6 --attitude-from scans --gt source --out " + path("s"));
  ASSERT_EQ(s.code, 0) << s.out;
  EXPECT_NE(s.out.find("estimated from the scans (floor normal + map surfaces; the walls' lean held it to gravity on "),
            std::string::npos)
      << s.out;
  EXPECT_NE(s.out.find("First frame levelled by its floor"), std::string::npos) << s.out;
  const PoseList truth = read_poses((dir_ / "s" / "truth.txt").string());
  const PoseList est = read_poses((dir_ / "s" / "poses.txt").string());
  ASSERT_EQ(truth.size(), 6U);
  ASSERT_EQ(est.size(), 6U);
  // The first frame starts where the truth does (x, y, yaw and height), its tilt from its floor:
  // within 3° of KinectFusion's, whose gravity is the folder's floor over all 50 frames.
  EXPECT_NEAR((est.front().translation() - truth.front().translation()).norm(), 0.0, 1e-6);
  for (std::size_t k = 0; k < est.size(); ++k) {
    const Eigen::Vector3d up_est = est[k].linear().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d up_true = truth[k].linear().transpose() * Eigen::Vector3d::UnitZ();
    EXPECT_LT(std::acos(std::min(1.0, up_est.dot(up_true))), 3.0 * std::numbers::pi / 180.0) << k;
  }
  // Given, the folder's attitude is the truth's to the bit.
  const CmdResult g = run("slam --rgbd " + rgbd + " --scans 6 --gt source --out " + path("g"));
  ASSERT_EQ(g.code, 0) << g.out;
  EXPECT_NE(g.out.find("given (the poses of the input or --attitude-from)"), std::string::npos) << g.out;
  const PoseList given = read_poses((dir_ / "g" / "poses.txt").string());
  ASSERT_EQ(given.size(), 6U);
  EXPECT_NEAR(given.back().translation().z(), read_poses((dir_ / "g" / "truth.txt").string()).back().translation().z(), 1e-6);
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

// export --mcap: one summary line, an MCAP file (atomically in place), and bad input refused
// before any work with one line and exit 2. The file's content is tested in tests/ros.
TEST_F(CliTest, ExportsAnMcapForFoxgloveAndRefusesBadInput) {
  HMap map(indoor_preset());
  map.column_for_update({3, -2}).push_back({0.0F, 0.4F, 50.0F, 0.9F});
  map.column_for_update({-7, 5}).push_back({-0.3F, 0.2F, 1.0F, 0.3F});
  OccupancyGrid grid(map.cell_size(), 0.12, 0.97);
  grid.update({3, -2}, 2.0F);
  grid.update({0, 0}, -2.0F);
  save_hmap(path("m.hmap"), map, {}, &grid);
  save_hmap(path("no_grid.hmap"), map);

  std::ofstream(path("poses.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n";
  const CmdResult r = run("export " + path("m.hmap") + " --mcap " + path("m.mcap") + " --trajectory " + path("poses.txt"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(lines(r.out), 1U) << r.out;
  // Two HVoxels in two tiles of 64 cells (cell -7 lies in tile -1): two SceneUpdates; one /tf per
  // pose, at 0 since a KITTI file without times.txt beside it has no stamps.
  EXPECT_NE(r.out.find("/grid 1, /hvoxels 2, /map 1, /points 1, /tf 2, /trajectory 1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("no stamps (all at time 0)"), std::string::npos) << r.out;
  std::ifstream in(path("m.mcap"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  ASSERT_GT(bytes.size(), 16U);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89MCAP0\r\n", 8));
  EXPECT_EQ(bytes.substr(bytes.size() - 8), std::string("\x89MCAP0\r\n", 8));

  for (const auto& [args, says] : std::vector<std::pair<std::string, std::string>>{
           {path("m.hmap") + " --mcap " + path("m.bag"), "ending in .mcap"},
           {path("m.hmap") + " --mcap " + path("no/such/folder/m.mcap"), "does not exist"},
           // No grid kept: one is derived from the columns as for --pgm; these two columns hold no ground.
           {path("no_grid.hmap") + " --mcap " + path("n.mcap"), "no ground found near the hint"},
           {path("m.hmap") + " --mcap " + path("n.mcap") + " --trajectory " + path("none.txt"), "none.txt"},
           {path("m.hmap") + " --ply " + path("n.ply") + " --trajectory " + path("poses.txt"), "goes with --mcap"}}) {
    const CmdResult bad = run("export " + args);
    EXPECT_EQ(bad.code, 2) << bad.out;
    EXPECT_EQ(lines(bad.out), 1U) << bad.out;
    EXPECT_NE(bad.out.find(says), std::string::npos) << bad.out;
  }
  EXPECT_FALSE(std::filesystem::exists(path("m.bag")));
  EXPECT_FALSE(std::filesystem::exists(path("n.mcap")));
  EXPECT_FALSE(std::filesystem::exists(path("n.ply")));
}

// map/slam --mcap: the same recording export --mcap writes from the saved map (map: byte for byte,
// with the scans' poses as /trajectory), and a bad --mcap refused before any work.
TEST_F(CliTest, MapAndSlamWriteTheMcapExportWould) {
  ASSERT_EQ(run("simulate --scene office --sensor kinect --frames 6 --stride 5 --seed 3 --out " + path("seq")).code, 0);
  const CmdResult m = run("map --kitti " + path("seq") + " --preset indoor --out " + path("m.hmap") + " --mcap " + path("m.mcap"));
  ASSERT_EQ(m.code, 0) << m.out;
  EXPECT_NE(m.out.find("/map 1, /points 1, /tf 6, /trajectory 1"), std::string::npos) << m.out;  // a /tf per scan
  // export takes the stamps of seq/times.txt beside seq/poses.txt, as map took the folder's.
  const CmdResult e = run("export " + path("m.hmap") + " --mcap " + path("e.mcap") + " --trajectory " + path("seq/poses.txt"));
  ASSERT_EQ(e.code, 0) << e.out;
  const auto bytes = [&](const std::string& name) {
    std::ifstream in(path(name), std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  ASSERT_GT(bytes("m.mcap").size(), 100U);
  EXPECT_EQ(bytes("m.mcap"), bytes("e.mcap"));

  const CmdResult s = run("slam --kitti " + path("seq") + " --preset indoor --out " + path("s") + " --mcap " + path("s.mcap"));
  ASSERT_EQ(s.code, 0) << s.out;
  // SLAM keeps no grid: /map and /grid come from the columns, as export derives them.
  EXPECT_NE(s.out.find("/grid 1"), std::string::npos) << s.out;
  EXPECT_NE(s.out.find("/map 1, /points 1, /tf 6, /trajectory 1"), std::string::npos) << s.out;
  EXPECT_EQ(bytes("s.mcap").substr(0, 8), std::string("\x89MCAP0\r\n", 8));

  for (const std::string& cmd : {"map --kitti " + path("seq") + " --out " + path("n.hmap") + " --mcap " + path("n.bag"),
                                 "slam --kitti " + path("seq") + " --out " + path("n") + " --mcap " + path("no/such/n.mcap")}) {
    const CmdResult bad = run(cmd);
    EXPECT_EQ(bad.code, 2) << bad.out;
    EXPECT_EQ(lines(bad.out), 1U) << bad.out;
  }
  EXPECT_FALSE(std::filesystem::exists(path("n.hmap")));
  EXPECT_FALSE(std::filesystem::exists(path("n")));
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

// simulate --sweep (issue 16): each scan a sweep taken while the car moves, written as
// velodyne/*.pcd whose field t is each point's time from the sweep's start; slam reads the times
// through the KITTI folder (times.txt gives the stamps) and deskews. A sensor without a sweep is
// refused with one line naming the option.
TEST_F(CliTest, SimulateSweepWritesPerPointTimeThatSlamDeskews) {
  const CmdResult sim = run("simulate --scene parking --sensor vlp16 --sweep --frames 3 --seed 2 --out " + path("sweep"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "sweep" / "velodyne" / "000000.bin"));
  for (const char* f : {"poses.txt", "times.txt", "odometry.txt", "velodyne/000002.pcd"}) {
    EXPECT_TRUE(std::filesystem::exists(dir_ / "sweep" / f)) << f;
  }
  constexpr double kPeriod = 0.1;            // [s] SpinningLidarParams::sweep_period
  constexpr double kColumn = kPeriod / 1800;  // [s] a VLP-16 column (0.2°)
  for (const char* scan : {"000000.pcd", "000002.pcd"}) {
    std::vector<float> times;
    const PointCloud cloud = read_pcd(dir_ / "sweep" / "velodyne" / scan, nullptr, &times);
    ASSERT_GT(cloud.size(), 10000U) << scan;
    ASSERT_EQ(times.size(), cloud.size()) << scan;
    const auto [lo, hi] = std::minmax_element(times.begin(), times.end());
    EXPECT_GE(*lo, 0.0F);
    EXPECT_LT(*hi, kPeriod);
    EXPECT_GT(*hi, 0.95 * kPeriod);  // the whole revolution, not one instant
    // Column by column, azimuth counter-clockwise from x: the time grows with the azimuth, one
    // column's time per 0.2° (the directions are exact; the noise is along the beam).
    double worst = 0.0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (i > 0) {
        ASSERT_GE(times[i], times[i - 1]) << scan << " point " << i;
      }
      double azimuth = std::atan2(static_cast<double>(cloud[i].y()), static_cast<double>(cloud[i].x()));
      if (azimuth < -1e-6) azimuth += 2.0 * std::numbers::pi;
      worst = std::max(worst, std::abs(static_cast<double>(times[i]) - azimuth / (2.0 * std::numbers::pi) * kPeriod));
    }
    EXPECT_LT(worst, 0.1 * kColumn) << scan;
  }
  // Without odometry or an IMU the last two estimates give the velocity, from the third scan on;
  // with odometry every scan after the first is deskewed (and the first too, once the second gives
  // the velocity: the map is rebuilt, the count is of scans matched deskewed). slam.deskew=0 says
  // in one line that the times were left alone.
  const CmdResult slam = run("slam --kitti " + path("sweep") + " --out " + path("slam"));
  ASSERT_EQ(slam.code, 0) << slam.out;
  EXPECT_NE(slam.out.find("Deskewed: 1 of 3 scans"), std::string::npos) << slam.out;
  EXPECT_EQ(slam.out.find("not deskewed"), std::string::npos) << slam.out;
  const CmdResult odo = run("slam --kitti " + path("sweep") + " --odometry " + path("sweep/odometry.txt") + " --out " + path("slam_odo"));
  ASSERT_EQ(odo.code, 0) << odo.out;
  EXPECT_NE(odo.out.find("Deskewed: 2 of 3 scans"), std::string::npos) << odo.out;
  EXPECT_EQ(odo.out.find("not deskewed"), std::string::npos) << odo.out;
  const CmdResult off = run("slam --kitti " + path("sweep") + " --set slam.deskew=0 --out " + path("slam_off"));
  ASSERT_EQ(off.code, 0) << off.out;
  EXPECT_NE(off.out.find("Deskewed: 0 of 3 scans"), std::string::npos) << off.out;
  EXPECT_NE(off.out.find("3 scans carry a time per point but were not deskewed (slam.deskew=0)"), std::string::npos)
      << off.out;
  const CmdResult two = run("slam --kitti " + path("sweep") + " --set slam.deskew=2 --out " + path("slam_two"));
  EXPECT_EQ(two.code, 2) << two.out;
  EXPECT_EQ(lines(two.out), 1U) << two.out;
  EXPECT_NE(two.out.find("slam.deskew"), std::string::npos) << two.out;

  const CmdResult bad = run("simulate --scene office --sensor kinect --sweep --frames 2 --out " + path("bad"));
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_EQ(lines(bad.out), 1U) << bad.out;
  EXPECT_NE(bad.out.find("--sweep"), std::string::npos) << bad.out;
  EXPECT_FALSE(std::filesystem::exists(path("bad")));
}

// simulate --scene city (issue 19): a drive through the town, its scans written as they are
// made, no truth files; bad --route-km values and options of other scenes give one line, exit 2.
TEST_F(CliTest, SimulateCityDriveAndItsBadOptions) {
  const CmdResult sim = run("simulate --scene city --route-km 0.2 --frames 3 --stride 10 --out " + path("city"));
  ASSERT_EQ(sim.code, 0) << sim.out;
  for (const char* name : {"velodyne/000000.bin", "velodyne/000001.bin", "velodyne/000002.bin", "poses.txt", "times.txt",
                           "odometry.txt"}) {
    EXPECT_TRUE(std::filesystem::exists(path("city") + "/" + name)) << name;
  }
  EXPECT_FALSE(std::filesystem::exists(path("city/velodyne/000003.bin")));
  EXPECT_FALSE(std::filesystem::exists(path("city/truth.ply")));
  EXPECT_FALSE(std::filesystem::exists(path("city/truth_seen.ply")));
  std::ifstream poses(path("city/poses.txt"));
  std::size_t pose_lines = 0;
  for (std::string line; std::getline(poses, line);) pose_lines += line.empty() ? 0 : 1;
  EXPECT_EQ(pose_lines, 3U);
  EXPECT_NE(sim.out.find("no truth files"), std::string::npos) << sim.out;

  const std::pair<std::string, std::string> bad[] = {
      {"--scene city --route-km 0", "--route-km"},
      {"--scene city --route-km 0.05", "--route-km"},
      {"--scene city --route-km 21", "--route-km"},
      {"--scene city --route-km -3", "--route-km"},
      {"--scene city --route-km nan", "--route-km"},
      {"--scene city --route-km ten", "--route-km"},
      {"--scene parking --route-km 2", "--route-km"},
      {"--scene city --long-route", "--long-route"},
  };
  for (const auto& [args, named] : bad) {
    const CmdResult r = run("simulate " + args + " --out " + path("bad"));
    EXPECT_EQ(r.code, 2) << args << ": " << r.out;
    EXPECT_EQ(lines(r.out), 1U) << args << ": " << r.out;
    EXPECT_NE(r.out.find(named), std::string::npos) << args << ": " << r.out;
    EXPECT_FALSE(std::filesystem::exists(path("bad"))) << args;
  }
}

// The PVOX boxes experiment's ruler output: every edge of both filters in edges.csv, measured or
// missing (never both, never a length without its faces), the counts and the average in report.json
// agree with the rows, and every face matched with a plane names a plane of planes.csv.
TEST_F(CliTest, PvoxBoxesReportsMissingEdgesAsMissing) {
  const CmdResult r = run("experiment pvox-boxes --quick --seed 4 --out " + path("pvox"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream csv(dir_ / "pvox" / "edges.csv");
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line, "filter,edge,true_mm,measured_mm,accuracy,status,first_m,second_m,missing");
  std::map<std::string, std::pair<std::size_t, std::size_t>> counts;  // filter -> measured, missing
  std::map<std::string, double> accuracy_sum;
  while (std::getline(csv, line)) {
    std::vector<std::string> cells;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) cells.push_back(cell);
    ASSERT_GE(cells.size(), 9U) << line;
    if (cells[5] == "measured") {
      EXPECT_FALSE(cells[3].empty() || cells[4].empty() || cells[6].empty() || cells[7].empty()) << line;
      EXPECT_EQ(cells[8], "\"\"") << line;
      ++counts[cells[0]].first;
      accuracy_sum[cells[0]] += std::stod(cells[4]);
    } else {
      EXPECT_EQ(cells[5], "missing") << line;
      EXPECT_TRUE(cells[3].empty() && cells[4].empty()) << line;
      EXPECT_NE(cells[8], "\"\"") << line;
      ++counts[cells[0]].second;
    }
  }
  std::ifstream in(dir_ / "pvox" / "report.json");
  const auto j = nlohmann::json::parse(in);
  std::ifstream planes_csv(dir_ / "pvox" / "planes.csv");
  const std::string planes((std::istreambuf_iterator<char>(planes_csv)), std::istreambuf_iterator<char>());
  for (const char* filter : {"rbf", "brf"}) {
    const auto [measured, missing] = counts[filter];
    EXPECT_EQ(measured + missing, 9U) << filter;
    EXPECT_EQ(j.at(filter).at("edges_measured").get<std::size_t>(), measured) << filter;
    EXPECT_EQ(j.at(filter).at("edges_missing").get<std::size_t>(), missing) << filter;
    if (measured > 0) {
      EXPECT_NEAR(j.at(filter).at("average_accuracy_measured").get<double>(), accuracy_sum[filter] / static_cast<double>(measured), 1e-3) << filter;
    }
    for (const auto& face : j.at(filter).at("faces")) {
      if (face.at("plane").is_null()) continue;
      const std::string name = face.at("name").get<std::string>();
      EXPECT_NE(planes.find(std::string(filter) + ",") , std::string::npos);
      EXPECT_NE(planes.find("\"" + name + "\""), std::string::npos) << name;
    }
  }
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

std::string file_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// hmap map --continue (issue 22): a map built on from its saved layers is the map built in one
// run, byte for byte, the ground patches and the 2D grid included; parameters that would make it
// another map are refused.
TEST_F(CliTest, MapContinuedFromItsFileEqualsOneRun) {
  ASSERT_EQ(run("simulate --scene parking --sensor vlp16 --frames 8 --seed 4 --out " + path("seq")).code, 0);
  std::ifstream poses(dir_ / "seq" / "poses.txt");
  std::vector<std::string> lines_of_poses;
  for (std::string line; std::getline(poses, line);) lines_of_poses.push_back(line);
  ASSERT_EQ(lines_of_poses.size(), 8U);
  std::string first, second;
  {
    std::ofstream p1(path("p1.txt")), p2(path("p2.txt"));
    for (int k = 0; k < 8; ++k) {
      const std::string scan = " " + (dir_ / "seq" / "velodyne" / format("%06d.bin", k)).string();
      (k < 5 ? p1 : p2) << lines_of_poses[static_cast<std::size_t>(k)] << "\n";
      (k < 5 ? first : second) += scan;
    }
  }
  const CmdResult whole = run("map --kitti " + path("seq") + " --out " + path("whole.hmap"));
  ASSERT_EQ(whole.code, 0) << whole.out;
  ASSERT_EQ(run("map" + first + " --poses " + path("p1.txt") + " --out " + path("part.hmap")).code, 0);
  const CmdResult cont = run("map" + second + " --poses " + path("p2.txt") + " --continue " + path("part.hmap") +
                             " --out " + path("cont.hmap"));
  ASSERT_EQ(cont.code, 0) << cont.out;
  EXPECT_NE(cont.out.find("Continued"), std::string::npos) << cont.out;
  const MapFile m = load_map_file(dir_ / "cont.hmap");
  ASSERT_TRUE(m.grid.has_value());
  EXPECT_GT(m.grid->known_cells(), 100U);
  EXPECT_GT(m.ground.size(), 10U);
  EXPECT_GT(m.map.stats().hvoxels, load_hmap(dir_ / "part.hmap").stats().hvoxels);
  EXPECT_TRUE(file_bytes(dir_ / "cont.hmap") == file_bytes(dir_ / "whole.hmap"));

  // Bad combinations: one line, exit 2, nothing written.
  const std::string tail = second + " --poses " + path("p2.txt") + " --continue " + path("part.hmap") + " --out " + path("bad.hmap");
  for (const std::string& extra : {std::string(" --cell 0.1"), std::string(" --set map.max_range=30"), std::string(" --hvoxels-only")}) {
    const CmdResult r = run("map" + tail + extra);
    EXPECT_EQ(r.code, 2) << extra;
    EXPECT_EQ(lines(r.out), 1U) << r.out;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "bad.hmap")) << extra;
  }
  ASSERT_EQ(run("map" + first + " --poses " + path("p1.txt") + " --hvoxels-only --out " + path("bare.hmap")).code, 0);
  const CmdResult bare = run("map" + second + " --poses " + path("p2.txt") + " --continue " + path("bare.hmap") + " --out " + path("bad.hmap"));
  EXPECT_EQ(bare.code, 2);
  EXPECT_NE(bare.out.find("bare.hmap"), std::string::npos) << bare.out;
  EXPECT_NE(bare.out.find("--hvoxels-only"), std::string::npos) << bare.out;
  const CmdResult missing = run("map" + second + " --poses " + path("p2.txt") + " --continue " + path("nope.hmap") + " --out " + path("bad.hmap"));
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.out.find("nope.hmap"), std::string::npos) << missing.out;
}


// hmap slam --continue (issue 22): a second session localised in the first one's saved map.
// A LiDAR mounted upside down (the town's VLP-16 scans with y and z negated: 180° about x). Taken
// as upright, its map is upside down (the first pose's up is the sensor's +z); with --sensor-up -z
// each pose is the upright run's, mirrored back, within 6 cm and 0.5°. A bad axis, or the flag
// with the attitude given, is one line and exit 2.
TEST_F(CliTest, SlamOnALidarMountedUpsideDown) {
  ASSERT_EQ(run("simulate --scene city --sensor vlp16 --frames 6 --stride 3 --out " + path("up")).code, 0);
  std::filesystem::create_directories(dir_ / "down" / "velodyne");
  for (int k = 0; k < 6; ++k) {
    const std::string name = format("%06d.bin", k);
    std::ifstream in(dir_ / "up" / "velodyne" / name, std::ios::binary);
    std::vector<float> v(std::filesystem::file_size(dir_ / "up" / "velodyne" / name) / sizeof(float));
    in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(float)));
    for (std::size_t i = 0; i + 3 < v.size(); i += 4) {  // x y z intensity
      v[i + 1] = -v[i + 1];
      v[i + 2] = -v[i + 2];
    }
    std::ofstream out(dir_ / "down" / "velodyne" / name, std::ios::binary);
    out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(float)));
  }
  const CmdResult upright = run("slam --kitti " + path("up") + " --out " + path("s_up"));
  ASSERT_EQ(upright.code, 0) << upright.out;
  EXPECT_EQ(upright.out.find("--sensor-up"), std::string::npos) << upright.out;
  const CmdResult taken_upright = run("slam --kitti " + path("down") + " --out " + path("s_guess"));
  ASSERT_EQ(taken_upright.code, 0) << taken_upright.out;
  EXPECT_GT(read_poses(dir_ / "s_guess" / "poses.txt").front()(2, 2), 0.99);  // the sensor's +z taken as up
  const CmdResult told = run("slam --kitti " + path("down") + " --sensor-up -z --out " + path("s_down"));
  ASSERT_EQ(told.code, 0) << told.out;
  EXPECT_NE(told.out.find("First scan levelled by its floor"), std::string::npos) << told.out;
  const PoseList a = read_poses(dir_ / "s_up" / "poses.txt");
  const PoseList b = read_poses(dir_ / "s_down" / "poses.txt");
  ASSERT_EQ(a.size(), 6U);
  ASSERT_EQ(b.size(), 6U);
  EXPECT_LT(b.front()(2, 2), -0.99);  // the sensor's -z is up
  Pose flip = Pose::Identity();
  flip.linear() = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();  // the upright sensor's frame in the flipped one's
  // Each run follows the truth's motion from its first pose within 4.5 cm (3.1-4.0 cm: the walls'
  // lean levels the first scans to within about 0.1° of each other, and the first match lands
  // 3.3 cm off along the street; 2-2.5 cm with the floors alone, slam.wall_tilt_drift=0), and the
  // two agree within 6 cm and 0.5 deg.
  const PoseList truth = read_poses(dir_ / "up" / "poses.txt");
  ASSERT_EQ(truth.size(), 6U);
  for (std::size_t k = 0; k < 6; ++k) {
    const Pose want = truth[0].inverse() * truth[k];
    EXPECT_LT((want.inverse() * (a[0].inverse() * a[k])).translation().norm(), 0.045) << k;
    EXPECT_LT((want.inverse() * ((b[0] * flip).inverse() * (b[k] * flip))).translation().norm(), 0.045) << k;
    const Pose d = a[k].inverse() * (b[k] * flip);
    EXPECT_LT(d.translation().norm(), 0.06) << k;
    EXPECT_LT(Eigen::AngleAxisd(d.linear()).angle(), 0.5 * std::numbers::pi / 180.0) << k;
  }
  for (const std::string& extra : {std::string(" --sensor-up q"), " --sensor-up -z --attitude-from " + path("up/poses.txt")}) {
    const CmdResult r = run("slam --kitti " + path("down") + extra + " --out " + path("bad"));
    EXPECT_EQ(r.code, 2) << extra;
    EXPECT_EQ(lines(r.out), 1U) << r.out;
    EXPECT_NE(r.out.find("--sensor-up"), std::string::npos) << r.out;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "bad")) << extra;
  }
}

TEST_F(CliTest, SlamContinuesASavedMapInItsFrame) {
  ASSERT_EQ(run("simulate --scene parking --sensor vlp16 --frames 8 --seed 4 --out " + path("seq")).code, 0);
  const PoseList truth = read_poses(dir_ / "seq" / "poses.txt");
  ASSERT_EQ(truth.size(), 8U);
  std::string first, second;
  for (int k = 0; k < 8; ++k) (k < 5 ? first : second) += " " + (dir_ / "seq" / "velodyne" / format("%06d.bin", k)).string();
  const CmdResult one = run("slam" + first + " --out " + path("s1"));
  ASSERT_EQ(one.code, 0) << one.out;
  const CmdResult two = run("slam" + second + " --continue " + path("s1/map.hmap") + " --out " + path("s2"));
  ASSERT_EQ(two.code, 0) << two.out;
  EXPECT_NE(two.out.find("The first scan was found at"), std::string::npos) << two.out;
  EXPECT_NE(two.out.find("3 of 3 matches converged"), std::string::npos) << two.out;
  // Its poses are in the first session's frame (the first scan's pose there): the truth's motion
  // from scan 0, within 10 cm and 1° (the first session's map, not the scans' order, placed them).
  const PoseList cont = read_poses(dir_ / "s2" / "poses.txt");
  ASSERT_EQ(cont.size(), 3U);
  for (std::size_t k = 0; k < 3; ++k) {
    const Pose want = truth[0].inverse() * truth[k + 5];
    EXPECT_NEAR(cont[k].translation().x(), want.translation().x(), 0.1) << k;
    EXPECT_NEAR(cont[k].translation().y(), want.translation().y(), 0.1) << k;
    const double yaw_want = std::atan2(want(1, 0), want(0, 0));
    const double yaw = std::atan2(cont[k](1, 0), cont[k](0, 0));
    EXPECT_NEAR(std::remainder(yaw - yaw_want, 2.0 * std::numbers::pi), 0.0, std::numbers::pi / 180.0) << k;
  }
  EXPECT_GT(load_hmap(dir_ / "s2" / "map.hmap").stats().hvoxels, load_hmap(dir_ / "s1" / "map.hmap").stats().hvoxels);
  // The first session's cell centroids were saved with its map and continued (no loop was closed
  // in either): the second map holds them and its own scans'.
  const MapFile s1 = load_map_file(dir_ / "s1" / "map.hmap");
  const MapFile s2 = load_map_file(dir_ / "s2" / "map.hmap");
  ASSERT_TRUE(s1.centroids.has_value());
  ASSERT_TRUE(s2.centroids.has_value());
  EXPECT_GT(s1.centroids->size(), 100U);
  EXPECT_GT(s2.centroids->size(), s1.centroids->size());
  EXPECT_NE(two.out.find(std::to_string(s1.centroids->size()) + " cell centroids before"), std::string::npos) << two.out;
  // hmap map --continue keeps them as saved (its scans, at given poses, add none), and hmap merge
  // unites two sessions' (the same frame here: each cell's weights add up).
  const CmdResult mapped = run("map" + second + " --poses " + path("s2/poses.txt") + " --continue " + path("s1/map.hmap") +
                               " --hvoxels-only --out " + path("m.hmap"));
  ASSERT_EQ(mapped.code, 0) << mapped.out;
  // (A file holds the centroids of the tiles its map stores: those whose HVoxels the new scans
  // carved away all go.)
  const MapFile m = load_map_file(dir_ / "m.hmap");
  ASSERT_TRUE(m.centroids.has_value());
  EXPECT_LE(m.centroids->size(), s1.centroids->size());
  EXPECT_GT(m.centroids->size(), s1.centroids->size() * 9 / 10);
  m.centroids->for_each([&](const CellKey& k, const Eigen::Vector2f& o, double) {
    const Eigen::Vector2f* saved = s1.centroids->offset(k);
    ASSERT_NE(saved, nullptr);
    EXPECT_EQ(*saved, o);
  });
  const CmdResult merged = run("merge " + path("s1/map.hmap") + " " + path("s2/map.hmap") + " --out " + path("u.hmap"));
  ASSERT_EQ(merged.code, 0) << merged.out;
  const MapFile u = load_map_file(dir_ / "u.hmap");
  ASSERT_TRUE(u.centroids.has_value());
  EXPECT_GE(u.centroids->size(), s2.centroids->size());
  std::map<std::pair<int, int>, double> weight;
  for (const MapFile* f : {&s1, &s2}) {
    f->centroids->for_each([&](const CellKey& k, const Eigen::Vector2f&, double w) { weight[{k.i, k.j}] += w; });
  }
  u.centroids->for_each([&](const CellKey& k, const Eigen::Vector2f&, double w) {
    EXPECT_NEAR(w, (weight[{k.i, k.j}]), 1e-9 * w) << k.i << " " << k.j;
  });

  // Bad combinations: one line, exit 2, nothing written.
  const std::string tail = second + " --out " + path("bad");
  for (const std::string& extra :
       {" --continue " + path("s1/map.hmap") + " --cell 0.1", " --continue " + path("s1/map.hmap") + " --set map.max_range=30",
        " --continue " + path("s1/map.hmap") + " --search 30", " --continue " + path("s1/map.hmap") + " --search-yaw -1",
        std::string(" --start 1 2 3"), " --continue " + path("nope.hmap")}) {
    const CmdResult r = run("slam" + tail + extra);
    EXPECT_EQ(r.code, 2) << extra;
    EXPECT_EQ(lines(r.out), 1U) << r.out;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "bad")) << extra;
  }
  // slam.* may change for the second session.
  const CmdResult tuned = run("slam" + second + " --continue " + path("s1/map.hmap") + " --search-yaw 20 --set slam.max_iterations=40 --out " + path("s3"));
  EXPECT_EQ(tuned.code, 0) << tuned.out;
}
}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

// hmap merge (issue 22): two sessions' maps into one, the second registered first with --align.
TEST_F(CliTest, MergeRegistersAndUnitesTwoSessions) {
  ASSERT_EQ(run("simulate --scene parking --sensor vlp16 --frames 8 --seed 4 --out " + path("seq")).code, 0);
  const PoseList truth = read_poses(dir_ / "seq" / "poses.txt");
  ASSERT_EQ(truth.size(), 8U);
  // The second session's poses in a frame 8° and (0.7, -0.4, 0.1) m away.
  Pose S = Pose::Identity();
  S.linear() = Eigen::AngleAxisd(8.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  S.translation() = Eigen::Vector3d(0.7, -0.4, 0.1);
  PoseList first_poses(truth.begin(), truth.begin() + 5), second_poses;
  std::string first, second;
  for (int k = 0; k < 8; ++k) {
    const std::string scan = " " + (dir_ / "seq" / "velodyne" / format("%06d.bin", k)).string();
    if (k < 5) first += scan;
    if (k >= 3) {
      second += scan;
      second_poses.push_back(S * truth[static_cast<std::size_t>(k)]);
    }
  }
  write_poses_kitti(dir_ / "p1.txt", first_poses);
  write_poses_kitti(dir_ / "p2.txt", second_poses);
  ASSERT_EQ(run("map" + first + " --poses " + path("p1.txt") + " --out " + path("a.hmap")).code, 0);
  ASSERT_EQ(run("map" + second + " --poses " + path("p2.txt") + " --out " + path("b.hmap")).code, 0);

  const CmdResult r = run("merge " + path("a.hmap") + " " + path("b.hmap") + " --align --out " + path("m.hmap"));
  ASSERT_EQ(r.code, 0) << r.out;
  // "x X m, y Y m, z Z m, yaw W deg": S⁻¹.
  double x = 0, y = 0, z = 0, yaw = 0;
  const auto at = r.out.find("first's: x ");
  ASSERT_NE(at, std::string::npos) << r.out;
  ASSERT_EQ(std::sscanf(r.out.c_str() + at, "first's: x %lf m, y %lf m, z %lf m, yaw %lf deg", &x, &y, &z, &yaw), 4) << r.out;
  const Pose want = S.inverse();
  EXPECT_NEAR(x, want.translation().x(), 0.1) << r.out;
  EXPECT_NEAR(y, want.translation().y(), 0.1) << r.out;
  EXPECT_NEAR(z, want.translation().z(), 0.05) << r.out;
  EXPECT_NEAR(yaw, -8.0, 0.5) << r.out;
  // The file holds a's map with b's moved by that shift merged in, its grid and ground joined.
  const MapFile m = load_map_file(dir_ / "m.hmap");
  HMap expected = load_hmap(dir_ / "a.hmap");
  merge_map(expected, shifted_map(load_hmap(dir_ / "b.hmap"), {x, y, z, yaw * std::numbers::pi / 180.0}));
  EXPECT_NEAR(static_cast<double>(m.map.stats().hvoxels), static_cast<double>(expected.stats().hvoxels),
              0.01 * static_cast<double>(expected.stats().hvoxels));  // the printed shift is rounded
  ASSERT_TRUE(m.grid.has_value());
  EXPECT_GE(m.grid->known_cells(), load_map_file(dir_ / "a.hmap").grid->known_cells());
  EXPECT_GT(m.ground.size(), load_map_file(dir_ / "a.hmap").ground.size());

  // A known shift without --align is applied as given: the same file as merging by hand.
  const CmdResult k = run("merge " + path("a.hmap") + " " + path("a.hmap") + " --shift 0.5 0 0 0 --out " + path("k.hmap"));
  ASSERT_EQ(k.code, 0) << k.out;
  HMap twice = load_hmap(dir_ / "a.hmap");
  merge_map(twice, shifted_map(load_hmap(dir_ / "a.hmap"), {0.5, 0.0, 0.0, 0.0}));
  EXPECT_EQ(load_hmap(dir_ / "k.hmap").stats().hvoxels, twice.stats().hvoxels);

  // Bad input: one line, exit 2, nothing written.
  ASSERT_EQ(run("map" + second + " --poses " + path("p2.txt") + " --cell 0.2 --out " + path("fine.hmap")).code, 0);
  const std::string both = "merge " + path("a.hmap") + " ";
  for (const std::string& bad : {both + path("fine.hmap") + " --out " + path("bad.hmap"),
                                 both + path("nope.hmap") + " --out " + path("bad.hmap"),
                                 both + path("b.hmap") + " --shift 1 2 3 --out " + path("bad.hmap"),
                                 both + path("b.hmap") + " --shift 1 2 nan 0 --out " + path("bad.hmap"),
                                 both + path("b.hmap") + " --align --search 50 --out " + path("bad.hmap"),
                                 both + path("b.hmap") + " --out " + path("bad.ply")}) {
    const CmdResult e = run(bad);
    EXPECT_EQ(e.code, 2) << bad << "\n" << e.out;
    EXPECT_EQ(lines(e.out), 1U) << e.out;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "bad.hmap")) << bad;
  }
  EXPECT_NE(run(both + path("fine.hmap") + " --out " + path("bad.hmap")).out.find("fine.hmap"), std::string::npos);
}

}  // namespace
}  // namespace hmap
