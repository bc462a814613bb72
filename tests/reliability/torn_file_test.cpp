// No torn maps: `hmap map` is killed (SIGKILL) at random moments while it saves over an existing
// map, many times; each time the file on disk must be the old map or the new one, byte for byte,
// and load. Maps are saved through write_file_atomic (temporary file, fsync, rename). The same for
// the sets of files: the folders of pvox, slam, simulate and demo (write_folder_atomic), and the
// .pgm + .yaml pair of export --pgm (write_files_with_record).

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <optional>
#include <fstream>
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
 public:
  /// Staging folders of an interrupted run beside the folder `target`.
  std::vector<fs::path> staging_folders(const fs::path& target) const { return temporaries(target); }

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
    const fs::path folder = target.parent_path();
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict, its bug 105329) on "." + string.
    std::string prefix = ".";
    prefix += target.filename().string();
    prefix += ".tmp.";
    for (const auto& entry : fs::directory_iterator(folder)) {
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

/// Kills `child`: in even runs at a random moment of up to 1.1 `full_run`s, in odd runs a random
/// 0..`max_us` microseconds after `begun()` holds (the save or the staging folder appeared).
/// Returns whether the kill came after it began.
bool kill_during(test::Child& child, int run, Clock::duration full_run, std::mt19937& rng, int max_us,
                 const std::function<bool()>& begun) {
  bool after_begin = false;
  if (run % 2 == 0) {
    std::uniform_real_distribution<double> at(0.0, 1.1);
    const auto kill_at = Clock::now() + std::chrono::duration_cast<Clock::duration>(full_run * at(rng));
    while (Clock::now() < kill_at && !child.finished()) std::this_thread::sleep_for(std::chrono::microseconds(100));
  } else {
    std::uniform_int_distribution<int> after_us(0, max_us);
    const auto give_up = Clock::now() + 5 * full_run;
    while (!begun() && !child.finished() && Clock::now() < give_up) {
    }
    if (!child.finished()) {
      after_begin = true;
      std::this_thread::sleep_for(std::chrono::microseconds(after_us(rng)));
    }
  }
  child.kill();
  (void)child.wait();
  return after_begin;
}

/// Every file under `dir` (recursively), relative name to bytes; the files named in `timed`
/// hold timings, so only their presence is compared.
std::map<std::string, std::string> folder_set(const fs::path& dir, std::initializer_list<std::string_view> timed = {}) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    const std::string name = fs::relative(entry.path(), dir).string();
    bool is_timed = false;
    for (const std::string_view t : timed) is_timed = is_timed || name == t;
    files[name] = is_timed ? std::string("(timed)") : test::read_bytes(entry.path());
  }
  return files;
}

/// Runs `args(old_n, target)` over a copy of the old folder, killing it 12 times (half at a random
/// moment, half 0-20 ms after the staging folder appears), and checks that `target` then holds
/// exactly the old set or the new one.
void kill_folder_runs(TornFileTest& t, const fs::path& dir, const std::string& what,
                      const std::function<std::vector<std::string>(bool, const fs::path&)>& args,
                      std::initializer_list<std::string_view> timed) {
  std::string out;
  ASSERT_EQ(test::run_hmap(args(false, dir / "old"), dir / "log", out), 0) << out;
  const auto t0 = Clock::now();
  ASSERT_EQ(test::run_hmap(args(true, dir / "new"), dir / "log", out), 0) << out;
  const auto full_run = Clock::now() - t0;
  const auto old_set = folder_set(dir / "old", timed);
  const auto new_set = folder_set(dir / "new", timed);
  ASSERT_NE(old_set, new_set);

  const fs::path target = dir / "target";
  // Not killed, over the old folder: exactly the new set (a kill after the end gives the same).
  fs::copy(dir / "old", target, fs::copy_options::recursive);
  ASSERT_EQ(test::run_hmap(args(true, target), dir / "log", out), 0) << out;
  ASSERT_EQ(folder_set(target, timed), new_set) << what << ": the same run over the old folder differs from the new one";

  std::mt19937 rng(20261202);
  int kept_old = 0;
  int got_new = 0;
  int killed_while_writing = 0;
  for (int run = 0; run < 12; ++run) {
    fs::remove_all(target);
    fs::copy(dir / "old", target, fs::copy_options::recursive);
    test::Child child(args(true, target));
    ASSERT_TRUE(child.started());
    killed_while_writing += kill_during(child, run, full_run, rng, 20000, [&] { return !t.staging_folders(target).empty(); }) ? 1 : 0;
    const auto set = folder_set(target, timed);
    const bool is_old = set == old_set;
    const bool is_new = set == new_set;
    ASSERT_TRUE(is_old || is_new) << what << " run " << run << ": " << target << " holds " << set.size()
                                  << " files, neither the old set (" << old_set.size() << ") nor the new one ("
                                  << new_set.size() << ")";
    kept_old += is_old ? 1 : 0;
    got_new += is_new ? 1 : 0;
    for (const auto& s : t.staging_folders(target)) fs::remove_all(s);  // a killed run leaves its staging folder
  }
  std::printf("[          ] %s, 12 kills: old folder kept %d, new folder %d; %d kills after the staging folder appeared\n",
              what.c_str(), kept_old, got_new, killed_while_writing);
  EXPECT_GT(kept_old, 0) << what;
  EXPECT_GT(killed_while_writing, 0) << what << ": no kill landed while the set was written: the test proved little";
}

