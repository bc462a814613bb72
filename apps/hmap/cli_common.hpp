#pragma once
// What the subcommands share: parameter options, scan sources, progress, number formatting.

#include <CLI/CLI.hpp>

#include <chrono>
#include <filesystem>
#include <memory>
#include <new>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <initializer_list>
#include <vector>

#include "hmap/core/budget.hpp"
#include "hmap/core/error.hpp"
#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"
#include "hmap/io/config.hpp"
#include "hmap/io/cloud_stats.hpp"
#include "hmap/io/scan_source.hpp"

namespace hmap::cli {

/// Options that set parameters, applied in this order: preset, config file, --set, named flags.
struct ParamOptions {
  /// Empty: not named. `hmap map` and `hmap slam` then choose it from the first scan's reach
  /// (preset_for_sensor); other commands take "outdoor".
  std::string preset;
  std::string config;
  std::vector<std::string> overrides;
  std::optional<double> cell;
  std::optional<double> min_range;
  std::optional<double> max_range;

  void add_to(CLI::App& app);
  /// Where the parameters come from; the preset empty when none was named.
  [[nodiscard]] ParamSources sources() const;
  /// The parameters, from `fallback` where no preset was named.
  [[nodiscard]] Params resolve(const std::string& fallback = "outdoor") const;
};

/// What the first scan chose (resolve_params_for_scan), as sentences for a command's summary:
/// " preset indoor (...). map.point_distance_threshold = 0.6 (...)."; empty when it chose nothing.
[[nodiscard]] std::string chosen_summary(const ScanParams& chosen);

/// The sensor inputs beyond scan files, shared by every command that reads scans: RGB-D folders
/// (7-Scenes, TUM), ROS bags, and the rotation that makes the data's world frame gravity-aligned.
/// A command adopts them through InputOptions; they become the fields of a ScanSourceSpec
/// (hmap/io/scan_source.hpp), opened by the library's open_scan_source.
struct ScanSourceOptions {
  std::string rgbd;                   ///< 7-Scenes or TUM RGB-D folder (layout told by its files)
  std::string tum;                    ///< TUM RGB-D folder (must hold depth.txt)
  std::string intrinsics;             ///< fx fy cx cy or a 3x3 matrix, overriding the folder's
  std::optional<double> depth_scale;  ///< [m per depth unit]
  std::string up;                     ///< up axis of the world frame (x, -y, ...) or "floor"
  std::vector<std::string> rotation;  ///< T_map_world rotation, 9 numbers row-major
  std::string bag;                    ///< ROS 1 bag
  std::string cloud_topic;            ///< sensor_msgs/PointCloud2 topic of the bag
  std::string pose_topic;             ///< nav_msgs/Odometry (or PoseStamped) topic of the bag
  std::vector<std::string> tf_frames; ///< MAP [SENSOR] frames of /tf

  void add_to(CLI::App& app);
};

/// Help texts of the input options, one definition for every command (tested against `--help`).
inline constexpr const char* kKittiHelp =
    "KITTI-layout folder: velodyne/*.bin, with poses.txt, calib.txt and times.txt when present";
inline constexpr const char* kScanFilesHelp =
    "Scan files, in order: .pcd .ply .bin (KITTI) .xyz .txt .csv .pts .vtk (legacy POLYDATA / UNSTRUCTURED_GRID)";
inline constexpr const char* kKnownPosesHelp = "Poses T_map_scan, KITTI or TUM format, one per scan";
inline constexpr const char* kScanCountHelp = "Use only the first N scans (0, the default: all of them)";

/// One scan as read from its source, with what reading it counted and, when asked, its points' times.
struct ReadScan {
  PointCloud cloud;
  CloudReadStats stats;
  std::vector<float> times_s;
};

/// The scans every scan-reading command takes, one definition of the options and their help:
/// --kitti DIR or scan files, --poses FILE, --scans N, and the sensor inputs (RGB-D folders, bags,
/// --up / --rotation). A command adopts them by deriving its options struct from InputOptions and
/// calling add_input_options(); run() opens them with open_inputs().
struct InputOptions {
  std::string kitti;
  std::vector<std::string> files;
  std::string poses;
  std::size_t scans = 0;  ///< 0: all
  ScanSourceOptions sensors;

