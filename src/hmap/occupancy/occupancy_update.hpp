#pragma once
// HVoxel to 2D occupancy update (section IV-B, eq. 3-4): each scan's HVoxels, judged against the
// local ground patch, update the log-odds of the cells along the ray from the sensor to them.

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/maps/scan_hvoxels.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// How one HVoxel counts for the 2D grid, by eq. (4)'s cases.
enum class HVoxelRole : std::uint8_t {
  kIgnored,   ///< entirely above z+ or below z− of the local ground: p = 0.5 (ceilings, crowns)
  kObstacle,  ///< its top farther than d_pth from the local ground
  kGround,    ///< its top within d_pth of the local ground: drivable
};

/// The role of `v` over a local ground at height `ground_z` [m].
[[nodiscard]] HVoxelRole hvoxel_role(const HVoxel& v, double ground_z, const OccupancyParams& p);

/// eq. (4) for one HVoxel at signed distance `delta` [m] = |c| − |v| along the ray (negative
/// before the HVoxel's cell): obstacle max(ρ, 0.5)·exp(−δ²/2σ²), ground
/// K_g + (0.5 − K_g)/(1 + exp(−δ/d_pth)), ignored 0.5.
[[nodiscard]] double inverse_sensor_model(HVoxelRole role, double density, double delta, const OccupancyParams& p);

/// The stretch [t_lo, t_hi] of t in [0, 1] where the linear height h(t) = h_start + t·(h_end −
/// h_start) is at most `limit`; empty (t_lo > t_hi) when nowhere.
[[nodiscard]] std::pair<double, double> below_along(double h_start, double h_end, double limit);

struct OccupancyUpdateStats {
  std::size_t rays = 0;        ///< scan cells with at least one HVoxel that is not ignored
  std::size_t cells = 0;       ///< grid cells updated
  std::size_t no_ground = 0;   ///< scan cells skipped: no ground patch within ground_reach
};

/// Updates the 2D grid with one scan after another, reusing its buffers (nothing is allocated per
/// scan once warm). Each cell on the path from the sensor's cell to a scan cell (both included)
/// takes p(c|z) = max over that cell's HVoxels of eq. (4); a cell reached by several rays keeps
/// the largest p of the scan when one is a hit (p >= 0.5: a hit outranks a pass-through), else
/// the smallest (the clearest pass: a ground cell's own ray gives 0.4 at δ = 0, a ray passing low
/// over it K_g), and is then updated once by eq. (3). p is floored at K_g: in front of an obstacle the obstacle term tends to 0, which would
/// otherwise be certainty of free space from a single scan.
///
/// Unlike the paper's 2D ray, a pass frees a cell only where the lowest 3D ray to the scan cell
/// runs at most `occupancy.free_ray_height` above the ground (taken linear from the ground under
/// the sensor to the scan cell's): a ray passing higher says nothing about what stands under it.
/// Outdoors, where rays to facades and tree crowns cross parked cars and trunks, the paper's rule
/// freed 96 % of the truly blocked cells (docs/COMPARE.md). A height above z+ restores it.
///
/// Two shortcuts, both exact to 1e-4 in probability: farther than `cutoff()` before its HVoxel's
/// cell a ray's p is the floor K_g, so eq. (4) is only evaluated near the end of each ray; and the
/// local ground of a cell is the plane of the patch nearest to the centre of its 4x4-cell block,
/// looked up once per block and scan (in buckets of the patches near the window, rebuilt per scan).
/// Each ray's walk starts at the first cell it can change (traverse_2d_from).
class OccupancyUpdater {
 public:
  /// Throws hmap::Error for invalid parameters.
  explicit OccupancyUpdater(const Params& params);
  ~OccupancyUpdater();
  OccupancyUpdater(OccupancyUpdater&&) noexcept;
  OccupancyUpdater& operator=(OccupancyUpdater&&) noexcept;

  /// The rays run in parallel (TBB), each thread keeping its own per-cell maxima.
  OccupancyUpdateStats update(const ScanHVoxels& scan, const GroundModel& ground, OccupancyGrid& grid);