TEST_F(TornFileTest, AKilledPvoxRunLeavesTheOldFolderOrTheNewOne) {
  HMAP_REQUIRE_DATA("balm_os0");
  // Issue 14: the folder's map, CSV, pictures and summary are one set. Old: 1 scan; new: 2
  // (summary.json holds timings: its presence is compared).
  kill_folder_runs(*this, dir_, "pvox", [](bool is_new, const fs::path& out) {
    return std::vector<std::string>{"pvox", "--kitti", (test::data_dir() / "balm_os0").string(), "--max-scans", is_new ? "2" : "1",
                                    "--edge", "0.2", "--measure", "poses", "--out", out.string()};
  }, {"summary.json"});
}

TEST_F(TornFileTest, AKilledSlamRunLeavesTheOldFolderOrTheNewOne) {
  HMAP_REQUIRE_DATA("balm_os0");
  kill_folder_runs(*this, dir_, "slam", [](bool is_new, const fs::path& out) {
    return std::vector<std::string>{"slam", "--kitti", (test::data_dir() / "balm_os0").string(), "--scans", is_new ? "3" : "2",
                                    "--out", out.string()};
  }, {"matches.csv"});
}

TEST_F(TornFileTest, AKilledSimulateRunLeavesTheOldRecordingOrTheNewOne) {
  // The new recording is shorter: before issue 14 its folder kept the old run's last scans
  // beside the new poses even without a kill.
  kill_folder_runs(*this, dir_, "simulate", [](bool is_new, const fs::path& out) {
    return std::vector<std::string>{"simulate", "--scene", "office", "--sensor", "kinect", "--stride", "4", "--frames",
                                    is_new ? "3" : "5", "--seed", is_new ? "2" : "1", "--out", out.string()};
  }, {});
}

TEST_F(TornFileTest, AKilledDemoLeavesTheOldFolderOrTheNewOne) {
  kill_folder_runs(*this, dir_, "demo", [](bool is_new, const fs::path& out) {
    return std::vector<std::string>{"demo", "--scene", "boxes", "--frames", is_new ? "4" : "3", "--out", out.string()};
  }, {"report.md"});  // the report holds timings
}

TEST_F(TornFileTest, AShorterSimulationReplacesTheWholeRecording) {
  std::string out;
  const auto simulate = [&](const char* frames) {
    return std::vector<std::string>{"simulate", "--scene", "office", "--sensor", "kinect", "--stride", "4", "--frames", frames,
                                    "--out", (dir_ / "seq").string()};
  };
  ASSERT_EQ(test::run_hmap(simulate("6"), dir_ / "log", out), 0) << out;
  ASSERT_EQ(test::run_hmap(simulate("2"), dir_ / "log", out), 0) << out;
  std::vector<std::string> scans;
  for (const auto& e : fs::directory_iterator(dir_ / "seq" / "velodyne")) scans.push_back(e.path().filename().string());
  std::sort(scans.begin(), scans.end());
  EXPECT_EQ(scans, (std::vector<std::string>{"000000.bin", "000001.bin"}));
  // A folder holding a file of the user's is not replaced: refused by name before the work.
  std::ofstream(dir_ / "seq" / "notes.txt") << "mine\n";
  ASSERT_EQ(test::run_hmap(simulate("2"), dir_ / "log", out), 2) << out;
  EXPECT_NE(out.find("holds 'notes.txt', which hmap simulate does not write"), std::string::npos) << out;
  EXPECT_EQ(test::read_bytes(dir_ / "seq" / "notes.txt"), "mine\n");
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
}

