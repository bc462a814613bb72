#pragma once
// Where in its cell the map's surface lies (slam.hvoxel_centroids = 2): the plan centroid of the
// points of the tall HVoxels merged into each cell. The HMAP keeps a cell's heights, not where in
// the cell its points were; the SLAM keeps this beside it, so that a scan matched at its points'
// centroids (ScanHVoxels::centroids) meets a map on the same footing, and the `.hmap` file saves it
// with the map (format version 3) for a session that continues it.
//
// Stored like the HMAP: tiles of 8 × 8 cells found through a TileIndex (open addressing), each cell
// 32 bytes (its offset and its weighted sums). The matcher looks an offset up per scan HVoxel
// whose cell changes; a node-based hash map of cells cost the SLAM about 6 % of its samples there.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "hmap/maps/hmap.hpp"
#include "hmap/maps/scan_hvoxels.hpp"
#include "hmap/maps/tile_index.hpp"

namespace hmap {

class CellCentroids {
 public:
  // The HMAP's tiles: one tile key and one local index for both (HMap::tile_of, local_index).
  static constexpr int kTileBits = HMap::kTileBits;
  static constexpr int kTileCells = HMap::kTileCells;

 private:
  struct Tile {
    Tile() {  // (Eigen's vectors are not zeroed by {})
      offset.fill(Eigen::Vector2f::Constant(std::numeric_limits<float>::quiet_NaN()));
      sums.fill(Eigen::Vector3d::Zero());
    }
    // [m] from the cell's centre; NaN: no centroid. Apart from the sums, so that a lookup reads
    // one cache line of offsets.
    std::array<Eigen::Vector2f, kTileCells> offset;
    std::array<Eigen::Vector3d, kTileCells> sums;  // Σ n·x, Σ n·y (map frame), Σ n
  };

 public:

  /// Throws hmap::Error for a cell size that is not positive and finite.
  explicit CellCentroids(double cell_size);

  /// Adds the HVoxels of `scan` at least `min_height` tall, each its plan centroid
  /// (ScanHVoxels::centroids) weighted by its points, moved into the map by the planar pose
  /// (x, y, yaw). A scan without centroids adds nothing.
  void add(const ScanHVoxels& scan, double x, double y, double yaw, float min_height);

  /// Adds `weight` points at (x, y) in the map frame to the cell they lie in. Non-finite input and
  /// a weight that is not positive add nothing.
  void add(double x, double y, double weight);

  /// Adds the centroids of `other` (another session's map, `hmap merge`), each moved into this
  /// map's frame by the planar pose (x, y, yaw): its point, the cell's centre plus its offset, with
  /// its weight, into the cell it lands in. `other` may be this. Throws hmap::Error for another
  /// cell size.
  void add(const CellCentroids& other, double x, double y, double yaw);

  /// The offset [m] of the cell's centroid from the cell's centre, or nullptr for a cell nothing
  /// tall was merged into.
  [[nodiscard]] const Eigen::Vector2f* offset(const CellKey& key) const {
    const Tile* tile = tiles_.find(tile_of(key));
    return tile == nullptr ? nullptr : in(*tile, local_index(key));
  }

  /// The tiles of a square of cells, for lookups without the index: the matcher's window around
  /// the scan. Cells outside it, and tiles made after reset(), are looked up in the index.
  class View {
   public:
    void reset(const CellCentroids* source, const CellKey& center, std::int32_t half_cells);
    [[nodiscard]] const CellCentroids* source() const { return source_; }
    /// As CellCentroids::offset. The source must not have been destroyed since reset().
    [[nodiscard]] const Eigen::Vector2f* offset(const CellKey& key) const {
      const CellKey t = tile_of(key);
      const std::int32_t ti = t.i - tile_min_.i;
      const std::int32_t tj = t.j - tile_min_.j;
      if (ti >= 0 && tj >= 0 && ti < tiles_wide_ && tj < tiles_wide_) {
        const Tile* tile = tiles_[static_cast<std::size_t>(ti) * static_cast<std::size_t>(tiles_wide_) + static_cast<std::size_t>(tj)];
        if (tile != nullptr) return in(*tile, local_index(key));
      }
      return source_ != nullptr ? source_->offset(key) : nullptr;
    }

   private:
    const CellCentroids* source_ = nullptr;
    CellKey tile_min_;
    std::int32_t tiles_wide_ = 0;
    std::vector<const Tile*> tiles_;  // row by row, nullptr where the source had none
  };

  /// Sets a cell's centroid as saved: `offset` [m] from its centre (each component within half a
  /// cell), the sum of the points' weights `weight` behind it; later adds weigh against it.
  /// Throws hmap::Error for a cell that already has one, a non-finite or outlying offset, or a
  /// weight that is not positive and finite.
  void restore(const CellKey& cell, const Eigen::Vector2f& offset, double weight);

  /// Calls f(cell, offset, weight) for every cell with a centroid: tiles in the order they were
  /// made, cells within a tile by HMap::local_index.
  template <typename F>
  void for_each(F&& f) const {
    tiles_.for_each([&](const CellKey& tile_key, const Tile& tile) {
      for (std::size_t local = 0; local < static_cast<std::size_t>(kTileCells); ++local) {
        if (in(tile, local) == nullptr) continue;
        f(HMap::key_in_tile(tile_key, static_cast<int>(local)), tile.offset[local], tile.sums[local].z());
      }
    });
  }

  /// Cells with a centroid.
  [[nodiscard]] std::size_t size() const { return cells_; }
  [[nodiscard]] double cell_size() const { return cell_; }
  /// Bytes held: the tiles and the index.
  [[nodiscard]] std::size_t bytes() const { return tiles_.size() * sizeof(Tile) + tiles_.table_bytes(); }

 private:
  [[nodiscard]] static const Eigen::Vector2f* in(const Tile& tile, std::size_t local) {
    const Eigen::Vector2f& offset = tile.offset[local];
    return offset.x() == offset.x() ? &offset : nullptr;  // NaN: none
  }
  [[nodiscard]] static CellKey tile_of(const CellKey& key) { return HMap::tile_of(key); }
  [[nodiscard]] static std::size_t local_index(const CellKey& key) { return static_cast<std::size_t>(HMap::local_index(key)); }

  double cell_;
  TileIndex<Tile> tiles_;
  std::size_t cells_ = 0;
};

}  // namespace hmap
