// The CLI on broken input: exit code 2 and one line naming the file, the position and what was
// expected; never a stack trace, an abort or a sanitizer report.

#include <gtest/gtest.h>

#include <cstring>

#include <sys/stat.h>

#include <algorithm>

#include "hmap/core/format.hpp"
#include "hmap/io/hmap_file.hpp"

#include "common/test_data.hpp"
#include "reliability/reliability_util.hpp"

namespace hmap {
namespace {

namespace fs = std::filesystem;

class CliErrorsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::temp_dir("cli_errors");
    write("good.xyz", "1 2 0\n2 3 0\n3 4 0\n");
    write("good.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, std::string_view bytes) const {
    std::ofstream out(dir_ / name, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return (dir_ / name).string();
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  /// Runs hmap and checks the refusal: exit 2, one line "hmap: error: ...", holding every `parts`.
  void expect_refusal(const std::vector<std::string>& args, const std::vector<std::string>& parts) const {
    std::string out;
    const int code = test::run_hmap(args, dir_ / "log", out);
    std::string command;
    for (const auto& a : args) command += " " + a;
    EXPECT_EQ(code, 2) << "hmap" << command << "\n" << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << "hmap" << command << "\n" << out;
    EXPECT_TRUE(out.starts_with("hmap: error: ")) << out;
    for (const auto& part : parts) EXPECT_NE(out.find(part), std::string::npos) << "'" << part << "' not in: " << out;
  }

  fs::path dir_;
};

TEST_F(CliErrorsTest, BrokenScansNameTheFileAndThePosition) {
  const auto map = [&](const std::string& scan) {
    return std::vector<std::string>{"map", scan, "--poses", path("good.txt"), "--out", path("m.hmap")};
  };
  expect_refusal(map(write("huge.pcd",
                           "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1000000000000\n"
                           "HEIGHT 1\nPOINTS 1000000000000\nDATA binary\n" + std::string(24, '\0'))),
                 {"huge.pcd", "POINTS 1000000000000"});
  expect_refusal(map(write("huge.ply",
                           "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\n"
                           "property float y\nproperty float z\nend_header\n" + std::string(24, '\0'))),
                 {"huge.ply", "byte ", "1000000000"});
  expect_refusal(map(write("bad.xyz", "1 2 3\n4 x 6\n")), {"bad.xyz", "line 2"});
  expect_refusal(map(write("odd.bin", std::string(17, '\0'))), {"odd.bin", "16"});
  expect_refusal(map(write("huge.vtk", "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET POLYDATA\n"
                                       "POINTS 4000000000 float\n" + std::string(12, '\0'))),
                 {"huge.vtk", "4000000000"});
  // A terminal escape in the file is written as \x1B, not sent to the user's terminal.
  expect_refusal(map(write("ctrl.xyz", "1 2 3\n4 \x1b[2J 6\n")), {"ctrl.xyz", "line 2", "\\x1B[2J"});
}

TEST_F(CliErrorsTest, BrokenRos2RecordingsNameTheFileAndWhatIsWrong) {
  // An MCAP file whose header record claims 2^56 bytes, and one whose only chunk claims 2^60.
  const std::string magic("\x89MCAP0\r\n", 8);
  const std::string huge = write("huge.mcap", magic + '\x01' + std::string(7, '\0') + '\x01' + std::string(8, '\0'));
  for (const char* command : {"bag-info", "map"}) {
    std::vector<std::string> args = {command, "--bag", huge, "--cloud-topic", "/c", "--out", path("m.hmap")};
    if (std::string(command) == "bag-info") args = {command, huge};
    expect_refusal(args, {"huge.mcap: byte 8: header record runs past the end of the file"});
  }
  // A rosbag2 folder without its metadata.yaml.
  fs::create_directories(dir_ / "rosbag2");
  write("rosbag2/rosbag2_0.db3", "SQLite format 3");
  expect_refusal({"bag-info", path("rosbag2")}, {"rosbag2: is a folder without metadata.yaml: not a rosbag2 recording"});
  expect_refusal({"slam", "--bag", path("rosbag2"), "--cloud-topic", "/c", "--out", path("m.hmap")},
                 {"rosbag2: is a folder without metadata.yaml"});
  // metadata.yaml naming a file that is not there.
  write("rosbag2/metadata.yaml", "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  relative_file_paths:\n    - gone.db3\n");
  expect_refusal({"bag-info", path("rosbag2")}, {"metadata.yaml: relative_file_paths: lists ", "gone.db3, which does not exist"});
  // A .db3 that is not SQLite.
  write("rosbag2/metadata.yaml", "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  relative_file_paths:\n    - rosbag2_0.db3\n");
  expect_refusal({"bag-info", path("rosbag2")}, {"rosbag2_0.db3"});
}

TEST_F(CliErrorsTest, BrokenPosesConfigsAndMapsNameTheFileAndThePosition) {
  const auto map_with = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {"map", path("good.xyz"), "--out", path("m.hmap")};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  };
  expect_refusal(map_with({"--poses", write("nan.txt", "1 0 0 nan 0 1 0 0 0 0 1 0\n")}), {"nan.txt", "line 1", "not finite"});
  expect_refusal(map_with({"--poses", write("scaled.txt", "# c\n2 0 0 0 0 2 0 0 0 0 2 0\n")}),
                 {"scaled.txt", "line 2", "not a rotation"});
  expect_refusal(map_with({"--poses", path("good.txt"), "--config", write("loop.yaml", "a: &x {b: *x}\n")}),
                 {"loop.yaml", "line 1"});
  expect_refusal(map_with({"--poses", path("good.txt"), "--config", write("syntax.yaml", "map: [1, \"\x01\n")}),
                 {"syntax.yaml", "line "});
  expect_refusal({"info", write("bad.hmap", std::string("\x89HMAP\r\n\x1a\x02\0\0\0\0\0\0\0", 16) + std::string(40, '\xff'))},
                 {"bad.hmap", "byte "});
}

TEST_F(CliErrorsTest, AbsurdParametersAreRefusedByName) {
  const std::vector<std::string> base = {"map", path("good.xyz"), "--poses", path("good.txt"), "--out", path("m.hmap")};
  auto with = [&](std::vector<std::string> extra) {
    auto args = base;
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  };
  expect_refusal(with({"--cell", "1e-6"}), {"map.cell_size"});
  expect_refusal(with({"--max-range", "1e9"}), {"map.max_range"});
  expect_refusal(with({"--set", "ground.iterations=4294967696"}), {"ground.iterations", "integer"});
  expect_refusal(with({"--set", "map.cell_size=nan"}), {"map.cell_size"});
}

// Issue 14: outputs that are not regular files, missing folders, inputs that are not regular
// files, parameters without bounds, loops and allocations sized by a map.

TEST_F(CliErrorsTest, OutputsThatAreNotRegularFilesAreNeverReplaced) {
  const std::string fifo = path("fifo.hmap");  // named as a map: the extension is right, the file kind is not
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  // A link to /dev/null: as root, --out /dev/null had its device node replaced by a regular file;
  // through a link the test shows the refusal without risking the machine's /dev/null.
  const std::string null_link = path("null.hmap");
  fs::create_symlink("/dev/null", null_link);
  fs::create_directory(path("folder.hmap"));
  for (const std::string& out : {fifo, null_link, path("folder.hmap")}) {
    expect_refusal({"map", path("good.xyz"), "--poses", path("good.txt"), "--out", out}, {out, "not a regular file"});
  }
  struct stat st {};
  ASSERT_EQ(::stat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  EXPECT_TRUE(fs::is_symlink(null_link));
  ASSERT_EQ(::stat(null_link.c_str(), &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
}

TEST_F(CliErrorsTest, AMissingOutputFolderIsNamedBeforeTheWork) {
  // Before: every scan was mapped, then the save failed naming a hidden temporary file.
  expect_refusal({"map", path("good.xyz"), "--poses", path("good.txt"), "--out", path("nodir/m.hmap")},
                 {"nodir/m.hmap", "output folder", "does not exist"});
  std::string out;
  (void)test::run_hmap({"map", path("good.xyz"), "--poses", path("good.txt"), "--out", path("nodir/m.hmap")}, dir_ / "log", out);
  EXPECT_EQ(out.find(".tmp."), std::string::npos) << out;
  // Every output of export is checked before the map is read (the map here does not even exist).
  expect_refusal({"export", path("absent.hmap"), "--ply", path("nodir/m.ply")}, {"nodir/m.ply", "does not exist"});
  expect_refusal({"export", path("absent.hmap"), "--pgm", path("nodir/m")}, {"nodir/m.pgm", "does not exist"});
}

TEST_F(CliErrorsTest, InputsThatAreNotRegularFilesAreRefusedWithoutBlocking) {
  const std::string fifo = path("scan.xyz");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  // No writer ever opens the FIFO: a plain open() for reading would wait forever.
  expect_refusal({"map", fifo, "--poses", path("good.txt"), "--out", path("m.hmap")}, {fifo, "pipe or FIFO", "not a regular file"});
  expect_refusal({"map", path("good.xyz"), "--poses", "/dev/zero", "--out", path("m.hmap")},
                 {"/dev/zero", "character device", "not a regular file"});
  expect_refusal({"info", fifo}, {fifo, "not a regular file"});
  // A folder as the parameter file: one line naming it, not libstdc++'s "basic_filebuf" message.
  fs::create_directory(path("conf"));
  expect_refusal({"map", path("good.xyz"), "--poses", path("good.txt"), "--out", path("m.hmap"), "--config", path("conf")},
                 {path("conf"), "a folder, not a regular file"});
  expect_refusal({"map", path("good.xyz"), "--poses", path("good.txt"), "--out", path("m.hmap"), "--config",
                  write("twice.yaml", "map:\n  cell_size: 0.2\nmap.cell_size: 0.3\n")},
                 {"twice.yaml", "line 3", "'map.cell_size' is given twice (first on line 2)"});
}

TEST_F(CliErrorsTest, TextThatIsNotACloudIsRefused) {
  // A pose file as a scan: its rows read as points (1, 0, 0), all within min_range; this saved an
  // empty map with exit 0.
  expect_refusal({"map", path("good.txt"), "--poses", path("good.txt"), "--out", path("m.hmap")},
                 {"no point of the 1 read from 1 scans was kept", "1 out of the 1.2-25 m range"});
  EXPECT_FALSE(fs::exists(path("m.hmap")));
  expect_refusal({"map", write("k.txt", "fx fy cx cy\n525 525 319.5 239.5\n"), "--poses", path("good.txt"), "--out", path("m.hmap")},
                 {"k.txt", "line 1", "must name the columns x, y and z"});
}

TEST_F(CliErrorsTest, ParametersAndFlagsBeyondTheirRangesAreRefusedByName) {
  const std::vector<std::string> map = {"map", path("good.xyz"), "--poses", path("good.txt"), "--out", path("m.hmap")};
  const auto with = [&](std::vector<std::string> args, std::vector<std::string> extra) {
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  };
  expect_refusal(with(map, {"--set", "ground.iterations=2147483647"}), {"ground.iterations = 2147483647", "[0, 100000]"});
  expect_refusal(with(map, {"--set", "slam.coarse_translation=1000000"}), {"slam.coarse_translation", "[0, 20] m"});
  expect_refusal(with(map, {"--set", "slam.coarse_rotation=1e12"}), {"slam.coarse_rotation", "[0, 3.14"});
  expect_refusal(with(map, {"--scans", "-1"}), {"--scans: must be a count (0, 1, 2, ...), got '-1'"});
}

TEST_F(CliErrorsTest, LoopsAndAllocationsSizedByAMapAreBounded) {
  // A valid map (the library writes it, checksum included) with one HVoxel at 3e38 m and one
  // 100 km tall: `z += step` never ended on the first, and the second asked for gigabytes.
  HMap far(Params{});
  far.column_for_update(CellKey{0, 0}).push_back(HVoxel{3e38F, 3e38F, 10.0F, 1.0F});
  save_hmap(path("far.hmap"), far);
  expect_refusal({"export", path("far.hmap"), "--bt", path("far.bt")}, {"far.bt", "beyond OctoMap's key range", "nothing written"});
  EXPECT_FALSE(fs::exists(path("far.bt")));
  HMap tall(Params{});
  tall.column_for_update(CellKey{0, 0}).push_back(HVoxel{0.0F, 1e5F, 10.0F, 1.0F});
  save_hmap(path("tall.hmap"), tall);
  expect_refusal({"--max-memory", "64", "export", path("tall.hmap"), "--ply", path("tall.ply"), "--points", "--z-step", "0.001"},
                 {"points recovered every 0.001 m", "memory budget of 64 MiB"});
  expect_refusal({"export", path("tall.hmap"), "--ply", path("tall.ply"), "--points", "--z-step", "1e-6"},
                 {"--z-step", "[0.001, 100]"});
  // 100 km is beyond OctoMap's ±32768 leaves of 0.25 m (8192 m): refused, not dropped and counted.
  expect_refusal({"export", path("tall.hmap"), "--bt", path("tall.bt")}, {"1 HVoxels lie beyond OctoMap's key range (+-8192 m"});
  expect_refusal({"render", path("tall.hmap"), "--view", "oblique", "--z-low", "1e17", "--out", path("t.png")},
                 {"--z-low", "[-100000, 100000]"});
}

TEST_F(CliErrorsTest, TheMapGrowingBeyondTheBudgetIsRefusedByScan) {
  // A flat floor of 280 x 280 cells of 0.1 m, seen from 4 poses 100 m apart: each scan adds
  // 78,400 new cells (about 1.5 MiB of HMAP and 2D grid; the third passes 4 MiB). Refused by scan,
  // before the next one, and nothing written.
  std::string floor;
  for (int i = -140; i < 140; ++i) {
    for (int j = -140; j < 140; ++j) floor += format("%.2f %.2f -1.5\n", i * 0.1 + 0.05, j * 0.1 + 0.05);
  }
  const std::string scan = write("floor.xyz", floor);
  write("p4.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 100 0 1 0 0 0 0 1 0\n1 0 0 200 0 1 0 0 0 0 1 0\n1 0 0 300 0 1 0 0 0 0 1 0\n");
  const std::vector<std::string> scans = {scan, scan, scan, scan, "--poses", path("p4.txt"), "--cell", "0.1", "--max-range", "20",
                                          "--preset", "outdoor"};
  const auto with = [&](std::vector<std::string> head, const std::string& out) {
    head.insert(head.end(), scans.begin(), scans.end());
    head.insert(head.end(), {"--out", out});
    return head;
  };
  expect_refusal(with({"--max-memory", "4", "map"}, path("m.hmap")),
                 {"scan 2 (", "floor.xyz", "the map needs 6 MiB, more than the memory budget of 4 MiB", "--max-memory"});
  EXPECT_FALSE(fs::exists(path("m.hmap")));
  // compare holds the elevation map of [9] beside: one scan fewer.
  expect_refusal(with({"--max-memory", "4", "compare", "--skip-octomap"}, path("cmp")),
                 {"scan 1 (", "floor.xyz", "the comparison needs", "more than the memory budget of 4 MiB"});
  EXPECT_FALSE(fs::exists(path("cmp")));
  std::string log;  // the same run within a budget of 16 MiB: mapped
  EXPECT_EQ(test::run_hmap(with({"--max-memory", "16", "map"}, path("m.hmap")), dir_ / "log", log), 0) << log;
  // SLAM: one real OS0-64 scan at 1 cm cells already holds 6 MiB.
  HMAP_REQUIRE_DATA("balm_os0");
  expect_refusal({"--max-memory", "4", "slam", "--kitti", (test::data_dir() / "balm_os0").string(), "--scans", "2", "--cell", "0.01",
                  "--max-range", "20", "--out", path("slam")},
                 {"scan 0 (", "000000.bin", "the map needs", "more than the memory budget of 4 MiB"});
  EXPECT_FALSE(fs::exists(path("slam")));
}

// A scan file is checked against the budget before it is read: its bytes and its points are held
// at once (2 x 3.2 MB here against 4 MiB), refused by scan and file, nothing written.
TEST_F(CliErrorsTest, AScanBeyondTheBudgetIsRefusedBeforeItIsRead) {
  std::string bin(200000 * 16, '\0');
  for (std::size_t k = 0; k < 200000; ++k) {
    const float p[4] = {5.0F + static_cast<float>(k % 100) * 0.01F, static_cast<float>(k / 100) * 0.001F, -1.0F, 0.0F};
    std::memcpy(bin.data() + k * 16, p, sizeof p);
  }
  const std::string scan = write("big.bin", bin);
  const std::string poses = write("p1.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  expect_refusal({"--max-memory", "4", "map", scan, "--poses", poses, "--out", path("m.hmap")},
                 {"big.bin: reading the scan needs 7 MiB, more than the memory budget of 4 MiB", "--max-memory"});
  EXPECT_FALSE(fs::exists(path("m.hmap")));
  std::string log;  // within 16 MiB: mapped
  EXPECT_EQ(test::run_hmap({"--max-memory", "16", "map", scan, "--poses", poses, "--out", path("m.hmap")}, dir_ / "log", log), 0) << log;
}

TEST_F(CliErrorsTest, AFlagValueWithATerminalEscapeIsQuotedNotSent) {
  // CLI11 quotes the argument it cannot take; the escape is written as \x1B, in one line.
  expect_refusal({"map", "--cell", "1\x1b[2J", path("good.xyz"), "--out", path("m.hmap")}, {"--cell", "1\\x1B[2J"});
}

}  // namespace
}  // namespace hmap
