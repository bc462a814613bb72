// No torn maps: `hmap map` is killed (SIGKILL) at random moments while it saves over an existing
// map, many times; each time the file on disk must be the old map or the new one, byte for byte,
// and load. Maps are saved through write_file_atomic (temporary file, fsync, rename).

#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <random>
#include <thread>

#include "common/test_data.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/hmap_file.hpp"
#include "reliability/reliability_util.hpp"

namespace hmap {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

class TornFileTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::temp_dir("torn_file"); }
  void TearDown() override { fs::remove_all(dir_); }

  /// `hmap map` of the first `scans` scans of balm_os0 into `out`.
  static std::vector<std::string> map_args(int scans, const fs::path& out) {
    return {"map", "--kitti", (test::data_dir() / "balm_os0").string(), "--scans", std::to_string(scans),
            "--preset", "outdoor", "--cell", "0.1", "--out", out.string()};
  }

  /// Temporary files of an interrupted save beside `target` (".NAME.tmp.PID.RANDOM").
  std::vector<fs::path> temporaries(const fs::path& target) const {
    std::vector<fs::path> found;
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict, its bug 105329) on "." + string.
    std::string prefix = ".";
    prefix += target.filename().string();
    prefix += ".tmp.";
    for (const auto& entry : fs::directory_iterator(dir_)) {
      if (entry.path().filename().string().starts_with(prefix)) found.push_back(entry.path());
    }
    return found;
  }

  fs::path dir_;
};

TEST_F(TornFileTest, KilledSavesLeaveTheOldMapOrTheNewOne) {
  HMAP_REQUIRE_DATA("balm_os0");
  // The old map (2 scans) and the new one (3 scans), made once without interruption.
  const fs::path old_path = dir_ / "old.hmap";
  const fs::path new_path = dir_ / "new.hmap";
  std::string out;
  ASSERT_EQ(test::run_hmap(map_args(2, old_path), dir_ / "log", out), 0) << out;
  const auto t0 = Clock::now();
  ASSERT_EQ(test::run_hmap(map_args(3, new_path), dir_ / "log", out), 0) << out;
  const auto full_run = Clock::now() - t0;
  const std::string old_bytes = test::read_bytes(old_path);
  const std::string new_bytes = test::read_bytes(new_path);
  ASSERT_NE(old_bytes, new_bytes);

  // Half of the kills at a random moment of the whole run, half a random 0-3 ms after the
  // temporary file of the save appears (inside the save: writing, fsync, rename or just after).
  std::mt19937 rng(20240611);
  constexpr int kRuns = 30;
  const fs::path target = dir_ / "map.hmap";
  int kept_old = 0;
  int got_new = 0;
  int killed_while_saving = 0;
  int leftover_temporaries = 0;
  const auto deadline = Clock::now() + std::chrono::seconds(25);
  for (int run = 0; run < kRuns && Clock::now() < deadline; ++run) {
    fs::copy_file(old_path, target, fs::copy_options::overwrite_existing);
    test::Child child(map_args(3, target));
    ASSERT_TRUE(child.started());
    if (run % 2 == 0) {
      std::uniform_real_distribution<double> at(0.0, 1.1);
      const auto delay = std::chrono::duration_cast<Clock::duration>(full_run * at(rng));
      const auto kill_at = Clock::now() + delay;
      while (Clock::now() < kill_at && !child.finished()) std::this_thread::sleep_for(std::chrono::microseconds(200));
    } else {
      std::uniform_int_distribution<int> after_us(0, 3000);
      const auto give_up = Clock::now() + 5 * full_run;
      while (temporaries(target).empty() && !child.finished() && Clock::now() < give_up) {
      }
      if (!child.finished()) {
        ++killed_while_saving;
        std::this_thread::sleep_for(std::chrono::microseconds(after_us(rng)));
      }
    }
    child.kill();
    (void)child.wait();

    const std::string bytes = test::read_bytes(target);
    const bool is_old = bytes == old_bytes;
    const bool is_new = bytes == new_bytes;
    ASSERT_TRUE(is_old || is_new) << "run " << run << ": " << target << " holds " << bytes.size()
                                  << " bytes, neither the old map (" << old_bytes.size() << ") nor the new one ("
                                  << new_bytes.size() << ")";
    EXPECT_NO_THROW((void)load_map_file(target)) << "run " << run;
    kept_old += is_old ? 1 : 0;
    got_new += is_new ? 1 : 0;
    // A killed save cannot remove its temporary file; it never replaces the map.
    for (const auto& t : temporaries(target)) {
      ++leftover_temporaries;
      fs::remove(t);
    }
  }
  std::printf("[          ] %d kills: old map kept %d, new map %d; %d kills after the save began; "
              "%d temporary files left by killed saves\n",
              kept_old + got_new, kept_old, got_new, killed_while_saving, leftover_temporaries);
  EXPECT_GT(kept_old, 0);
  EXPECT_GT(killed_while_saving, 0) << "no kill landed after the save began: the test proved little";
}

