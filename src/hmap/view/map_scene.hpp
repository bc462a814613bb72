#pragma once
// What the browser viewer (`hmap view`) shows of a map, encoded for the page: the HVoxels as
// boxes by view tile and level of detail (binary), the 2D occupancy grid as a byte image, the
// ground patches, the trajectory and one cell's column (JSON). Pure: no file or socket here; the
// server (hmap/serve) moves these bytes.
//
// Box record, 32 bytes, little-endian, one per box of a tile at a level:
//   offset 0   3 float32  centre x, y, z [m], map frame
//   offset 12  3 float32  size x, y, z [m]
//   offset 24  float32    density ρ (eq. 1); the largest of the HVoxels merged into a coarse box
//   offset 28  4 uint8    r, g, b, a: the colour of the centre's height on the map's z range
//
// View tiles are kViewTileCells × kViewTileCells cells: tile (a, b) holds cells
// [a·64, a·64 + 64) × [b·64, b·64 + 64). Level L draws blocks of 2^L × 2^L cells: the HVoxels of a
// block sorted by height and united where they overlap or are closer than the block's edge, so
// a far tile costs a fraction of its boxes and keeps its silhouette.

#include <array>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"
#include "hmap/occupancy/occupancy_update.hpp"

namespace hmap::view {

inline constexpr int kViewTileCells = 64;  ///< cells per view tile edge
inline constexpr int kLevels = 4;          ///< levels of detail 0..3: blocks of 1, 2, 4, 8 cells
inline constexpr std::size_t kBoxBytes = 32;

/// One box of the viewer, as the page decodes it.
struct Box {
  Eigen::Vector3f centre;  ///< [m]
  Eigen::Vector3f size;    ///< [m]
  float density = 0.0F;    ///< ρ, eq. (1)
  std::array<std::uint8_t, 4> rgba{};
  friend bool operator==(const Box&, const Box&) = default;
};

/// The 2D grid as one byte per cell: 0..100 the occupancy probability in percent, 255 unknown.
/// Cell (col, row) is row-major at row·width + col; its lower-left corner is origin + (col, row)·
/// resolution, so x grows with col and y with row.
struct GridImage {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  ///< [m]
  double resolution = 0.0;                           ///< [m]
  std::int32_t width = 0, height = 0;                ///< [cells]
  std::vector<std::uint8_t> cells;
};
inline constexpr std::uint8_t kUnknownCell = 255;

/// The grid as a byte image over the box of its known cells. Throws hmap::Error past `max_cells`.
[[nodiscard]] GridImage grid_image(const OccupancyGrid& grid, std::size_t max_cells = 64'000'000);

/// One HVoxel of a column query with how the 2D grid reads it.
struct ColumnEntry {
  HVoxel hvoxel;
  std::optional<HVoxelRole> role;  ///< eq. (4)'s case over the local ground; none without ground
  /// [-] eq. (4) at the HVoxel's own cell (δ = 0): what it says of the cell's occupancy;
  /// none without a ground patch within reach.
  std::optional<double> occupancy;
};

/// The column of one cell.
struct ColumnReport {
  CellKey cell;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  ///< [m]
  std::vector<ColumnEntry> hvoxels;                  ///< bottom to top
  std::optional<double> ground_z;                    ///< [m] local ground height, if any patch
  std::optional<double> grid_probability;            ///< of the 2D grid's cell, if known
};

/// A map as the viewer shows it: the map file's layers and an optional trajectory.
class MapScene {
 public:
  /// `trajectory`: positions [m] in the map frame, in order (may be empty). `format` names the
  /// map's origin for the page: "hmap", or "pvox" for voxels_as_columns(), coloured by probability.
  MapScene(HMap map, std::vector<GroundPatch> ground, std::optional<OccupancyGrid> grid,
           std::vector<Eigen::Vector3d> trajectory, std::string format = "hmap");

