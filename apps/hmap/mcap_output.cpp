#include "mcap_output.hpp"

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

void write_map_mcap(const std::string& path, const HMap& map, const OccupancyGrid* grid, std::span<const Pose> trajectory) {
  const auto t0 = Clock::now();
  ros::FoxgloveSceneStats stats;
  write_file_atomic(path, [&](std::ostream& out) {
    stats = ros::write_foxglove_mcap(map, grid, trajectory, [&](std::span<const std::uint8_t> b) {
      out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    });
  });
  std::string topics;
  for (const auto& [topic, n] : stats.messages) {
    topics += format("%s%s %llu", topics.empty() ? "" : ", ", topic.c_str(), static_cast<unsigned long long>(n));
  }
  const auto bytes = static_cast<double>(stats.bytes);
  std::printf("wrote %s (%s, %.1f s): messages %s; %llu HVoxel cubes, %llu points, %s\n", path.c_str(),
              (bytes < 1e6 ? format("%.1f kB", bytes / 1e3) : format("%.1f MB", bytes / 1e6)).c_str(), ms_since(t0) / 1000.0,
              topics.c_str(), static_cast<unsigned long long>(stats.cubes), static_cast<unsigned long long>(stats.points),
              grid != nullptr ? format("the 2D grid of %zu cells", grid->known_cells()).c_str() : "no 2D grid");
}

void write_run_mcap(const std::string& path, const HMap& map, std::span<const GroundPatch> ground,
                    const OccupancyGrid* kept, std::span<const Pose> trajectory) {
  if (map.stats().hvoxels == 0) {
    write_map_mcap(path, map, nullptr, trajectory);
    return;
  }
  const ExportedGrid chosen = export_grid(map, ground, kept);
  if (!chosen.ground_found) {
    std::printf("%s: no ground found near (%.2f, %.2f, %.2f) for a 2D grid; /map and /grid left out\n", path.c_str(),
                chosen.hint.x(), chosen.hint.y(), chosen.hint.z());
  }
  write_map_mcap(path, map, chosen.ground_found ? &chosen.grid : nullptr, trajectory);
}

}  // namespace hmap::cli
