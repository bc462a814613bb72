#pragma once
// The three serializations of the seed (its Fig. 17), as bytes in memory; the caller writes them
// (atomically) and reads them. Pure: no file access here.
//
// Raw points CSV:  header "x,y,z", one point per line, metres with 4 decimals.
// Voxel CSV:       header "x,y,z,edge,probability", one line per voxel holding points (centre,
//                  edge [m], p), sorted by key; voxels only crossed by rays (free space) are left out.
// Binary (.pvox), version 1, integers and doubles little-endian:
//
//   offset  size  field
//   0       8     magic 89 50 56 4F 58 0D 0A 1A ("\x89PVOX\r\n\x1a", as PNG's)
//   8       4     uint32 version = 1
//   12      4     uint32 flags = 0 (readers reject any other value)
//   16      8     float64 edge [m]
//   24      8     float64 measurement variance σ_m² [m²]
//   32      8     float64 logit_min
//   40      8     float64 logit_max
//   48      8     float64 miss_logit
//   56      8     uint64 voxel count N
//   64      8     uint64 U, payload bytes before compression (at most 256·C + 4096 and 2 GiB)
//   72      8     uint64 C
//   80      C     payload, one zstd frame
//   80 + C  8     uint64 XXH64 (seed 0) of bytes [0, 80 + C)
//
// Payload: N records in increasing key order; each: the key as three zigzag LEB128 deltas from
// the previous key (the first from (0, 0, 0)), LEB128 hits, LEB128 misses, and the mean of the
// voxel's points as three bytes q (mean = centre + (q − 127.5)/255 · edge: 0.23 mm at 58.6 mm).
// The second moments are not stored: a decoded voxel has its points at their mean.

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/budget.hpp"
#include "hmap/core/types.hpp"
#include "hmap/pvox/voxel_map.hpp"

namespace hmap::pvox {

[[nodiscard]] std::string points_csv(const PointCloud& points_map);

/// One line of the voxel CSV.
struct VoxelRecord {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< [m]
  double edge = 0.0;                                 ///< [m]
  double probability = 0.5;
};

[[nodiscard]] std::string voxels_csv(const VoxelMap& map);
/// Parses a voxel CSV; throws hmap::InputError naming `source` and the line for anything else.
[[nodiscard]] std::vector<VoxelRecord> parse_voxels_csv(std::string_view text, const std::string& source);

[[nodiscard]] std::vector<std::uint8_t> encode_binary(const VoxelMap& map);
/// Decodes a binary map; throws hmap::InputError naming `source`, the byte offset and the problem
/// for a wrong magic, version or flags, a checksum mismatch, a truncation, or an invalid field.
[[nodiscard]] VoxelMap decode_binary(std::span<const std::uint8_t> bytes, const std::string& source,
                                     const MemoryBudget& budget = {});

}  // namespace hmap::pvox