  /// `poses_help`: what --poses means to this command; empty for a command without --poses.
  void add_input_options(CLI::App& app, const std::string& poses_help);
  /// The library's spec of these inputs, reads checked against memory_budget(), warnings printed.
  [[nodiscard]] ScanSourceSpec spec(bool poses_required) const;
  /// open_scan_source(spec(poses_required)).
  [[nodiscard]] ScanSource open_inputs(bool poses_required) const;
};

/// A one-line progress bar on stderr when it is a terminal; silent otherwise.
class Progress {
 public:
  Progress(std::string what, std::size_t total);
  void update(std::size_t done, double ms_per_item);
  void finish();

 private:
  std::string what_;
  std::size_t total_;
  bool active_;
  std::chrono::steady_clock::time_point last_;
};

/// CLI11 check of a count option (--scans, --frames, --seed): "-1" is refused by name instead of
/// wrapping to 2^64 - 1 in a std::size_t.
inline const CLI::Validator kCount(
    [](std::string& value) -> std::string {
      if (!value.empty() && value.find_first_not_of("0123456789") == std::string::npos) return "";
      return "must be a count (0, 1, 2, ...), got '" + value + "'";
    },
    "COUNT");

/// The memory budget of this run (`hmap --max-memory MIB`, default MemoryBudget::kDefaultBytes).
[[nodiscard]] MemoryBudget& memory_budget();

/// Runs `step` (integrating scan `k` of `src`) and gives any hmap::Error or std::bad_alloc it
/// throws the scan's name and where its pose came from: "scan pose is too far from the map origin"
/// and "out of memory" alone do not say which of 3000 scans did it.
template <typename Step>
decltype(auto) for_scan(const ScanSource& src, std::size_t k, Step&& step) {
  const auto where = [&] {
    return "scan " + std::to_string(k) + " (" + src.scans.at(k).string() + ")" +
           (src.poses_name.empty() ? std::string() : ", pose from " + src.poses_name);
  };
  try {
    return step();
  } catch (const InputError&) {
    throw;  // already names its file
  } catch (const Error& e) {
    throw Error(where() + ": " + e.what());
  } catch (const std::bad_alloc&) {
    throw Error(where() + ": out of memory (the memory budget is hmap --max-memory MIB)");
  }
}

/// Before the work of a command that writes a folder as one set (write_folder_atomic): creates
/// the parents of `dir` and checks that `dir` can be replaced by what `command` writes (`owned`,
/// as check_output_set_folder); hmap::Error naming it otherwise (not the standard library's message).
void prepare_output_set(const std::filesystem::path& dir, std::initializer_list<std::string_view> owned, std::string_view command);

/// Refuses an output path whose extension (any letter case) is not one of `extensions`: `hmap map
/// --out a.ply` wrote .hmap bytes into a.ply, and a viewer then failed on it. `what` names the
/// what is written, e.g. "hmap map writes a .hmap map". hmap::Error otherwise, before any work.
void check_output_extension(const std::string& path, std::initializer_list<std::string_view> extensions,
                            const std::string& what);

[[nodiscard]] std::string human_bytes(double bytes);
[[nodiscard]] std::string human_count(double n);

using Clock = std::chrono::steady_clock;
[[nodiscard]] inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// The whole command line of `hmap`: the global options and every command (apps/hmap/app.cpp).
/// main() parses with it; the fuzz target cli_flags parses with it, its commands not run.
void configure_app(CLI::App& app);

void add_map_command(CLI::App& app);
void add_merge_command(CLI::App& app);
void add_info_command(CLI::App& app);
void add_export_command(CLI::App& app);
void add_bench_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_simulate_command(CLI::App& app);
void add_demo_command(CLI::App& app);
void add_compare_command(CLI::App& app);
void add_bag_info_command(CLI::App& app);  // only with HMAP_HAVE_ROS
void add_slam_command(CLI::App& app);  // apps/hmap/cmd_slam.cpp, when HMAP_HAVE_SLAM
void add_pvox_command(CLI::App& app);        // apps/hmap/cmd_pvox.cpp, when HMAP_HAVE_PVOX
void add_experiment_command(CLI::App& app);  // apps/hmap/cmd_experiment.cpp, when HMAP_HAVE_PVOX
void add_view_command(CLI::App& app);        // apps/hmap/cmd_view.cpp, when HMAP_HAVE_VIEW

}  // namespace hmap::cli