  [[nodiscard]] const HMap& map() const { return map_; }
  [[nodiscard]] const std::vector<GroundPatch>& ground() const { return ground_.patches(); }
  [[nodiscard]] const std::optional<OccupancyGrid>& grid() const { return grid_; }
  [[nodiscard]] const std::vector<Eigen::Vector3d>& trajectory() const { return trajectory_; }
  /// [m] the lowest z_min and highest z_max of the HVoxels: the range of the height colours.
  [[nodiscard]] float z_low() const { return z_low_; }
  [[nodiscard]] float z_high() const { return z_high_; }
  /// The grid as an image (grid_image()), made once; 0 × 0 without a grid or a known cell.
  [[nodiscard]] const GridImage& grid_image() const { return grid_image_; }

  /// The boxes of view tile (a, b) at `level` (0 .. kLevels − 1; throws hmap::Error beyond).
  [[nodiscard]] std::vector<Box> tile_boxes(const CellKey& tile, int level) const;
  /// The column of the cell holding (x, y) [m]; empty when nothing is stored there.
  [[nodiscard]] ColumnReport column(double x, double y) const;
  /// The map's description for the page (JSON): cell size, bounds, z range, the view tiles with
  /// their HVoxel counts, the ground patches, the trajectory and the grid image's frame. Made at
  /// the first call and kept (it walks the whole map: 1.4 M HVoxels took a map request seconds).
  [[nodiscard]] const std::string& summary_json() const;

 private:
  HMap map_;
  GroundModel ground_;
  std::optional<OccupancyGrid> grid_;
  std::vector<Eigen::Vector3d> trajectory_;
  std::string format_;
  GridImage grid_image_;
  float z_low_ = 0.0F;
  float z_high_ = 1.0F;
  /// summary_json(), made once however many server threads ask (shared: the scene stays movable).
  struct Summary {
    std::once_flag once;
    std::string json;
  };
  std::shared_ptr<Summary> summary_ = std::make_shared<Summary>();
  [[nodiscard]] std::string make_summary_json() const;
};

/// A scene of copies of a map being built (the live view of `hmap map --view`): the HVoxels, the
/// ground patches and the grid (may be null) as they are now; O(size of the map).
[[nodiscard]] MapScene snapshot(const HMap& map, std::span<const GroundPatch> ground, const OccupancyGrid* grid,
                                std::vector<Eigen::Vector3d> trajectory);

/// A voxel map (`.pvox`) in the viewer's terms: a column of cells of edge `edge` [m] per voxel
/// column, each voxel an HVoxel 0.99 of the edge high (stacked voxels must not touch: columns are
/// disjoint), its occupancy probability in the density field and 1 in the count. Throws
/// hmap::Error when the sizes differ or the edge is not a valid cell size.
[[nodiscard]] HMap voxels_as_columns(std::span<const Eigen::Vector3d> centres, std::span<const double> probability,
                                     double edge);

/// The view tile holding a cell.
[[nodiscard]] inline CellKey view_tile_of(const CellKey& cell) {
  return {cell.i >= 0 ? cell.i / kViewTileCells : -((-cell.i - 1) / kViewTileCells) - 1,
          cell.j >= 0 ? cell.j / kViewTileCells : -((-cell.j - 1) / kViewTileCells) - 1};
}

/// The colour of height z on [z_low, z_high]: blue, cyan, green, yellow, red (clamped beyond).
[[nodiscard]] std::array<std::uint8_t, 4> height_colour(float z, float z_low, float z_high);

/// Boxes as 32-byte records (layout above), and back. decode_boxes throws hmap::Error when the
/// byte count is not a multiple of 32.
[[nodiscard]] std::vector<std::uint8_t> encode_boxes(std::span<const Box> boxes);
[[nodiscard]] std::vector<Box> decode_boxes(std::span<const std::uint8_t> bytes);


/// A column report as JSON: {"cell": [i, j], "centre": [x, y], "ground_z": z|null,
/// "grid_probability": p|null, "hvoxels": [{"z_min", "z_max", "count", "density", "role",
/// "occupancy"}, ...]}.
[[nodiscard]] std::string column_json(const ColumnReport& report);

}  // namespace hmap::view
