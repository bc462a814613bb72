#pragma once
// The native `.hmap` map file: the parameters a map was built with and every HVoxel, exact.
//
// Layout, version 3 (version 2, the same without the cell centroids, and version 1, without the
// ground and grid sections too, are still read). Integers are little-endian; offsets in bytes, J = JSON length, C = compressed
// payload length; the whole file is 48 + J + C bytes.
//
//   offset       size  field
//   0            8     magic 89 48 4D 41 50 0D 0A 1A ("\x89HMAP\r\n\x1a": the high bit, CR-LF and
//                      ^Z catch transfers that strip bits or convert line ends, as in PNG)
//   8            4     uint32 format version = 3
//   12           4     uint32 flags = 0 (no flag is defined; readers reject any other value)
//   16           8     uint64 J
//   24           J     params JSON, UTF-8: one object holding "format": "hmap", "tile_size": 16 and
//                      every parameter of hmap::param_refs by dotted name as a number
//                      ({"map.cell_size": 0.25, ...}); every parameter must be present
//   24 + J       8     uint64 U, uncompressed payload size (at most 32 GiB)
//   32 + J       8     uint64 C
//   40 + J       C     the payload, one zstd frame
//   40 + J + C   8     uint64 XXH64 (seed 0) of bytes [0, 40 + J + C)
//
// Payload (uncompressed, U bytes):
//   uint64 tile count T
//   T tiles, in increasing (tile_i, tile_j) order, none without HVoxels; each:
//     int32 tile_i, int32 tile_j      tile (a, b) holds cells [16a, 16a + 16) × [16b, 16b + 16)
//     256 cells in HMap::local_index order (row-major: local = 16 · (i mod 16) + (j mod 16)), each:
//       varint n                      LEB128, unsigned, shortest encoding: HVoxels in the cell
//       n × 4 float32                 z_min, z_max, count, density; sorted by height, disjoint
//   (version 2 only, both possibly empty:)
//   uint64 ground patch count P, then P patches of Alg. 4's tree in their tree order, each:
//     3 float64 centre, 3 float64 unit normal (z > 0), float64 half size > 0,
//     int32 parent (-1 for a root, else the index of an earlier patch)
//   uint64 occupancy tile count G, then G tiles in increasing (i, j) order, none all unknown:
//     int32 tile_i, int32 tile_j      tile (a, b) holds cells [8a, 8a + 8) × [8b, 8b + 8)
//     64 float32 log-odds             cell (i, j) at 8 · (i mod 8) + (j mod 8); NaN = unknown,
//                                     others within the clamping bounds of the parameters
//   (version 3 only, possibly empty:)
//   uint64 cell centroid count K, then K cells in increasing (i, j) order, each once:
//     int32 i, int32 j                the cell, in one of the stored tiles
//     2 float32 offset                [m] of the centroid of the tall points merged into the cell
//                                     from its centre, each within half a cell (CellCentroids)
//     float64 weight                  > 0, the points behind it
//
// The writer's output is a function of the map alone: identical maps give identical bytes.
// The reader checks the checksum before decompressing, and decodes the payload a zstd block at a
// time: memory follows the bytes really decoded, never U. It does not bound the compression
// ratio, since uniform maps legitimately compress beyond 1000:1.

#include <filesystem>
#include <optional>
#include <span>
#include <vector>

#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/cell_centroids.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// Everything a `.hmap` file holds: the HMAP and, for the hybrid map of section IV, the ground
/// patches and the 2D occupancy grid kept alongside (empty / absent when not saved).
struct MapFile {
  HMap map;
  std::vector<GroundPatch> ground;
  std::optional<OccupancyGrid> grid;
  /// Where in its cell the map's surface lies (the SLAM's CellCentroids); absent before version 3,
  /// possibly empty from it (a map not made by the SLAM).
  std::optional<CellCentroids> centroids;
};

/// Writes `map` to `path` in the `.hmap` format, atomically (readers see the old file or the
/// complete new one). Throws hmap::Error when the file cannot be written.
void save_hmap(const std::filesystem::path& path, const HMap& map);
/// The same with the hybrid layers: `ground` patches and the 2D `grid` (may be null). The grid's
/// cell size must be the map's.
void save_hmap(const std::filesystem::path& path, const HMap& map, std::span<const GroundPatch> ground,
               const OccupancyGrid* grid);
/// The same with the SLAM's cell centroids (may be null: none saved). Their cell size must be the
/// map's.
void save_hmap(const std::filesystem::path& path, const HMap& map, std::span<const GroundPatch> ground,
               const OccupancyGrid* grid, const CellCentroids* centroids);

/// Reads a `.hmap` file. Every field is checked before it is used and nothing is allocated from a
/// size the file claims before the claim is verified: a damaged or hostile file gives
/// hmap::InputError naming the file, the byte ("byte N", or "payload byte N" inside the
/// decompressed payload) and what was expected.
[[nodiscard]] HMap load_hmap(const std::filesystem::path& path);
/// Reads a `.hmap` file with its hybrid layers, checked as load_hmap checks the HVoxels.
[[nodiscard]] MapFile load_map_file(const std::filesystem::path& path);

}  // namespace hmap
