#pragma once
// What the subcommands share: parameter options, scan sources, progress, number formatting.

#include <CLI/CLI.hpp>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap::cli {

/// Options that set parameters, applied in this order: preset, config file, --set, named flags.
struct ParamOptions {
  std::string preset = "outdoor";
  std::string config;
  std::vector<std::string> overrides;
  std::optional<double> cell;
  std::optional<double> min_range;
  std::optional<double> max_range;

  void add_to(CLI::App& app);
  [[nodiscard]] Params resolve() const;
};

/// The scans of a run and their poses: a KITTI folder or a list of files.
struct ScanSource {
  std::vector<std::filesystem::path> scans;
  std::optional<PoseList> T_map_scan;
  std::string poses_name;  ///< the file the poses came from, for messages

  /// `kitti_dir` or `files` (one of them), optional `poses_file` overriding the folder's, at most
  /// `max_scans` scans (0 = all). Throws InputError for a pose count that does not match.
  static ScanSource open(const std::string& kitti_dir, const std::vector<std::string>& files,
                         const std::string& poses_file, std::size_t max_scans, bool poses_required);
  [[nodiscard]] PointCloud read(std::size_t index, CloudReadStats& stats) const;
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

[[nodiscard]] std::string human_bytes(double bytes);
[[nodiscard]] std::string human_count(double n);

using Clock = std::chrono::steady_clock;
[[nodiscard]] inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

void add_map_command(CLI::App& app);
void add_info_command(CLI::App& app);
void add_export_command(CLI::App& app);
void add_bench_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_simulate_command(CLI::App& app);
void add_demo_command(CLI::App& app);

}  // namespace hmap::cli
