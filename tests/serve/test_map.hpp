#pragma once
// A small room saved as a .hmap for the tests of `hmap view`: a 6 m × 4 m floor at cell 0.25 m,
// walls 2.4 m high on its border, a table (top at 0.75 m over the floor) and a ground patch tree
// and 2D grid beside it, so every layer of the page has something to show.

#include <filesystem>

#include "hmap/io/hmap_file.hpp"

namespace hmap::test {

inline constexpr double kRoomCell = 0.25;
inline constexpr int kRoomCellsX = 24;
inline constexpr int kRoomCellsY = 16;

/// The room; `nx` × `ny` cells (larger ones for measurements).
inline HMap room_map(int nx = kRoomCellsX, int ny = kRoomCellsY) {
  Params p;
  p.map.cell_size = kRoomCell;
  HMap map(p);
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      auto c = map.column_for_update({i, j});
      const bool wall = i == 0 || j == 0 || i == nx - 1 || j == ny - 1;
      if (wall) {
        c.push_back({0.0F, 2.4F, 200.0F, 1.0F});
        continue;
      }
      c.push_back({0.0F, 0.05F, 20.0F, 0.95F});
      if (i >= 8 && i < 14 && j >= 5 && j < 9) c.push_back({0.7F, 0.75F, 12.0F, 0.9F});  // the table top
    }
  }
  return map;
}

inline void save_room(const std::filesystem::path& path, int nx = kRoomCellsX, int ny = kRoomCellsY) {
  HMap map = room_map(nx, ny);
  if (nx != kRoomCellsX || ny != kRoomCellsY) {
    // Bigger rooms get shelves: a second and third HVoxel in every fifth cell.
    for (int i = 1; i + 1 < nx; i += 5) {
      for (int j = 1; j + 1 < ny; ++j) {
        auto c = map.column_for_update({i, j});
        if (c.size() == 1) {
          c.push_back({1.0F, 1.05F, 8.0F, 0.8F});
          c.push_back({1.8F, 1.85F, 8.0F, 0.8F});
        }
      }
    }
    save_hmap(path, map);
    return;
  }
  std::vector<GroundPatch> ground{{Eigen::Vector3d(3.0, 2.0, 0.05), Eigen::Vector3d::UnitZ(), 1.0, -1},
                                  {Eigen::Vector3d(1.5, 2.0, 0.05), Eigen::Vector3d::UnitZ(), 1.0, 0}};
  OccupancyGrid grid(kRoomCell, 0.12, 0.97);
  for (int i = 0; i < kRoomCellsX; ++i) {
    for (int j = 0; j < kRoomCellsY; ++j) {
      const bool wall = i == 0 || j == 0 || i == kRoomCellsX - 1 || j == kRoomCellsY - 1;
      grid.set({i, j}, wall ? log_odds(0.97) : log_odds(0.12));
    }
  }
  save_hmap(path, map, ground, &grid);
}

}  // namespace hmap::test
