// What a new user meets in the first hour (issue 15): the input options every command shares, the
// --rotation of the help, output names that say what is written, the .pvox map read back, and the
// OctoMap export counted as liboctomap counts it.

#include <gtest/gtest.h>

#include <octomap/OcTree.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <sys/wait.h>

#include "apps/cli_run.hpp"
#include "common/test_data.hpp"
#include "hmap/io/hmap_file.hpp"

namespace hmap {
namespace {

using test::CmdResult;
using test::lines;
using test::run;

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

class FirstHourTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::temp_dir("first_hour");
    // A floor of 2 m x 2 m 1 m below the sensor and a wall at x = 1, 5 cm apart: enough for every command.
    std::ofstream scan(path("scan.xyz"));
    for (int i = 0; i < 40; ++i) {
      for (int j = 0; j < 40; ++j) {
        scan << -1.0 + 0.05 * i << " " << -1.0 + 0.05 * j << " -1\n";
        scan << "1 " << -1.0 + 0.05 * i << " " << -1.0 + 0.05 * j << "\n";
      }
    }
    std::ofstream(path("pose.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::filesystem::path dir_;
};

// The help shows nine numbers; they work unquoted and quoted, and a short rotation is named.
TEST_F(FirstHourTest, RotationTakesNineNumbersUnquotedOrQuoted) {
  const std::string base = "map " + path("scan.xyz") + " --poses " + path("pose.txt");
  const CmdResult plain = run(base + " --rotation 1 0 0 0 1 0 0 0 1 --out " + path("a.hmap"));
  EXPECT_EQ(plain.code, 0) << plain.out;
  const CmdResult quoted = run(base + " --rotation '0 -1 0 1 0 0 0 0 1' --out " + path("b.hmap"));
  EXPECT_EQ(quoted.code, 0) << quoted.out;
  // Before the scan file too: the nine numbers end the option.
  const CmdResult first = run("map --rotation 1 0 0 0 1 0 0 0 1 " + path("scan.xyz") + " --poses " + path("pose.txt") +
                              " --out " + path("c.hmap"));
  EXPECT_EQ(first.code, 0) << first.out;
  const CmdResult shorter = run(base + " --rotation 1 0 0 --out " + path("d.hmap"));
  EXPECT_EQ(shorter.code, 2);
  EXPECT_TRUE(has(shorter.out, "--rotation")) << shorter.out;
  EXPECT_EQ(lines(shorter.out), 1U) << shorter.out;
  const CmdResult skew = run(base + " --rotation 1 0 0 0 2 0 0 0 1 --out " + path("e.hmap"));
  EXPECT_EQ(skew.code, 2);
  EXPECT_TRUE(has(skew.out, "not orthonormal")) << skew.out;
}

// One definition of the input options: every scan-reading command shows the same help for them,
// lists VTK, says what --scans 0 means, and takes -o.
TEST_F(FirstHourTest, EveryScanCommandSharesTheInputOptions) {
  for (const char* command : {"map", "slam", "pvox", "compare", "bench"}) {
    SCOPED_TRACE(command);
    const CmdResult help = run(std::string(command) + " --help");
    ASSERT_EQ(help.code, 0) << help.out;
    EXPECT_TRUE(has(help.out, ".pts .vtk")) << help.out;
    EXPECT_TRUE(has(help.out, "Use only the first N scans (0, the default: all of them)")) << help.out;
    for (const char* option : {"--kitti", "--rgbd", "--tum", "--bag", "--up", "--rotation", "--scans"}) {
      EXPECT_TRUE(has(help.out, option)) << option;
    }
    if (std::string(command) != "bench") {
      EXPECT_TRUE(has(help.out, "-o,--out")) << help.out;
    }
  }
  // VTK scans are read by every command (the reader, not each command, knows the extension).
  std::ofstream(path("s.vtk")) << "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n";
  const CmdResult bench = run("bench " + path("s.vtk") + " --hmap-only --repeat 1");
  EXPECT_EQ(bench.code, 0) << bench.out;
  const CmdResult unknown = run("map " + path("s.las") + " --poses " + path("pose.txt") + " --out " + path("m.hmap"));
  EXPECT_EQ(unknown.code, 2);
  std::ofstream(path("s.las")) << "x";
  const CmdResult las = run("map " + path("s.las") + " --poses " + path("pose.txt") + " --out " + path("m.hmap"));
  EXPECT_TRUE(has(las.out, ".pts or .vtk")) << las.out;
  // pvox takes -o and --scans like the others (--max-scans still works).
  const CmdResult pvox = run("pvox " + path("scan.xyz") + " --scans 1 -o " + path("pv"));
  EXPECT_EQ(pvox.code, 0) << pvox.out;
  const CmdResult old = run("pvox " + path("scan.xyz") + " --max-scans 1 -o " + path("pv2"));
  EXPECT_EQ(old.code, 0) << old.out;
}

// An output name whose extension is not what is written is refused in one line, before the work,
// and nothing is written under it.
TEST_F(FirstHourTest, OutputExtensionMustMatchWhatIsWritten) {
  const std::string base = "map " + path("scan.xyz") + " --poses " + path("pose.txt");
  const CmdResult ply = run(base + " --out " + path("a.ply"));
  EXPECT_EQ(ply.code, 2);
  EXPECT_EQ(lines(ply.out), 1U) << ply.out;
  EXPECT_TRUE(has(ply.out, "a.ply: hmap map writes a .hmap map; give a name ending in .hmap, not .ply")) << ply.out;
  EXPECT_FALSE(std::filesystem::exists(path("a.ply")));
  ASSERT_EQ(run(base + " --out " + path("m.HMAP")).code, 0);  // any letter case
  ASSERT_EQ(run(base + " --out " + path("m.hmap")).code, 0);
  const CmdResult jpg = run("render " + path("m.hmap") + " --out " + path("x.jpg"));
  EXPECT_EQ(jpg.code, 2);
  EXPECT_EQ(lines(jpg.out), 1U) << jpg.out;
  EXPECT_TRUE(has(jpg.out, "x.jpg: hmap render writes a PNG picture; give a name ending in .png, not .jpg")) << jpg.out;
  EXPECT_FALSE(std::filesystem::exists(path("x.jpg")));
  for (const std::string& bad : {std::string("--ply ") + path("b.obj"), std::string("--bt ") + path("b.ot"),
                                 std::string("--geotiff ") + path("b.png")}) {
    const CmdResult e = run("export " + path("m.hmap") + " " + bad);
    EXPECT_EQ(e.code, 2) << bad;
    EXPECT_EQ(lines(e.out), 1U) << e.out;
    EXPECT_TRUE(has(e.out, "give a name ending in")) << e.out;
  }
  EXPECT_EQ(run("render " + path("m.hmap") + " --out " + path("x.png")).code, 0);
}

// Every file the tool writes, it reads back: `info` and `render` take the .pvox of `hmap pvox`.
TEST_F(FirstHourTest, InfoAndRenderReadThePvoxMap) {
  const CmdResult built = run("pvox " + path("scan.xyz") + " --poses " + path("pose.txt") + " --out " + path("pv"));
  ASSERT_EQ(built.code, 0) << built.out;
  const std::string map = (dir_ / "pv" / "map.pvox").string();
  const CmdResult info = run("info " + map);
  ASSERT_EQ(info.code, 0) << info.out;
  EXPECT_TRUE(has(info.out, "a PVOX map")) << info.out;
  const CmdResult json = run("info --json " + map);
  ASSERT_EQ(json.code, 0) << json.out;
  const auto j = nlohmann::json::parse(json.out);
  const auto summary = nlohmann::json::parse(std::ifstream(dir_ / "pv" / "summary.json"));
  EXPECT_EQ(j["format"], "pvox");
  EXPECT_EQ(j["voxels"], summary["voxels"]);
  EXPECT_EQ(j["occupied_voxels"], summary["occupied_voxels"]);
  EXPECT_DOUBLE_EQ(j["edge"].get<double>(), summary["edge_m"].get<double>());
  // The floor and the wall: the occupied voxels' centres span them, within a voxel.
  const double edge = j["edge"].get<double>();
  EXPECT_NEAR(j["bounds"]["max"][0].get<double>(), 1.0, edge);
  EXPECT_NEAR(j["bounds"]["min"][2].get<double>(), -1.0, edge);
  for (const char* view : {"top", "oblique"}) {
    const std::string png = path(std::string(view) + ".png");
    const CmdResult r = run("render " + map + " --view " + view + " --out " + png);
    ASSERT_EQ(r.code, 0) << r.out;
    std::ifstream in(png, std::ios::binary);
    std::array<char, 8> magic{};
    in.read(magic.data(), 8);
    EXPECT_EQ(std::string(magic.data() + 1, 3), "PNG") << view;
  }
  const CmdResult layer = run("render " + map + " --layer occupancy --out " + path("l.png"));
  EXPECT_EQ(layer.code, 2);
  EXPECT_EQ(lines(layer.out), 1U) << layer.out;
  // A damaged .pvox is named, not taken for a .hmap.
  std::string bytes;
  {
    std::ifstream in(map, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 0x40);
  std::ofstream(path("bad.pvox"), std::ios::binary) << bytes;
  const CmdResult bad = run("info " + path("bad.pvox"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_TRUE(has(bad.out, "bad.pvox")) << bad.out;
  EXPECT_FALSE(has(bad.out, "hmap file")) << bad.out;
}

/// The counts of one .bt as liboctomap reads it: leaves, and occupied / free volume in voxels.
struct TreeCounts {
  std::size_t leaves = 0;
  double occupied = 0.0;
  double free = 0.0;
};

TreeCounts count_tree(const octomap::OcTree& tree) {
  TreeCounts c;
  c.leaves = tree.getNumLeafNodes();
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    (tree.isNodeOccupied(*it) ? c.occupied : c.free) += std::pow(it.getSize() / tree.getResolution(), 3.0);
  }
  return c;
}

/// The numbers `export --bt` printed: occupied voxels, free voxels, leaves.
std::array<std::size_t, 3> printed_counts(const std::string& out) {
  std::smatch m;
  if (!std::regex_search(out, m, std::regex("wrote (\\d+) occupied and (\\d+) free voxels of .*: (\\d+) OctoMap leaves"))) {
    ADD_FAILURE() << out;
    return {};
  }
  return {std::stoul(m[1]), std::stoul(m[2]), std::stoul(m[3])};
}

// The counts `export --bt` prints are liboctomap's for the file it wrote: the pruned tree's leaves,
// and the occupied volume in voxels of the map's cell.
TEST_F(FirstHourTest, OctomapExportPrintsWhatOctomapCounts) {
  HMap map(indoor_preset());
  // Two HVoxels meeting inside one leaf (counted once), a tall block that prunes, and a low one.
  map.column_for_update({3, -2}).push_back({0.0F, 0.42F, 50.0F, 0.9F});
  map.column_for_update({3, -2}).push_back({0.43F, 0.5F, 5.0F, 0.5F});
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) map.column_for_update({i, j}).push_back({0.0F, 1.59F, 30.0F, 0.9F});
  }
  map.column_for_update({-7, 5}).push_back({-0.3F, -0.3F, 1.0F, 0.3F});
  save_hmap(path("m.hmap"), map);
  const CmdResult r = run("export " + path("m.hmap") + " --bt " + path("m.bt"));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto [occupied, free_voxels, leaves] = printed_counts(r.out);
  const TreeCounts c = count_tree(octomap::OcTree(path("m.bt")));
  EXPECT_EQ(c.leaves, leaves);
  EXPECT_NEAR(c.occupied, static_cast<double>(occupied), 1e-6);
  EXPECT_EQ(free_voxels, 0U);  // a map without its 2D grid: nothing known free
  EXPECT_LT(leaves, occupied);  // the 4 x 4 x 16 block pruned
  EXPECT_TRUE(has(r.out, "no free leaves")) << r.out;
}

// A mapped scan's free space (the 2D grid's free cells, from the ground up to z+) is written as
// free leaves, never over an HVoxel, and liboctomap counts what was printed.
TEST_F(FirstHourTest, OctomapExportWritesTheFreeSpace) {
  ASSERT_EQ(run("map " + path("scan.xyz") + " --poses " + path("pose.txt") + " --preset indoor --out " + path("m.hmap")).code, 0);
  const MapFile file = load_map_file(path("m.hmap"));
  ASSERT_FALSE(file.ground.empty());
  const CmdResult r = run("export " + path("m.hmap") + " --bt " + path("m.bt"));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto [occupied, free_voxels, leaves] = printed_counts(r.out);
  const octomap::OcTree tree(path("m.bt"));
  const TreeCounts c = count_tree(tree);
  EXPECT_EQ(c.leaves, leaves);
  EXPECT_NEAR(c.occupied, static_cast<double>(occupied), 1e-6);
  EXPECT_NEAR(c.free, static_cast<double>(free_voxels), 1e-6);
  EXPECT_GT(free_voxels, 100U) << r.out;
  // Free space lies above the floor (z = -1) and below z+ over it; no HVoxel is free.
  const double z_plus = file.map.params().occupancy.z_plus;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    if (tree.isNodeOccupied(*it)) continue;
    EXPECT_GT(it.getZ(), -1.0) << it.getCoordinate();
    EXPECT_LT(it.getZ(), -1.0 + z_plus + file.map.cell_size()) << it.getCoordinate();
  }
  file.map.for_each_column([&](const CellKey& key, const ColumnView& column) {
    const Eigen::Vector2d xy = file.map.cell_center(key);
    for (const HVoxel& v : column) {
      const octomap::OcTreeNode* n = tree.search(xy.x(), xy.y(), 0.5 * (v.z_min + v.z_max));
      ASSERT_NE(n, nullptr);
      EXPECT_TRUE(tree.isNodeOccupied(n));
    }
  });
}

TEST_F(FirstHourTest, UpFloorOnOffice1FindsNoFloorInsteadOfAWall) {
  HMAP_REQUIRE_DATA("kinect_pcd");
  // office1.pcd sees desks and walls, no floor: its largest plane near the prior is a wall 5 m
  // ahead, which used to become the floor (the map came out on its side). Refused, by name.
  std::ofstream(path("id.txt")) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const CmdResult r = run("map " + (test::data_dir() / "kinect_pcd" / "office1.pcd").string() + " --poses " + path("id.txt") +
                          " --up floor --preset indoor --out " + path("o.hmap"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_TRUE(has(r.out, "no floor plane found")) << r.out;
  EXPECT_TRUE(has(r.out, "3 m of a sensor")) << r.out;
  EXPECT_EQ(lines(r.out), 1U) << r.out;
  // The grabber frames, a camera pitched down at the floor 0.7 m below, still find theirs.
  const CmdResult g = run("map " + (test::data_dir() / "kinect_pcd" / "frame_20121214T142255.814212.pcd").string() + " --poses " +
                          path("id.txt") + " --up floor --preset indoor --out " + path("g.hmap"));
  EXPECT_EQ(g.code, 0) << g.out;
  EXPECT_TRUE(has(g.out, "up from the floor plane")) << g.out;
}

}  // namespace
}  // namespace hmap
