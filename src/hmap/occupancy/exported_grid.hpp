#pragma once
// The 2D grid a saved map is exported with (export --pgm/--costmap/--geotiff/--mcap, map/slam
// --mcap): which of the map's grids, or one derived from its columns when it holds none.

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// Which grid: "both" (default), "kept" or "judged"; a map without a kept grid is always derived.
enum class GridSource { kBoth, kKept, kJudged };

/// "both" | "kept" | "judged" -> GridSource; nullopt for anything else.
[[nodiscard]] std::optional<GridSource> parse_grid_source(std::string_view name);

struct ExportGridParams {
  GridSource source = GridSource::kBoth;
  /// Derive the grid from the columns even when the map keeps one (export --rederive).
  bool rederive = false;
  /// Where the ground search of a derived grid starts; nullopt: the middle of the map, 0.5 m above
  /// the low fifth of the columns' lowest tops.
  std::optional<Eigen::Vector3d> ground_hint;
  /// RRT iterations of a derived grid's ground search; 0: grown with the map's area,
  /// 2·area / d_n², between ground.iterations and 4000.
  int ground_iterations = 0;
};

struct ExportedGrid {
  OccupancyGrid grid;
  std::vector<GroundPatch> ground;  ///< the patches the grid was judged on
  std::string what;                 ///< a sentence saying which grid this is
  bool derived = false;             ///< derived from the columns (no kept grid, or rederive)
  bool ground_found = true;         ///< false: a derived grid found no ground near `hint`; `grid` is empty
  Eigen::Vector3d hint = Eigen::Vector3d::Zero();  ///< a derived grid's ground search start
  int iterations = 0;                              ///< a derived grid's RRT iterations
};

/// The grid to export. `kept` (may be null or empty) is the grid kept scan by scan and `ground`
/// the patches kept with it. kBoth: each cell the more occupied of the kept grid and the columns of
/// the final map judged by eq. (4) on the same patches (the kept grid alone misses what few rays
/// hit, the judged one what later scans carved: docs/COMPARE.md). Without a kept grid (or with
/// `rederive`) the ground is found by Alg. 4 from the hint and each column judged on it; cells
/// without a patch within 2·d_n are unknown. Throws hmap::Error for an empty map or parameters out
/// of range.
[[nodiscard]] ExportedGrid export_grid(const HMap& map, std::span<const GroundPatch> ground, const OccupancyGrid* kept,
                                       const ExportGridParams& params = {});

}  // namespace hmap