/// The files of a pvox output folder, name to bytes; summary.json holds timings, so only its
/// scan count is kept.
std::map<std::string, std::string> pvox_set(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    const std::string bytes = test::read_bytes(entry.path());
    if (name == "summary.json") {
      const auto at = bytes.find("\"scans\": ");
      files[name] = at == std::string::npos ? "?" : bytes.substr(at, 11);
    } else {
      files[name] = bytes;
    }
  }
  return files;
}

TEST_F(TornFileTest, AKilledPvoxRunLeavesTheOldFolderOrTheNewOne) {
  HMAP_REQUIRE_DATA("balm_os0");
  // Issue 14: the folder's map, CSV, pictures and summary are one set. Old: 1 scan; new: 2.
  const auto pvox_args = [](int scans, const fs::path& out) {
    return std::vector<std::string>{"pvox", "--kitti", (test::data_dir() / "balm_os0").string(), "--max-scans",
                                    std::to_string(scans), "--edge", "0.2", "--measure", "poses", "--out", out.string()};
  };
  std::string out;
  ASSERT_EQ(test::run_hmap(pvox_args(1, dir_ / "old"), dir_ / "log", out), 0) << out;
  const auto t0 = Clock::now();
  ASSERT_EQ(test::run_hmap(pvox_args(2, dir_ / "new"), dir_ / "log", out), 0) << out;
  const auto full_run = Clock::now() - t0;
  const auto old_set = pvox_set(dir_ / "old");
  const auto new_set = pvox_set(dir_ / "new");
  ASSERT_NE(old_set, new_set);
  ASSERT_EQ(old_set.at("summary.json"), "\"scans\": 1,");

  std::mt19937 rng(20261202);
  const fs::path target = dir_ / "pv";
  int kept_old = 0;
  int got_new = 0;
  int killed_while_writing = 0;
  for (int run = 0; run < 16; ++run) {
    fs::remove_all(target);
    fs::copy(dir_ / "old", target);
    test::Child child(pvox_args(2, target));
    ASSERT_TRUE(child.started());
    if (run % 2 == 0) {  // anywhere in the run
      std::uniform_real_distribution<double> at(0.0, 1.1);
      const auto kill_at = Clock::now() + std::chrono::duration_cast<Clock::duration>(full_run * at(rng));
      while (Clock::now() < kill_at && !child.finished()) std::this_thread::sleep_for(std::chrono::microseconds(200));
    } else {  // 0-20 ms after the staging folder appears: among the files being written, or the swap
      std::uniform_int_distribution<int> after_us(0, 20000);
      const auto give_up = Clock::now() + 5 * full_run;
      while (temporaries(target).empty() && !child.finished() && Clock::now() < give_up) {
      }
      if (!child.finished()) {
        ++killed_while_writing;
        std::this_thread::sleep_for(std::chrono::microseconds(after_us(rng)));
      }
    }
    child.kill();
    (void)child.wait();
    const auto set = pvox_set(target);
    const bool is_old = set == old_set;
    const bool is_new = set == new_set;
    ASSERT_TRUE(is_old || is_new) << "run " << run << ": " << target << " holds " << set.size()
                                  << " files, neither the old set nor the new one";
    kept_old += is_old ? 1 : 0;
    got_new += is_new ? 1 : 0;
    for (const auto& t : temporaries(target)) fs::remove_all(t);  // a killed run leaves its staging folder
  }
  std::printf("[          ] 16 kills: old folder kept %d, new folder %d; %d kills after the staging folder appeared\n",
              kept_old, got_new, killed_while_writing);
  EXPECT_GT(kept_old, 0);
  EXPECT_GT(killed_while_writing, 0) << "no kill landed while the set was written: the test proved little";
}

}  // namespace
}  // namespace hmap
