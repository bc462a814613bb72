#pragma once
// HVoxel ray tracing and free-space computation (section III-C, Alg. 3, Fig. 3).

#include <algorithm>
#include <array>
#include <functional>
#include <span>
#include <vector>

#include "hmap/maps/scan_hvoxels.hpp"

namespace hmap {

/// The free HVoxels one scan leaves in one cell: disjoint intervals, each counting its rays.
struct alignas(64) FreeCell {  // one cache line: every ray visit touches exactly one
  static constexpr int kMaxIntervals = 4;
  CellKey key;
  std::uint32_t n = 0;
  std::array<FreeHVoxel, kMaxIntervals> intervals{};

  [[nodiscard]] std::span<const FreeHVoxel> hvoxels() const { return {intervals.data(), n}; }
  /// Unites [lo, hi] (carrying `rays` rays) with the intervals it overlaps or comes within
  /// `unite_gap` of. When all slots are taken and it meets none, it joins the nearest interval if
  /// closer than `join_gap`, else it is dropped: leaving space unknown is safer than calling a
  /// gap free.
  void add(float lo, float hi, float rays, float unite_gap, float join_gap) {
    // Most visits fall inside or against the one interval of a cell already crossed (what
    // add_slow does too, without its loop).
    FreeHVoxel& iv = intervals[0];
    if (n == 1 && lo <= iv.z_max + unite_gap && hi >= iv.z_min - unite_gap) {
      iv.z_min = std::min(iv.z_min, lo);
      iv.z_max = std::max(iv.z_max, hi);
      iv.rays += rays;
      return;
    }
    if (n == 0) {
      iv = {lo, hi, rays};
      n = 1;
      return;
    }
    if (lo >= iv.z_min && hi <= iv.z_max) {
      iv.rays += rays;
      return;
    }
    add_slow(lo, hi, rays, unite_gap, join_gap);
  }

 private:
  void add_slow(float lo, float hi, float rays, float unite_gap, float join_gap);
};

/// Casts one ray per HVoxel of a scan from the sensor origin and accumulates the free HVoxels.
/// The rays run as four tasks (TBB), one per quadrant around the sensor's cell, each into its
/// own accumulator; the cells two quadrants share (the sensor's row and column) are folded after.
class FreeSpaceTracer {
 public:
  explicit FreeSpaceTracer(const MapParams& params);

  /// Alg. 3: for every HVoxel with ρ >= n_th, the cells between the sensor's cell and the
  /// HVoxel's cell (ProjectLineTo2D, an exact grid traversal; the HVoxel's own cell excluded)
  /// get the free interval swept between the line models to z_max and to z_min over the cell.
  /// `alongside`, if given, runs as one more task beside the rays (the mapper merges meanwhile).
  void trace(const ScanHVoxels& scan, const std::function<void()>& alongside = {});

  /// The free cells of the last trace, each cell once.
  [[nodiscard]] const std::vector<const FreeCell*>& cells() const { return cells_; }
  [[nodiscard]] std::size_t rays() const;

 private:
  struct Accumulator {
    std::vector<std::uint32_t> slot_of_window;  // free cell index + 1 per window cell, 0: none
    std::vector<std::size_t> used_windows;
    std::vector<FreeCell> cells;                // [0, used_cells) hold this trace's free cells
    std::size_t used_cells = 0;                 // (kept allocated across scans: no re-construction)
    std::vector<std::uint32_t> targets;         // scan cells whose rays this side casts
    std::vector<Eigen::Vector2f> ray_dz;        // (z_min, z_max) − z_s of the current target
    std::size_t rays = 0;
    void reset();
    void trace(const ScanHVoxels& scan, const MapParams& params);
    FreeCell& cell_at(std::size_t window_index, const CellKey& key) {
      const std::uint32_t slot = slot_of_window[window_index];
      return slot != 0 ? cells[slot - 1] : new_cell(window_index, key);
    }
    [[nodiscard]] std::span<FreeCell> used() { return {cells.data(), used_cells}; }
    [[nodiscard]] std::span<const FreeCell> used() const { return {cells.data(), used_cells};
    }
    FreeCell& new_cell(std::size_t window_index, const CellKey& key);
  };

  MapParams params_;
  std::array<Accumulator, 4> quadrants_;
  std::vector<const FreeCell*> cells_;
};

}  // namespace hmap
