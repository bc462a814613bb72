#include "cli_common.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>

#include "hmap/core/error.hpp"
#include "hmap/io/cloud_reader.hpp"
#include "hmap/io/config.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/poses.hpp"

namespace hmap::cli {

void ParamOptions::add_to(CLI::App& app) {
  app.add_option("--preset", preset, "Parameter preset of the paper's section V")
      ->check(CLI::IsMember({"indoor", "outdoor"}))
      ->capture_default_str();
  app.add_option("--config", config, "YAML parameter file applied on top of the preset");
  app.add_option("--set", overrides, "Override one parameter, NAME=VALUE (repeatable; see hmap params)");
  app.add_option("--cell", cell, "Grid cell size [m] (map.cell_size)");
  app.add_option("--min-range", min_range, "Drop points closer than this to the sensor [m]");
  app.add_option("--max-range", max_range, "Drop points farther than this from the sensor [m]");
}

Params ParamOptions::resolve() const {
  Params p = hmap::preset(preset);
  if (!config.empty()) apply_config_file(config, p);
  for (const auto& o : overrides) apply_override(o, p);
  if (cell) p.map.cell_size = *cell;
  if (min_range) p.map.min_range = *min_range;
  if (max_range) p.map.max_range = *max_range;
  validate(p);
  return p;
}

ScanSource ScanSource::open(const std::string& kitti_dir, const std::vector<std::string>& files,
                            const std::string& poses_file, std::size_t max_scans, bool poses_required) {
  ScanSource src;
  if (!kitti_dir.empty() && !files.empty()) throw Error("give either --kitti DIR or scan files, not both");
  if (kitti_dir.empty() && files.empty()) throw Error("no scans: give --kitti DIR or scan files");
  if (!kitti_dir.empty()) {
    KittiSequenceOptions options;
    if (max_scans > 0) options.max_scans = max_scans;
    KittiSequence seq = open_kitti_sequence(kitti_dir, options);
    src.scans = seq.scan_paths;
    if (seq.T_map_scan) {
      src.T_map_scan = std::move(seq.T_map_scan);
      src.poses_name = (std::filesystem::path(kitti_dir) / "poses.txt").string();
    }
  } else {
    for (const auto& f : files) src.scans.emplace_back(f);
  }
  if (max_scans > 0 && src.scans.size() > max_scans) src.scans.resize(max_scans);
  if (!poses_file.empty()) {
    src.T_map_scan = read_poses(poses_file);
    src.poses_name = poses_file;
  }
  if (src.T_map_scan) {
    auto& poses = *src.T_map_scan;
    const bool truncated = max_scans > 0 && poses.size() > src.scans.size() && src.scans.size() == max_scans;
    if (poses.size() != src.scans.size() && !truncated) {
      throw InputError(src.poses_name, "", "holds " + std::to_string(poses.size()) + " poses for " +
                                               std::to_string(src.scans.size()) + " scans");
    }
    poses.resize(src.scans.size());
  } else if (poses_required) {
    throw Error("no poses: give --poses FILE (KITTI or TUM format) or a KITTI folder with poses.txt; "
                "to estimate poses from the scans, use `hmap slam`");
  }
  return src;
}

PointCloud ScanSource::read(std::size_t index, CloudReadStats& stats) const {
  CloudReadStats s;
  PointCloud cloud = read_cloud(scans.at(index), &s);
  stats += s;
  return cloud;
}

Progress::Progress(std::string what, std::size_t total)
    : what_(std::move(what)), total_(total), active_(::isatty(STDERR_FILENO) == 1), last_() {}

void Progress::update(std::size_t done, double ms_per_item) {
  if (!active_) return;
  const auto now = Clock::now();
  if (done < total_ && now - last_ < std::chrono::milliseconds(100)) return;
  last_ = now;
  constexpr int kWidth = 30;
  const double frac = total_ > 0 ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
  const int filled = static_cast<int>(std::lround(frac * kWidth));
  std::fprintf(stderr, "\r%s [%s%s] %zu/%zu  %.1f ms each", what_.c_str(),
               std::string(static_cast<std::size_t>(filled), '#').c_str(),
               std::string(static_cast<std::size_t>(kWidth - filled), ' ').c_str(), done, total_, ms_per_item);
  std::fflush(stderr);
}

void Progress::finish() {
  if (!active_) return;
  std::fprintf(stderr, "\r\033[K");
  std::fflush(stderr);
}

std::string human_bytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 4) {
    bytes /= 1024.0;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", bytes, units[u]);
  return buf;
}

std::string human_count(double n) {
  char buf[32];
  if (n >= 1e6) {
    std::snprintf(buf, sizeof buf, "%.2f M", n / 1e6);
  } else if (n >= 1e4) {
    std::snprintf(buf, sizeof buf, "%.1f k", n / 1e3);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f", n);
  }
  return buf;
}

}  // namespace hmap::cli
