#pragma once
// HVoxel ray tracing and free-space computation (section III-C, Alg. 3, Fig. 3).

#include <algorithm>
#include <array>
#include <bit>
#include <limits>
#include <functional>
#include <span>
#include <vector>

#include "hmap/maps/scan_hvoxels.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace hmap {

/// The free HVoxels one scan leaves in one cell: disjoint intervals, each counting its rays.
/// Held lane by lane (structure of arrays), so that one ray's band is tested against all four
/// intervals at once: lanes [n, 4) are empty (z_min = +inf, z_max = −inf, no rays) and never
/// overlap anything, and the usual visits (the band meets exactly one interval, or none while a
/// lane is free) update their lane without a branch on how many intervals the cell holds. The
/// branch on that count mispredicted often (on the HDL-64 scans 28 % of the visits are to cells
/// with two to four intervals): the tracer took 15–20 % longer, with the same result.
struct alignas(64) FreeCell {  // one cache line: every ray visit touches exactly one
  static constexpr int kMaxIntervals = 4;
  CellKey key;
  std::uint32_t n = 0;  ///< intervals held, in lanes [0, n)
  alignas(16) std::array<float, kMaxIntervals> z_min = empty_lanes(1.0F);   ///< [m]
  alignas(16) std::array<float, kMaxIntervals> z_max = empty_lanes(-1.0F);  ///< [m]
  alignas(16) std::array<float, kMaxIntervals> rays{};  ///< |v_f| of each interval

  /// No intervals.
  void clear() {
    n = 0;
    z_min = empty_lanes(1.0F);
    z_max = empty_lanes(-1.0F);
    rays = {};
  }
  [[nodiscard]] FreeHVoxel hvoxel(std::uint32_t k) const { return {z_min[k], z_max[k], rays[k]}; }
  /// The intervals as FreeHVoxels, written into `out`.
  [[nodiscard]] std::span<const FreeHVoxel> hvoxels(std::array<FreeHVoxel, kMaxIntervals>& out) const {
    for (std::uint32_t k = 0; k < n; ++k) out[k] = hvoxel(k);
    return {out.data(), n};
  }

  /// Unites [lo, hi] (carrying `rays` rays) with the intervals it overlaps or comes within
  /// `unite_gap` of. When all slots are taken and it meets none, it joins the nearest interval if
  /// closer than `join_gap`, else it is dropped: leaving space unknown is safer than calling a
  /// gap free. `lo` and `hi` are finite.
  void add(float lo, float hi, float r, float unite_gap, float join_gap) {
    // Meeting one interval widens it; meeting none while a lane is free starts an interval in
    // lane n (an empty lane united with [lo, hi] is [lo, hi]). Both without a branch; the rest
    // (a band that bridges intervals, a full cell) takes add_slow.
    const unsigned hits = hit_mask(lo, hi, unite_gap);
    const unsigned lane_bit = hits != 0 ? hits : 1U << n;
    if ((hits & (hits - 1)) == 0 && lane_bit < (1U << kMaxIntervals)) {
      unite_lane(lane_bit, lo, hi, r);
      n += hits == 0 ? 1 : 0;
      return;
    }
    add_slow(lo, hi, r, unite_gap, join_gap);
  }

  /// Bit k set when [lo, hi] overlaps lane k's interval or comes within `unite_gap` of it.
  [[nodiscard]] unsigned hit_mask(float lo, float hi, float unite_gap) const;
  /// hit_mask computed one lane at a time (what the vector form must equal).
  [[nodiscard]] unsigned hit_mask_scalar(float lo, float hi, float unite_gap) const {
    unsigned mask = 0;
    for (int k = 0; k < kMaxIntervals; ++k) {
      if (lo <= z_max[k] + unite_gap && hi >= z_min[k] - unite_gap) mask |= 1U << k;
    }
    return mask;
  }

 private:
  static constexpr std::array<float, kMaxIntervals> empty_lanes(float sign) {
    const float v = sign * std::numeric_limits<float>::infinity();
    return {v, v, v, v};
  }
  /// The lane of the one bit of `lane_bit` (below 1 << kMaxIntervals) takes [lo, hi] in and
  /// counts `r` more rays.
  void unite_lane(unsigned lane_bit, float lo, float hi, float r);
  void add_slow(float lo, float hi, float r, float unite_gap, float join_gap);
};

static_assert(sizeof(FreeCell) == 64, "a FreeCell is one cache line");

inline unsigned FreeCell::hit_mask(float lo, float hi, float unite_gap) const {
#if defined(__SSE2__)
  const __m128 gap = _mm_set1_ps(unite_gap);
  const __m128 reach_lo = _mm_cmple_ps(_mm_set1_ps(lo), _mm_add_ps(_mm_load_ps(z_max.data()), gap));
  const __m128 reach_hi = _mm_cmpge_ps(_mm_set1_ps(hi), _mm_sub_ps(_mm_load_ps(z_min.data()), gap));
  return static_cast<unsigned>(_mm_movemask_ps(_mm_and_ps(reach_lo, reach_hi)));
#else
  return hit_mask_scalar(lo, hi, unite_gap);
#endif
}

inline void FreeCell::unite_lane(unsigned lane_bit, float lo, float hi, float r) {
#if defined(__SSE2__)
  // The lane's bits all set, the others clear. min/max take the new value first: they return the
  // second operand on ties, as std::min(current, new) and std::max(current, new) do.
  const __m128i bit = _mm_set1_epi32(static_cast<int>(lane_bit));
  const __m128 lane = _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(bit, _mm_setr_epi32(1, 2, 4, 8)), bit));
  const __m128 inf = _mm_set1_ps(std::numeric_limits<float>::infinity());
  const __m128 new_lo = _mm_or_ps(_mm_and_ps(lane, _mm_set1_ps(lo)), _mm_andnot_ps(lane, inf));
  const __m128 new_hi = _mm_or_ps(_mm_and_ps(lane, _mm_set1_ps(hi)), _mm_andnot_ps(lane, _mm_sub_ps(_mm_setzero_ps(), inf)));
  _mm_store_ps(z_min.data(), _mm_min_ps(new_lo, _mm_load_ps(z_min.data())));
  _mm_store_ps(z_max.data(), _mm_max_ps(new_hi, _mm_load_ps(z_max.data())));
  _mm_store_ps(rays.data(), _mm_add_ps(_mm_load_ps(rays.data()), _mm_and_ps(lane, _mm_set1_ps(r))));
#else
  const auto k = static_cast<std::size_t>(std::countr_zero(lane_bit));
  z_min[k] = std::min(z_min[k], lo);
  z_max[k] = std::max(z_max[k], hi);
  rays[k] += r;
#endif
}

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
    std::vector<std::uint32_t> shared_slots;    // its cells on the sensor's row and column, folded
    std::vector<Eigen::Vector2f> ray_dz;        // (z_min, z_max) − z_s of the current target
    std::size_t rays = 0;
    void reset();  // the last trace's cells and rays (not the targets)
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
