#pragma once
// HVoxel extrusion (section III-E): free-space HVoxels of a scan carve the map's HVoxels.

#include <span>

#include "hmap/maps/column.hpp"

namespace hmap {

struct ExtrusionCounts {
  std::size_t updated = 0;     ///< HVoxels whose count was lowered (rules 2 and 4)
  std::size_t trimmed = 0;     ///< HVoxels that lost the overlapped part (rules 2 and 3)
  std::size_t subdivided = 0;  ///< HVoxels split in two around a free HVoxel (rule 4)
  std::size_t removed = 0;     ///< HVoxels removed, wholly covered or under n_th afterwards
};

/// Applies the four rules of III-E for the free HVoxels of one cell to that cell's column, then
/// removes the HVoxels the free space reached whose density fell under n_th:
///  1. no free HVoxel overlaps an HVoxel: nothing changes;
///  2. a free HVoxel overlaps an HVoxel with a smaller density: |v| −= d·|v_f| (d the overlapped
///     fraction of v's height); if ρ(v) then falls under n_th, the overlapped part is removed;
///  3. a free HVoxel overlaps with a bigger (or equal) density: the overlapped part is removed;
///  4. a free HVoxel strictly inside an HVoxel: with a smaller density the HVoxel is subdivided
///     around it, otherwise it is updated as in rule 2.
/// Removing part of an HVoxel keeps the count of the part that stays, pro rata of its height.
/// `column` is a TileColumn (in a map) or a Column (standing alone).
template <typename EditableColumn>
void extrude(EditableColumn& column, std::span<const FreeHVoxel> free, const MapParams& params,
             ExtrusionCounts& counts);

extern template void extrude(TileColumn&, std::span<const FreeHVoxel>, const MapParams&, ExtrusionCounts&);
extern template void extrude(Column&, std::span<const FreeHVoxel>, const MapParams&, ExtrusionCounts&);

}  // namespace hmap