  /// Distance [m] before an HVoxel's cell beyond which eq. (4) is within 1e-4 of the floor K_g.
  [[nodiscard]] double cutoff() const { return cutoff_; }

 private:
  struct Buffers;  // one RayBuffer per thread (TBB, kept out of this header)
  void find_ground(const ScanHVoxels& scan, const ScanWindow& window, const GroundModel& ground,
                   OccupancyUpdateStats& stats);
  /// Buckets of one block each over the window and a rim, holding the patches whose centre is there.
  void index_patches(const ScanWindow& window, const GroundModel& ground);
  /// The patch nearest to (x, y), the centre of block (bi, bj), from the buckets (ties: the lowest
  /// index); −1 when none lies within the rim, where no patch is within ground_reach of the block.
  [[nodiscard]] std::int32_t nearest_patch(std::int32_t bi, std::int32_t bj, double x, double y,
                                           const std::vector<GroundPatch>& patches) const;

  Params params_;
  double cutoff_;           // the larger of the two terms' cutoffs
  double obstacle_cutoff_;  // the obstacle term's alone
  std::unique_ptr<Buffers> buffers_;
  std::vector<double> ground_z_;            // per scan cell: local ground height, NaN none
  std::vector<std::int32_t> block_patch_;   // per 4x4 block: nearest patch, -1 none
  std::vector<std::uint32_t> block_stamp_;  // scan number the entry was computed for
  std::uint32_t stamp_ = 0;
  std::int32_t window_width_ = -1;          // the blocks above are laid out for this width
  // The ground patches near the window in buckets of one block (counting sort, rebuilt per scan):
  // the nearest patch of a block in a few bucket reads instead of a query of the kd-tree's forest.
  // Bucket (a, b) is the window's block (a, b); the grid holds rows × cols buckets from (a0, b0).
  std::int32_t bucket_rim_ = 0;             // rings searched at most; −1: the kd-tree answers
  std::int32_t bucket_a0_ = 0;
  std::int32_t bucket_b0_ = 0;
  std::int32_t bucket_rows_ = 0;
  std::int32_t bucket_cols_ = 0;
  std::vector<std::uint32_t> bucket_begin_;  // per bucket: first entry in bucket_patches_, + end
  std::vector<std::uint32_t> bucket_fill_;
  std::vector<std::int32_t> bucket_patches_;
  struct PatchBucket {
    std::int32_t patch, a, b;
  };
  std::vector<PatchBucket> patch_bucket_;  // the patches near the window, by index, with their bucket
  std::vector<std::uint16_t> empty_rings_;   // per bucket: rings to the nearest patch's bucket
};

/// One scan with a fresh OccupancyUpdater (allocates its buffers: prefer the class scan after scan).
OccupancyUpdateStats update_occupancy(const ScanHVoxels& scan, const GroundModel& ground, const Params& params,
                                      OccupancyGrid& grid);

}  // namespace hmap

namespace hmap {

/// The 2D grid derived from a finished map alone, when its scans are not at hand (`hmap export
/// --pgm` of a saved map): every column is judged by eq. (4)'s cases at its own cell — an
/// obstacle HVoxel makes the cell occupied (clamp_max), drivable ground alone makes it free
/// (clamp_min), ignored HVoxels (above z+, below z−) say nothing — so columns with only a ceiling
/// or a tree crown stay unknown. Columns without a ground patch nearer than `max_ground_distance`
/// [m] are judged for obstacles only, and only against the nearest patch within
/// `occupancy.obstacle_reach`: blocked when the column's lowest HVoxel starts within
/// `ground.elevation_threshold` of that patch's plane (it stands on that ground) and one of its
/// HVoxels is an obstacle there (a wall's foot on a floor the sensor saw too sparsely for patches,
/// balm_os0's west wall); never free, since the ground around it was not seen.
[[nodiscard]] OccupancyGrid occupancy_from_map(const HMap& map, const GroundModel& ground, const Params& params,
                                               double max_ground_distance);

}  // namespace hmap
