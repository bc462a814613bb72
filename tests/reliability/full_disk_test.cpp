// A full disk: each output is written to a file system of 64 KiB (a tmpfs mounted in a user and
// mount namespace of the test's own, `unshare --user --map-root-user --mount`: no root and no
// change to the machine). Every save must fail with one line naming the file and "No space left
// on device", exit 2, leave the old file as it was and no temporary file behind.
//
// Skipped where unprivileged user namespaces are off (then the message is not tested).

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <string>

#include "common/test_data.hpp"
#include "reliability/reliability_util.hpp"

namespace hmap {
namespace {

namespace fs = std::filesystem;

/// `text` quoted for sh.
std::string quoted(const std::string& text) {
  std::string q = "'";
  for (const char c : text) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

class FullDiskTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::temp_dir("full_disk");
    if (std::system("unshare --user --map-root-user --mount sh -c 'mount -t tmpfs -o size=64k tmpfs /mnt' >/dev/null 2>&1") != 0) {
      GTEST_SKIP() << "unprivileged user and mount namespaces are not available here";
    }
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Runs `hmap ARGS` with DISK (in ARGS) a 64 KiB tmpfs holding `old_name` with the bytes "old";
  /// returns its exit code, its output in `out`, and in `after` the disk's files and old_name's
  /// bytes as they were when it ended ("name=bytes;...").
  int run_on_full_disk(const std::string& args, const std::string& old_name, std::string& out, std::string& after) {
    const fs::path disk = dir_ / "disk";
    fs::create_directories(disk);
    std::string line = args;
    for (std::size_t at = line.find("DISK"); at != std::string::npos; at = line.find("DISK", at)) line.replace(at, 4, disk.string());
    const std::string script =
        "mount -t tmpfs -o size=64k tmpfs " + quoted(disk.string()) + " || exit 99\n" +
        "printf old > " + quoted((disk / old_name).string()) + "\n" +
        quoted(test::hmap_bin()) + " " + line + " > " + quoted((dir_ / "out").string()) + " 2>&1\n" +
        "code=$?\n" +
        "for f in $(ls -A " + quoted(disk.string()) + "); do printf '%s;' \"$f\"; done > " + quoted((dir_ / "after").string()) + "\n" +
        "cat " + quoted((disk / old_name).string()) + " >> " + quoted((dir_ / "after").string()) + "\n" +
        "exit $code\n";
    std::ofstream(dir_ / "script.sh") << script;
    const int status = std::system(("unshare --user --map-root-user --mount sh " + quoted((dir_ / "script.sh").string())).c_str());
    out = test::read_bytes(dir_ / "out");
    after = test::read_bytes(dir_ / "after");
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  fs::path dir_;
};

TEST_F(FullDiskTest, AMapSavedToAFullDiskSaysSoAndKeepsTheOldOne) {
  HMAP_REQUIRE_DATA("balm_os0");
  std::string out, after;
  // One OS0-64 scan at 0.1 m: a map of some hundred KiB, more than the 64 KiB disk holds.
  const int code = run_on_full_disk("map --kitti " + (test::data_dir() / "balm_os0").string() +
                                        " --scans 1 --preset outdoor --cell 0.1 --out DISK/m.hmap",
                                    "m.hmap", out, after);
  ASSERT_NE(code, 99) << "mount failed";
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("m.hmap"), std::string::npos) << out;
  EXPECT_NE(out.find("No space left on device"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  EXPECT_EQ(after, "m.hmap;old") << "the disk must hold the old map alone, unchanged";
}

TEST_F(FullDiskTest, ExportsToAFullDiskSaySoAndKeepTheOldFiles) {
  HMAP_REQUIRE_DATA("balm_os0");
  std::string out, after;
  const fs::path map = dir_ / "m.hmap";
  ASSERT_EQ(test::run_hmap({"map", "--kitti", (test::data_dir() / "balm_os0").string(), "--scans", "2", "--preset", "outdoor",
                            "--cell", "0.1", "--out", map.string()},
                           dir_ / "log", out),
            0)
      << out;
  // The OctoMap export: liboctomap's writer gives up on its own; the message says why.
  int code = run_on_full_disk("export " + map.string() + " --bt DISK/m.bt", "m.bt", out, after);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("m.bt"), std::string::npos) << out;
  EXPECT_NE(out.find("No space left on device"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  EXPECT_EQ(after, "m.bt;old");
  // The PLY boxes.
  code = run_on_full_disk("export " + map.string() + " --ply DISK/m.ply", "m.ply", out, after);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("m.ply"), std::string::npos) << out;
  EXPECT_NE(out.find("No space left on device"), std::string::npos) << out;
  EXPECT_EQ(after, "m.ply;old");
}

TEST_F(FullDiskTest, AFolderOutputOnAFullDiskLeavesNothingHalfWritten) {
  std::string out, after;
  // simulate into a full disk: the staging folder is removed, the old folder is kept (here a
  // file "old" beside it stands for the rest of the disk).
  const int code = run_on_full_disk("simulate --scene office --sensor kinect --stride 4 --frames 6 --out DISK/seq", "keep", out, after);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("No space left on device"), std::string::npos) << out;
  EXPECT_EQ(after, "keep;old") << "no staging folder and no half recording left";
}

}  // namespace
}  // namespace hmap