/// The .pgm and .yaml written by `hmap export MAP --pgm STEM`.
struct PgmPair {
  std::string pgm;
  std::optional<std::string> yaml;
  bool operator==(const PgmPair&) const = default;
};

PgmPair read_pair(const fs::path& stem) {
  PgmPair p;
  p.pgm = test::read_bytes(fs::path(stem).concat(".pgm"));
  if (fs::exists(fs::path(stem).concat(".yaml"))) p.yaml = test::read_bytes(fs::path(stem).concat(".yaml"));
  return p;
}

TEST_F(TornFileTest, AKilledPgmExportNeverLeavesAYamlBesideAnotherImage) {
  HMAP_REQUIRE_DATA("balm_os0");
  // Two maps of different extent: the new grid's image and origin both differ from the old one's.
  const auto map_of = [&](int scans, const fs::path& out) {
    std::string log;
    ASSERT_EQ(test::run_hmap(map_args(scans, out), dir_ / "log", log), 0) << log;
  };
  map_of(1, dir_ / "old.hmap");
  map_of(12, dir_ / "new.hmap");
  fs::create_directories(dir_ / "o");
  fs::create_directories(dir_ / "n");
  std::string out;
  ASSERT_EQ(test::run_hmap({"export", (dir_ / "old.hmap").string(), "--pgm", (dir_ / "o" / "grid").string()}, dir_ / "log", out), 0) << out;
  const auto t0 = Clock::now();
  ASSERT_EQ(test::run_hmap({"export", (dir_ / "new.hmap").string(), "--pgm", (dir_ / "n" / "grid").string()}, dir_ / "log", out), 0) << out;
  const auto full_run = Clock::now() - t0;
  const PgmPair old_pair = read_pair(dir_ / "o" / "grid");
  const PgmPair new_pair = read_pair(dir_ / "n" / "grid");
  ASSERT_TRUE(old_pair.yaml && new_pair.yaml);
  ASSERT_NE(old_pair.pgm, new_pair.pgm);
  ASSERT_NE(*old_pair.yaml, *new_pair.yaml);

  std::mt19937 rng(20261203);
  const fs::path stem = dir_ / "grid";
  int kept_old = 0;
  int got_new = 0;
  int without_yaml = 0;
  int killed_while_saving = 0;
  for (int run = 0; run < 30; ++run) {
    fs::copy_file(dir_ / "o" / "grid.pgm", fs::path(stem).concat(".pgm"), fs::copy_options::overwrite_existing);
    fs::copy_file(dir_ / "o" / "grid.yaml", fs::path(stem).concat(".yaml"), fs::copy_options::overwrite_existing);
    test::Child child({"export", (dir_ / "new.hmap").string(), "--pgm", stem.string()});
    ASSERT_TRUE(child.started());
    // Odd runs: 0-2 ms after the image's temporary file appears (writing, renaming, or between).
    killed_while_saving +=
        kill_during(child, run, full_run, rng, 2000, [&] { return !temporaries(fs::path(stem).concat(".pgm")).empty(); }) ? 1 : 0;
    const PgmPair now = read_pair(stem);
    // Each file whole; and a YAML only beside the image it was written with.
    ASSERT_TRUE(now.pgm == old_pair.pgm || now.pgm == new_pair.pgm) << "run " << run << ": a torn image";
    if (now.yaml) {
      ASSERT_TRUE(now == old_pair || now == new_pair) << "run " << run << ": a YAML beside an image it was not written with";
      kept_old += now == old_pair ? 1 : 0;
      got_new += now == new_pair ? 1 : 0;
    } else {
      ++without_yaml;
    }
    for (const char* ext : {".pgm", ".yaml"}) {
      for (const auto& tmp : temporaries(fs::path(stem).concat(ext))) fs::remove(tmp);
    }
  }
  std::printf("[          ] 30 kills: old pair kept %d, new pair %d, image without its YAML %d; %d kills after the "
              "save began\n", kept_old, got_new, without_yaml, killed_while_saving);
  EXPECT_GT(kept_old, 0);
  EXPECT_GT(killed_while_saving, 0) << "no kill landed after the save began: the test proved little";
}

}  // namespace
}  // namespace hmap
