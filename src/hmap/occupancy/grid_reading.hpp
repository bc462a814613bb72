#pragma once
// How a 2D occupancy grid is read as a map a planner uses: which cells `hmap export --pgm` writes
// occupied, free or undecided, `hmap render --layer occupancy` draws so, and `hmap compare` scores.

#include <algorithm>
#include <cstdint>

#include "hmap/core/params.hpp"

namespace hmap {

enum class CellClass : std::uint8_t { kUndecided, kFree, kOccupied };

struct GridReading {
  double occupied_above = 0.65;  ///< [-] p above it: occupied (map_server's occupied_thresh)
  double free_at_most = 0.196;   ///< [-] p at or below it: free (map_server's free_thresh)

  /// The reading of a grid kept by eq. (3)-(4): free from p <= K_g on, as much evidence as one clear
  /// pass over the ground with nothing against it, so one scan leaves free cells (map_server's
  /// 0.196 needs two scans of passes, four of ground hits at p = 0.4); never stricter than 0.196.
  [[nodiscard]] static GridReading for_map(const OccupancyParams& p) { return {0.65, std::max(0.196, p.ground_gain)}; }

  /// The class of a cell of probability p. 1e-6 of slack: a cell after one pass holds the float
  /// log-odds of K_g, which reads back a few 1e-8 off.
  [[nodiscard]] CellClass classify(double p) const {
    if (p > occupied_above) return CellClass::kOccupied;
    return p <= free_at_most + 1e-6 ? CellClass::kFree : CellClass::kUndecided;
  }
};

}  // namespace hmap
