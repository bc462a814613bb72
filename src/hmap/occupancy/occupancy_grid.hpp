#pragma once
// The 2D occupancy grid kept alongside the HMAP (section IV-B): log-odds per cell with clamping,
// in the same unbounded tiles as the HMAP.

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/core/types.hpp"
#include "hmap/maps/tile_index.hpp"

namespace hmap {

/// log(p / (1 − p)).
[[nodiscard]] inline float log_odds(double p) { return static_cast<float>(std::log(p / (1.0 - p))); }
/// The inverse of log_odds.
[[nodiscard]] inline double probability(float l) { return 1.0 / (1.0 + std::exp(-static_cast<double>(l))); }

class OccupancyGrid {
 public:
  static constexpr int kTileBits = 3;
  static constexpr int kTileSize = 1 << kTileBits;
  static constexpr int kTileCells = kTileSize * kTileSize;
  /// A cell never observed holds NaN: unknown, as distinct from p = 0.5 after equal evidence.
  struct Tile {
    std::array<float, kTileCells> log_odds;
    Tile() { log_odds.fill(std::numeric_limits<float>::quiet_NaN()); }
  };

  /// cell_size [m]; clamping bounds as probabilities (OccupancyParams::clamp_min / clamp_max).
  OccupancyGrid(double cell_size, double clamp_min, double clamp_max);

  [[nodiscard]] double cell_size() const { return cell_size_; }
  /// eq. (3) with a prior of 0.5: l ← clamp(l + log_odds(p(c|z))); an unknown cell starts at 0.
  void update(const CellKey& key, float measurement_log_odds);
  /// Sets a cell's log-odds (clamped), as when a saved grid is read back. `l` must be finite.
  void set(const CellKey& key, float l);
  /// Log-odds of a cell, or nullopt if it was never observed.
  [[nodiscard]] std::optional<float> log_odds_at(const CellKey& key) const;
  /// Occupancy probability of a cell, or nullopt if it was never observed.
  [[nodiscard]] std::optional<double> probability_at(const CellKey& key) const;
  /// Cells observed at least once.
  [[nodiscard]] std::size_t known_cells() const;
  /// Calls f(CellKey, float log_odds) for every observed cell.
  template <typename F>
  void for_each_cell(F&& f) const {
    tiles_.for_each([&](const CellKey& t, const Tile& tile) {
      for (int k = 0; k < kTileCells; ++k) {
        if (!std::isnan(tile.log_odds[k])) f(CellKey{t.i * kTileSize + (k >> kTileBits), t.j * kTileSize + (k & (kTileSize - 1))}, tile.log_odds[k]);
      }
    });
  }
  /// Calls f(CellKey tile_key, const Tile&) for every allocated tile (tile (a, b) holds cells
  /// [8a, 8a + 8) × [8b, 8b + 8); cell (i, j) is at log_odds[8 · (i mod 8) + (j mod 8)]).
  template <typename F>
  void for_each_tile(F&& f) const {
    tiles_.for_each(f);
  }
  /// Bytes held by the tiles.
  [[nodiscard]] std::size_t memory_bytes() const { return tiles_.size() * sizeof(Tile); }
  [[nodiscard]] float clamp_min_log_odds() const { return l_min_; }
  [[nodiscard]] float clamp_max_log_odds() const { return l_max_; }

 private:
  [[nodiscard]] static CellKey tile_of(const CellKey& k) { return {k.i >> kTileBits, k.j >> kTileBits}; }
  [[nodiscard]] static int local_index(const CellKey& k) {
    return ((k.i & (kTileSize - 1)) << kTileBits) | (k.j & (kTileSize - 1));
  }

  double cell_size_;
  float l_min_;
  float l_max_;
  TileIndex<Tile> tiles_;
};

/// The cell-wise more occupied of two grids of the same cell size (a cell known to one only keeps
/// that one's value), with `a`'s clamping bounds: for a planner, an obstacle either grid holds is
/// an obstacle. Throws hmap::Error when the cell sizes differ.
[[nodiscard]] OccupancyGrid more_occupied(const OccupancyGrid& a, const OccupancyGrid& b);

/// The grid as a dense raster over the bounding box of its observed cells: cell (col, row) is the
/// key (i_min + col, j_min + row), so x grows with col and y with row (row 0 the southernmost);
/// the raster's lower-left corner is (i_min, j_min) · cell_size in the map frame.
struct GridRaster {
  std::int32_t i_min = 0, j_min = 0;
  std::int32_t width = 0, height = 0;  ///< [cells]; 0 × 0 for a grid without an observed cell
  double cell_size = 0.0;              ///< [m]
  std::vector<float> probability;      ///< row-major (row · width + col); NaN where never observed
};

/// The raster of `grid`. Throws hmap::Error when the box holds more than `max_cells` cells (a few
/// cells kilometres apart must not ask for gigabytes).
[[nodiscard]] GridRaster raster(const OccupancyGrid& grid, std::size_t max_cells = 400'000'000);

}  // namespace hmap
