#pragma once
// 2D occupancy grids against the true traversability of a robot: which cells of a true surface
// block a robot of given height, and how many of them a grid gets right, read as map_server reads
// a PGM (occupied from p = 0.65, free up to 0.196, undecided between). Pure: points and grids in,
// numbers out.

#include <cstddef>
#include <functional>
#include <unordered_map>

#include "hmap/core/types.hpp"
#include "hmap/occupancy/grid_reading.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// The truth of one cell.
struct TrueCell {
  bool blocked = false;   ///< a surface rises more than the step and at most the robot's height
  bool overhang = false;  ///< not blocked, under a surface higher than the robot (and below the cut)
};

using TrueTraversability = std::unordered_map<CellKey, TrueCell, CellKeyHash>;

/// Settings of the true traversability.
struct TraversabilityTruthParams {
  double cell_size = 0.25;     ///< [m] the grids' cell
  double step = 0.2;           ///< [m] higher above the local ground blocks
  double robot_height = 2.0;   ///< [m] higher above the local ground passes over the robot
  double overhang_cut = 1e9;   ///< [m] absolute height: surfaces above it are no overhang (a ceiling
                               ///< neither map is asked about)
  int ground_window = 2;       ///< [cells] the local ground is the lowest point of the (2w+1)² cells
                               ///< around, so a box top is not taken for ground
};

/// Per cell holding a truth point: blocked / overhang as defined above. The local ground of a cell
/// is the lowest point of `ground` (the walkable surfaces: floors, roads, ramps) in the window
/// around it; where `ground` has none there, the lowest point of `truth`. Without the ground apart,
/// any surface below the walkable one (a kerb's buried face, a retaining wall's foot) would lift
/// everything around it into an obstacle.
[[nodiscard]] TrueTraversability true_traversability(const PointCloud& truth, const PointCloud& ground,
                                                     const TraversabilityTruthParams& p);

/// Agreement of a 2D grid with the truth over the cells both know and the grid decided.
struct GridScores {
  std::size_t compared = 0;
  std::size_t correct = 0;
  std::size_t blocked = 0, blocked_found = 0;
  std::size_t free = 0, free_found = 0;
  std::size_t overhang = 0, overhang_free = 0;
  [[nodiscard]] static double ratio(std::size_t a, std::size_t b) {
    return b ? static_cast<double>(a) / static_cast<double>(b) : 0.0;
  }
  [[nodiscard]] double accuracy() const { return ratio(correct, compared); }
  [[nodiscard]] double blocked_recall() const { return ratio(blocked_found, blocked); }
  [[nodiscard]] double free_recall() const { return ratio(free_found, free); }
  [[nodiscard]] double overhang_accuracy() const { return ratio(overhang_free, overhang); }
};

/// map_server's thresholds on p.
inline constexpr double kPgmOccupied = 0.65;
inline constexpr double kPgmFree = 0.196;

/// Scores `grid` on the truth cells for which `in_scope(key)` holds (an empty function: all),
/// decided as `reading` reads them (default: map_server's thresholds; at p = 0.65 exactly: occupied).
[[nodiscard]] GridScores score_grid(const OccupancyGrid& grid, const TrueTraversability& truth,
                                    const std::function<bool(const CellKey&)>& in_scope = {},
                                    const GridReading& reading = {kPgmOccupied - 1e-12, kPgmFree});

}  // namespace hmap
