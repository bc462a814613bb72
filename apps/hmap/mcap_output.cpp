#include "mcap_output.hpp"

#include <algorithm>
#include <cstdio>
#include <ostream>

#include "cli_common.hpp"
#include "hmap/core/format.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/occupancy/exported_grid.hpp"
#include "hmap/ros/foxglove_scene.hpp"

namespace hmap::cli {

void check_mcap_output(const std::string& path) {
  check_output_extension(path, {".mcap"}, "--mcap writes an MCAP recording");
  check_output_file(path);
}

void check_mcap_stamps(std::span<const double> stamps_s, const std::string& source) { (void)ros::stamps_ns_of(stamps_s, source); }

void write_map_mcap(const std::string& path, const HMap& map, const OccupancyGrid* grid, std::span<const Pose> trajectory,
                    std::span<const double> stamps_s) {
  const auto t0 = Clock::now();
  const std::vector<std::uint64_t> stamps_ns = ros::stamps_ns_of(stamps_s, path);
  ros::FoxgloveSceneStats stats;
  write_file_atomic(path, [&](std::ostream& out) {
    stats = ros::write_foxglove_mcap(map, grid, trajectory, stamps_ns, [&](std::span<const std::uint8_t> b) {
      out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    });
  });
  std::string topics;
  for (const auto& [topic, n] : stats.messages) {
    topics += format("%s%s %llu", topics.empty() ? "" : ", ", topic.c_str(), static_cast<unsigned long long>(n));
  }
  const auto bytes = static_cast<double>(stats.bytes);
  std::string when = "no stamps (all at time 0)";
  if (!stamps_s.empty()) {
    const auto [first, last] = std::minmax_element(stamps_s.begin(), stamps_s.end());
    when = format("stamped %.3f to %.3f s", *first, *last);
  }
  std::printf("wrote %s (%s, %.1f s): messages %s; %llu HVoxel cubes, %llu points, %s; %s\n", path.c_str(),
              (bytes < 1e6 ? format("%.1f kB", bytes / 1e3) : format("%.1f MB", bytes / 1e6)).c_str(), ms_since(t0) / 1000.0,
              topics.c_str(), static_cast<unsigned long long>(stats.cubes), static_cast<unsigned long long>(stats.points),
              grid != nullptr ? format("the 2D grid of %zu cells", grid->known_cells()).c_str() : "no 2D grid", when.c_str());
}

void write_run_mcap(const std::string& path, const HMap& map, std::span<const GroundPatch> ground,
                    const OccupancyGrid* kept, std::span<const Pose> trajectory, std::span<const double> stamps_s) {
  if (map.stats().hvoxels == 0) {
    write_map_mcap(path, map, nullptr, trajectory, stamps_s);
    return;
  }
  const ExportedGrid chosen = export_grid(map, ground, kept);
  if (!chosen.ground_found) {
    std::printf("%s: no ground found near (%.2f, %.2f, %.2f) for a 2D grid; /map and /grid left out\n", path.c_str(),
                chosen.hint.x(), chosen.hint.y(), chosen.hint.z());
  }
  write_map_mcap(path, map, chosen.ground_found ? &chosen.grid : nullptr, trajectory, stamps_s);
}

}  // namespace hmap::cli
