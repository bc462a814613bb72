#pragma once
// Traversability for planners, beside the occupancy grid: per cell the height, slope and step of
// the local ground patch, and a cost in [0, 100] from occupancy, step and slope (Nav2's costmap
// scale: 0 free, 100 lethal), optionally inflated around lethal cells.

#include <cstdint>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/occupancy/grid_reading.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// Thresholds of the cost (documented in docs/HMAP.md, "Traversability").
struct TraversabilityParams {
  double max_step = 0.2;            ///< [m] a ground step this high or higher is lethal (cost 100)
  double max_slope_deg = 20.0;      ///< [deg] ground this steep or steeper is lethal
  /// How the grid's p is read: occupied (lethal) above `occupied_above`, free (no cost from the
  /// grid) at or below `free_at_most`, the cost scaling with p between. Give the reading the grid
  /// is exported with (`GridReading::for_map`), so the costmap agrees with the PGM cell by cell.
  GridReading reading;
  double ground_reach = 3.0;        ///< [m] cells farther from every ground patch have no ground
  double inflation_radius = 0.0;    ///< [m] lethal cells raise the cost of cells this near; 0 = none
  double cost_scaling = 3.0;        ///< [1/m] inflated cost 99·exp(−cost_scaling·d) at distance d
};

/// Throws hmap::Error naming the field for a value out of range.
void validate(const TraversabilityParams& p);

/// The layers over the bounding box of the grid's known cells; cell (col, row) is the key
/// (i_min + col, j_min + row), row 0 the southernmost. NaN where there is no ground patch.
struct TraversabilityLayers {
  std::int32_t i_min = 0, j_min = 0;
  std::int32_t width = 0, height = 0;
  double cell_size = 0.0;
  std::vector<float> ground_z;   ///< [m] the local patch's plane at the cell centre
  std::vector<float> slope_deg;  ///< [deg] of that patch's normal from vertical
  std::vector<float> step;       ///< [m] largest ground height difference to the 8 neighbours
  /// 0 free .. 100 lethal; kUnknown where neither the grid nor the ground says anything.
  std::vector<std::uint8_t> cost;
  static constexpr std::uint8_t kUnknown = 255;
  [[nodiscard]] std::size_t index(std::int32_t col, std::int32_t row) const {
    return static_cast<std::size_t>(row) * static_cast<std::size_t>(width) + static_cast<std::size_t>(col);
  }
};

/// Builds the layers. Cost per known cell: 100 when the grid says occupied or the step or slope
/// reaches its limit; else 99·max(step / max_step, slope / max_slope, grid term) rounded, the grid
/// term (p − free_at_most) / (occupied_above − free_at_most) for a cell the reading leaves
/// undecided and 0 for a free one;
/// then the inflation. `max_cells` bounds the box (throws hmap::Error naming the size beyond it).
[[nodiscard]] TraversabilityLayers traversability(const OccupancyGrid& grid, const GroundModel& ground,
                                                  const TraversabilityParams& p, std::size_t max_cells = 400'000'000);

}  // namespace hmap
